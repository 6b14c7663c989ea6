//! Planned moves in, steps out: a [`MoveSink`] that feeds a [`StepGenerator`] in chunks, so a planner can
//! stream into step generation with bounded memory. A declared position (homing, `SET_KINEMATIC_POSITION`)
//! finishes the running motors and restarts them at the new pose, as Klipper re-seats its steppers.

use kinematics::{Kinematics, Vec3};
use trapq::{MoveSink, Piece, Queue, TrapezoidMove};

use crate::error::StepError;
use crate::generator::{ExtruderSpec, StepGenerator};
use crate::motor::StepGenConfig;
use crate::sink::StepSink;

/// Pieces buffered per queue before the motors run over them.
const CHUNK_PIECES: usize = 8192;

/// Streams planned moves into per-motor step sinks.
#[derive(Debug)]
pub struct StepPipeline<'k, S: StepSink + Send> {
    kin: &'k dyn Kinematics,
    config: StepGenConfig,
    extruder: Option<ExtruderSpec>,
    generator: Option<StepGenerator<'k>>,
    toolhead: Vec<Piece>,
    extruder_pieces: Vec<Piece>,
    sinks: Vec<S>,
    /// Filtered step pairs of generators already finished (a restart finishes them).
    filtered_pairs: Vec<u64>,
    error: Option<StepError>,
}

impl<'k, S: StepSink + Send> StepPipeline<'k, S> {
    /// Motors of `kin` plus the optional extruder; `sinks` has one sink per motor in that order. Nothing is
    /// generated before the first [`MoveSink::set_position`] fixes the start pose.
    pub fn new(
        kin: &'k dyn Kinematics,
        extruder: Option<ExtruderSpec>,
        config: StepGenConfig,
        sinks: Vec<S>,
    ) -> Self {
        let motors = kin.motors().len() + usize::from(extruder.is_some());
        StepPipeline {
            kin,
            config,
            extruder,
            generator: None,
            toolhead: Vec::with_capacity(CHUNK_PIECES),
            extruder_pieces: Vec::with_capacity(CHUNK_PIECES),
            sinks,
            filtered_pairs: vec![0; motors],
            error: None,
        }
    }

    /// Motor names in sink order.
    pub fn motor_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.kin.motors().iter().map(|m| m.name.clone()).collect();
        if let Some(e) = &self.extruder {
            names.push(e.name.clone());
        }
        names
    }

    /// Run the buffered pieces, release every held-back step and hand back the sinks with each motor's count
    /// of filtered step pairs.
    pub fn finish(mut self) -> Result<(Vec<S>, Vec<u64>), StepError> {
        self.run_buffered();
        self.finish_generator();
        match self.error {
            Some(e) => Err(e),
            None => Ok((self.sinks, self.filtered_pairs)),
        }
    }

    fn run_buffered(&mut self) {
        if self.error.is_some() {
            return;
        }
        let Some(generator) = self.generator.as_mut() else {
            if !self.toolhead.is_empty() || !self.extruder_pieces.is_empty() {
                self.error = Some(StepError::NoStartPose);
            }
            return;
        };
        if let Err(e) = generator.run_chunk(&self.toolhead, &self.extruder_pieces, &mut self.sinks)
        {
            self.error = Some(e);
        }
        self.toolhead.clear();
        self.extruder_pieces.clear();
    }

    fn finish_generator(&mut self) {
        if let Some(mut generator) = self.generator.take() {
            if let Err(e) = generator.finish(&mut self.sinks) {
                self.error.get_or_insert(e);
            }
            for (index, total) in self.filtered_pairs.iter_mut().enumerate() {
                *total += generator.motor(index).map_or(0, |m| m.filtered_pairs());
            }
        }
    }
}

impl<S: StepSink + Send> MoveSink for StepPipeline<'_, S> {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) {
        let buffer = match queue {
            Queue::Toolhead => &mut self.toolhead,
            Queue::Extruder => &mut self.extruder_pieces,
        };
        buffer.extend(mv.pieces());
        if buffer.len() >= CHUNK_PIECES {
            self.run_buffered();
        }
    }

    fn set_position(&mut self, xyz: Vec3, e: f64) {
        self.run_buffered();
        self.finish_generator();
        if self.error.is_some() {
            return;
        }
        let extruder = self.extruder.clone().map(|spec| ExtruderSpec {
            start_position: e,
            ..spec
        });
        match StepGenerator::new(self.kin, xyz, extruder, self.config) {
            Ok(generator) => self.generator = Some(generator),
            Err(e) => self.error = Some(e),
        }
    }
}
