//! Step generation for a whole machine: one [`MotorStepper`] per motor (toolhead motors from the
//! kinematics, plus an optional extruder fed from its own queue), run in parallel over chunks of pieces.
//!
//! Motors are independent, so each chunk is processed by all motors at once (rayon); every motor handles its
//! pieces sequentially, which makes the output identical whatever the thread count. Memory is bounded by the
//! chunk size: steps go straight to each motor's sink.

use kinematics::{Kinematics, Vec3};
use rayon::prelude::*;
use trapq::{Piece, Queue, TrapezoidMove};

use crate::error::StepError;
use crate::motor::{MotorModel, MotorSpec, MotorStepper, StepGenConfig};
use crate::sink::StepSink;

/// The extruder motor: name, step distance (mm of filament per step) and start position (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct ExtruderSpec {
    pub name: String,
    pub step_distance: f64,
    pub start_position: f64,
}

/// Step generators for every motor of a machine.
#[derive(Debug)]
pub struct StepGenerator<'k> {
    kin: &'k dyn Kinematics,
    motors: Vec<(Queue, MotorStepper)>,
}

impl<'k> StepGenerator<'k> {
    /// Motors of `kin` (in its order) starting at toolhead pose `start`, then the extruder if given.
    pub fn new(
        kin: &'k dyn Kinematics,
        start: Vec3,
        extruder: Option<ExtruderSpec>,
        config: StepGenConfig,
    ) -> Result<Self, StepError> {
        let start_motors = start_motor_positions(kin, start)?;
        let mut motors = Vec::with_capacity(start_motors.len() + 1);
        for index in 0..start_motors.len() {
            let stepper = toolhead_motor(kin, index, &start_motors, config)?;
            motors.push((Queue::Toolhead, stepper));
        }
        if let Some(e) = extruder {
            let start_position = e.start_position;
            motors.push((Queue::Extruder, extruder_motor(e, start_position, config)?));
        }
        Ok(StepGenerator { kin, motors })
    }

    /// Number of motors (toolhead motors, then the extruder).
    pub fn motor_count(&self) -> usize {
        self.motors.len()
    }

    /// Motor names, in sink order.
    pub fn motor_names(&self) -> Vec<String> {
        self.motors
            .iter()
            .map(|(_, m)| m.spec().name.clone())
            .collect()
    }

    pub fn motor(&self, index: usize) -> Option<&MotorStepper> {
        self.motors.get(index).map(|(_, m)| m)
    }

    /// Process one chunk of pieces: `toolhead` and `extruder` pieces, each in print-time order and
    /// continuing the previous chunk. `sinks` has one sink per motor and holds every final step of the chunk
    /// when this returns (only each motor's held-back step waits). Motors run in parallel.
    pub fn run_chunk<S: StepSink + Send>(
        &mut self,
        toolhead: &[Piece],
        extruder: &[Piece],
        sinks: &mut [S],
    ) -> Result<(), StepError> {
        self.check_sinks(sinks.len())?;
        let kin = self.kin;
        let results: Vec<Result<(), StepError>> = self
            .motors
            .par_iter_mut()
            .zip(sinks.par_iter_mut())
            .map(|((queue, motor), sink)| {
                let pieces = match queue {
                    Queue::Toolhead => toolhead,
                    Queue::Extruder => extruder,
                };
                pieces
                    .iter()
                    .try_for_each(|piece| motor.process(piece, kin, sink))?;
                // The chunk's final steps reach the sinks now (a simulator reads them chunk by chunk).
                motor.flush(sink);
                Ok(())
            })
            .collect();
        // Report the first motor's error, deterministically.
        results.into_iter().collect()
    }

    /// End of input: release every motor's held-back step.
    pub fn finish<S: StepSink + Send>(&mut self, sinks: &mut [S]) -> Result<(), StepError> {
        self.check_sinks(sinks.len())?;
        for ((_, motor), sink) in self.motors.iter_mut().zip(sinks.iter_mut()) {
            motor.finish(sink);
        }
        Ok(())
    }

    /// Stream a whole move list: pieces are buffered per queue and processed `chunk_pieces` at a time,
    /// then [`Self::finish`] is called.
    pub fn run_moves<S, I>(
        &mut self,
        moves: I,
        chunk_pieces: usize,
        sinks: &mut [S],
    ) -> Result<(), StepError>
    where
        S: StepSink + Send,
        I: IntoIterator<Item = (Queue, TrapezoidMove)>,
    {
        let chunk = chunk_pieces.max(1);
        let mut toolhead = Vec::with_capacity(chunk);
        let mut extruder = Vec::with_capacity(chunk);
        for (queue, mv) in moves {
            let buffer = match queue {
                Queue::Toolhead => &mut toolhead,
                Queue::Extruder => &mut extruder,
            };
            mv.push_pieces(buffer);
            if toolhead.len() >= chunk || extruder.len() >= chunk {
                self.run_chunk(&toolhead, &extruder, sinks)?;
                toolhead.clear();
                extruder.clear();
            }
        }
        self.run_chunk(&toolhead, &extruder, sinks)?;
        self.finish(sinks)
    }

    fn check_sinks(&self, count: usize) -> Result<(), StepError> {
        if count == self.motors.len() {
            Ok(())
        } else {
            Err(StepError::Config(format!(
                "{} sinks for {} motors",
                count,
                self.motors.len()
            )))
        }
    }
}

/// Every toolhead motor's position at toolhead pose `start`.
pub(crate) fn start_motor_positions(
    kin: &dyn Kinematics,
    start: Vec3,
) -> Result<Vec<f64>, StepError> {
    let mut start_motors = vec![0.0; kin.motors().len()];
    kin.inverse(start, &mut start_motors)
        .map_err(|source| StepError::Unreachable {
            motor: "start pose".to_string(),
            time: 0.0,
            source,
        })?;
    Ok(start_motors)
}

/// Toolhead motor `index` of `kin`, starting where `start_motors` (from [`start_motor_positions`]) puts it.
pub(crate) fn toolhead_motor(
    kin: &dyn Kinematics,
    index: usize,
    start_motors: &[f64],
    config: StepGenConfig,
) -> Result<MotorStepper, StepError> {
    let motor = &kin.motors()[index];
    let spec = MotorSpec {
        name: motor.name.clone(),
        step_distance: motor.step_distance,
        model: MotorModel::from_map(kin.motor_map(index), index),
    };
    check_step_distance(&spec)?;
    Ok(MotorStepper::new(
        spec,
        start_motors[index],
        start_motors,
        config,
    ))
}

/// The extruder motor, starting at `start_position` (mm of filament).
pub(crate) fn extruder_motor(
    extruder: ExtruderSpec,
    start_position: f64,
    config: StepGenConfig,
) -> Result<MotorStepper, StepError> {
    let spec = MotorSpec {
        name: extruder.name,
        step_distance: extruder.step_distance,
        model: MotorModel::Linear {
            coeffs: [1.0, 0.0, 0.0],
        },
    };
    check_step_distance(&spec)?;
    Ok(MotorStepper::new(spec, start_position, &[], config))
}

fn check_step_distance(spec: &MotorSpec) -> Result<(), StepError> {
    if spec.step_distance.is_finite() && spec.step_distance > 0.0 {
        Ok(())
    } else {
        Err(StepError::Config(format!(
            "{}: step distance {} must be positive",
            spec.name, spec.step_distance
        )))
    }
}
