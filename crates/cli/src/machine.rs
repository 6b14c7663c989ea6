//! Loading `printer.cfg` for a command: diagnostics pointing into the file, its warnings on standard error.

use std::path::Path;

use printjob::Machine;

use crate::diag;

/// `--host` (of `run` and `estimate`): whose planning to reproduce.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum HostArg {
    #[default]
    Klipper,
    KalicoFekt,
}

impl From<HostArg> for motion::Host {
    fn from(h: HostArg) -> Self {
        match h {
            HostArg::Klipper => motion::Host::Klipper,
            HostArg::KalicoFekt => motion::Host::KalicoFekt,
        }
    }
}

/// Load `printer.cfg` and build the machine; the file becomes an input no output may replace.
pub fn load_machine(path: &Path) -> miette::Result<Machine> {
    let config = read_config(path)?;
    Machine::from_config(config, &path.display().to_string())
        .map_err(|e| miette::miette!("{}: {e}", path.display()))
}

/// Read `printer.cfg` with its warnings on standard error, refused when it has a key nothing reads (Klipper would
/// not start on it); the file and every file it includes become inputs no output may replace.
pub fn read_config(path: &Path) -> miette::Result<config::MachineConfig> {
    outfile::register_input(path);
    let (config, notes) =
        Machine::read(path).map_err(|e| miette::Report::new(diag::config_error(&e)))?;
    // Every file the config read is an input of the run: no output may replace an included file either.
    for file in config.document.files() {
        outfile::register_input(file);
    }
    for note in &notes {
        let kind = if note.refused { "error" } else { "warning" };
        let place = note
            .span
            .as_ref()
            .map_or_else(|| path.display().to_string(), ToString::to_string);
        crate::errln!("{place}: {kind}: {}", note.message);
    }
    let refused = notes.iter().filter(|n| n.refused).count();
    if refused > 0 {
        miette::bail!(
            "{}: {refused} unknown option(s): the printer would not start on this file",
            path.display()
        );
    }
    Ok(config)
}

/// A conversion of `machine`'s G-code for firmware without its kinematics, as `convert` and the demo assemble it:
/// the output axes of the machine's own motors (its kinematics shared, not built again), and options that start
/// where homing leaves the machine (nothing unknown is guessed without a homing pose) and give every written
/// segment at least each limited motor's travel over its limit, as the planner limits it (angular and joint
/// limits, step rates).
pub fn convert_job(
    machine: &Machine,
    mut options: convert::ConvertOptions,
) -> Result<(convert::AxisMap, convert::ConvertOptions), convert::ConvertError> {
    let map = convert::AxisMap::motors(machine.setup.kinematics.clone(), options.target)?;
    options.home = machine.setup.home_position;
    options.motor_limits = machine
        .setup
        .planner
        .kinematic_limits
        .iter()
        .map(|l| convert::MotorLimit {
            motor: l.motor,
            max_velocity: l.max_velocity,
            max_accel: l.max_accel,
        })
        .collect();
    Ok((map, options))
}
