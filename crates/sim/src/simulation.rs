//! One simulation: plan the G-code on the believed machine, replay its step streams on the machine as built,
//! and measure the printed features.

use crate::error::SimulationError;
use crate::features::{CircleFeature, QuadFeature, find_circles, find_quads};
use crate::machine::Machine;
use crate::replay::{Replay, ReplayOptions, replay};
use config::MachineConfig;
use std::io::BufRead;

/// One simulation: the replay and the features measured on it.
#[derive(Debug, Clone)]
pub struct Simulation {
    pub replay: Replay,
    pub circles: Vec<CircleFeature>,
    pub quads: Vec<QuadFeature>,
}

/// Plan `gcode` on the believed config, run it on `actual`, measure features.
pub fn simulate(
    believed: &MachineConfig,
    actual: &Machine,
    gcode: impl BufRead,
    source_name: &str,
    options: &ReplayOptions,
) -> Result<Simulation, SimulationError> {
    // Built by the one machine builder, as `jointspace run` and the plug-in build it.
    let believed = ::machine::Machine::from_config(believed.clone(), source_name)?;
    let replay = replay(&believed.setup, actual, gcode, source_name, options)?;
    let circles = find_circles(&replay.path);
    let quads = find_quads(&replay.path);
    Ok(Simulation {
        replay,
        circles,
        quads,
    })
}
