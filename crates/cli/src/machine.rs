//! Loading `printer.cfg` for a command: diagnostics pointing into the file, its warnings on standard error.

use std::path::Path;

use printjob::Machine;

use crate::diag;

/// Load `printer.cfg` and build the machine; the file becomes an input no output may replace.
pub fn load_machine(path: &Path) -> miette::Result<Machine> {
    outfile::register_input(path);
    let (config, notes) =
        Machine::read(path).map_err(|e| miette::Report::new(diag::config_error(&e)))?;
    for note in &notes {
        let kind = if note.refused { "error" } else { "warning" };
        match &note.span {
            Some(span) => eprintln!("{span}: {kind}: {}", note.message),
            None => eprintln!("{}: {kind}: {}", path.display(), note.message),
        }
    }
    let refused = notes.iter().filter(|n| n.refused).count();
    if refused > 0 {
        miette::bail!(
            "{}: {refused} unknown option(s): the printer would not start on this file",
            path.display()
        );
    }
    Machine::from_config(config, &path.display().to_string())
        .map_err(|e| miette::miette!("{}: {e}", path.display()))
}

/// The motors' speed limits as the planner applies them (angular and joint limits, step rates), for the converter:
/// every written segment takes at least each limited motor's travel over its limit.
pub fn convert_limits(setup: &motion::machine::MachineSetup) -> Vec<convert::MotorLimit> {
    setup
        .planner
        .kinematic_limits
        .iter()
        .map(|l| convert::MotorLimit {
            motor: l.motor,
            max_velocity: l.max_velocity,
            max_accel: l.max_accel,
        })
        .collect()
}
