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
        for name in ["polar", "scara", "cartesian", "fivebar"] {
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

    /// The five-bar homes each base joint to its endstop: the nozzle where the forward kinematics put it.
    #[test]
    fn a_fivebar_homes_to_its_endstop_angles() {
        let (machine, notes) = Machine::load(&example("fivebar")).expect("the example loads");
        assert!(notes.iter().all(|n| !n.refused), "{notes:?}");
        assert_eq!(machine.setup.kinematics.name(), "fivebar");
        let home = machine.setup.home_position.expect("homes to its endstops");
        // Left arm at 150°, right at 30°: elbows at (∓179.90, −125), 359.81 mm apart, the nozzle
        // √(200² − 179.90²) above them on x = 0.
        let half = 50.0 + 150.0 * 30f64.to_radians().cos();
        let y = -200.0 + 75.0 + (200.0f64 * 200.0 - half * half).sqrt();
        assert!(
            home[0].abs() < 1e-9 && (home[1] - y).abs() < 1e-9,
            "{home:?}"
        );
        assert_eq!(home[2], 0.5);
        let motors = machine.setup.kinematics.motors();
        let names: Vec<&str> = motors.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["stepper_left", "stepper_right", "stepper_z"]);
        // 25600 microsteps per joint turn; the joints' speed limits bind both arm motors.
        assert!((motors[0].step_distance - std::f64::consts::TAU / 25600.0).abs() < 1e-15);
        let limited: Vec<usize> = machine
            .setup
            .planner
            .kinematic_limits
            .iter()
            .map(|l| l.motor)
            .collect();
        assert_eq!(limited, [0, 1]);
    }
}
