//! The one place a machine is built. `printer.cfg` (a file, or the sections' text) → [`Machine`]: the
//! configuration as read, its warnings and unknown keys as [`ConfigNote`]s, and the [`MachineSetup`] every
//! front-end plans with (kinematics, planner limits and the motor limits along a move, the homing pose). The CLI,
//! the simulator, the Klipper plug-in, the fuzz targets and the benches all get their machine here, so one
//! printer.cfg means one machine everywhere.

mod load;
mod setup;

pub use load::{ConfigNote, LoadError, Machine, PlanOptions};
pub use setup::{MachineSetup, SetupError};

#[cfg(test)]
mod tests {
    use super::Machine;
    use std::path::Path;

    fn example(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/machines/{name}.cfg"))
    }

    /// The file (the command line) and its text (the plug-in without a file) build the same machine.
    #[test]
    fn a_file_and_its_text_build_one_machine() {
        for name in ["polar", "scara", "cartesian"] {
            let (from_file, notes) = Machine::load(&example(name)).expect("the example loads");
            assert!(notes.iter().all(|n| !n.refused), "{name}: {notes:?}");
            let text = std::fs::read_to_string(example(name)).expect("readable");
            let from_text = Machine::from_text(&text, "printer.cfg").expect("the text builds");
            let (a, b) = (&from_file.setup, &from_text.setup);
            assert_eq!(a.home_position, b.home_position, "{name}");
            assert_eq!(
                a.planner.kinematic_limits, b.planner.kinematic_limits,
                "{name}"
            );
            assert_eq!(a.kinematics.motors(), b.kinematics.motors(), "{name}");
        }
    }

    /// Every front-end reads a SCARA's shoulder in (−π, π], as firmware does: a point whose shoulder angle lies just
    /// past the cut is refused where the kinematics alone would take it.
    #[test]
    fn a_scara_shoulder_is_read_within_the_branch_cut() {
        let (machine, _) = Machine::load(&example("scara")).expect("the example loads");
        let kinematics::MachineParams::Scara(params) = &machine.config.params else {
            panic!("the example is a SCARA");
        };
        assert_eq!(
            params.shoulder_limits, None,
            "the file sets no shoulder limits"
        );
        let built =
            kinematics::scara::Scara::of(machine.setup.kinematics.as_ref()).expect("a SCARA");
        let (min, max) = built.params().shoulder_limits.expect("cut");
        assert!(min >= -std::f64::consts::PI && max <= std::f64::consts::PI);
    }
}
