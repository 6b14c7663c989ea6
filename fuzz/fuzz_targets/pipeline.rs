//! Fuzz target `pipeline`: arbitrary G-code bytes through the whole `run` pipeline (interpreter, planner with
//! lookahead, step generation) on the fixed example Cartesian machine.
//!
//! Invariants: no panic; a successful plan has a finite, non-negative print time; step clocks never go
//! backwards on any motor.
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use motion::machine::MachineSetup;
use printjob::plan_gcode;
use stepgen::{ExtruderSpec, StepGenConfig, StepPipeline, StepSink};

const MACHINE: &str = include_str!("../../examples/machines/cartesian.cfg");

/// Counts steps and checks that clocks are monotone.
#[derive(Debug, Default)]
struct MonotoneSink {
    last_clock: u64,
    steps: u64,
}

impl StepSink for MonotoneSink {
    fn step(&mut self, clock: u64, _dir: bool) {
        assert!(
            clock >= self.last_clock,
            "step clock went back from {} to {clock}",
            self.last_clock
        );
        self.last_clock = clock;
        self.steps += 1;
    }
}

fn machine() -> &'static config::MachineConfig {
    static MACHINE_CONFIG: OnceLock<config::MachineConfig> = OnceLock::new();
    MACHINE_CONFIG.get_or_init(|| {
        config::MachineConfig::from_str(MACHINE, "examples/machines/cartesian.cfg")
            .expect("example machine is valid")
    })
}

fuzz_target!(|data: &[u8]| {
    let machine = machine();
    let setup = MachineSetup::from_config(machine).expect("example machine builds");
    let extruder = machine.extruder.as_ref().map(|e| ExtruderSpec {
        name: e.stepper.name.clone(),
        step_distance: e.stepper.step_distance,
        start_position: 0.0,
    });
    let motors = setup.kinematics.motors().len() + usize::from(extruder.is_some());
    let sinks: Vec<MonotoneSink> = (0..motors).map(|_| MonotoneSink::default()).collect();
    let pipeline = StepPipeline::new(
        setup.kinematics.as_ref(),
        extruder,
        StepGenConfig::default(),
        sinks,
    );
    match plan_gcode(&setup, data, "fuzz.gcode", pipeline) {
        Ok((pipeline, summary)) => {
            assert!(
                summary.end_time.is_finite() && summary.end_time >= 0.0,
                "print time {}",
                summary.end_time
            );
            let _ = pipeline.finish();
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
