//! Planned moves in, steps out: a [`MoveSink`] that feeds a [`StepGenerator`] in chunks, so a planner can
//! stream into step generation with bounded memory. A declared position (homing, `SET_KINEMATIC_POSITION`)
//! finishes the running motors and restarts them at the new pose, as Klipper re-seats its steppers.

use kinematics::{Kinematics, Vec3};
use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use trapq::{MoveSink, Piece, Queue, SinkError, TrapezoidMove};

use crate::error::StepError;
use crate::generator::{
    ExtruderSpec, StepGenerator, extruder_motor, start_motor_positions, toolhead_motor,
};
use crate::motor::{MotorStepper, StepGenConfig};
use crate::sink::StepSink;

/// Pieces buffered per queue before the motors run over them (small enough that the first chunk reaches
/// the motors early and the last one leaves little work for the slowest motor alone).
const CHUNK_PIECES: usize = 2048;

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
        let toolhead = std::mem::take(&mut self.toolhead);
        let extruder = std::mem::take(&mut self.extruder_pieces);
        self.run_pieces(&toolhead, &extruder);
        self.toolhead = toolhead;
        self.extruder_pieces = extruder;
        self.toolhead.clear();
        self.extruder_pieces.clear();
    }

    /// Step every motor over one chunk of pieces (each queue in print-time order).
    fn run_pieces(&mut self, toolhead: &[Piece], extruder: &[Piece]) {
        if self.error.is_some() {
            return;
        }
        let Some(generator) = self.generator.as_mut() else {
            if !toolhead.is_empty() || !extruder.is_empty() {
                self.error = Some(StepError::NoStartPose);
            }
            return;
        };
        if let Err(e) = generator.run_chunk(toolhead, extruder, &mut self.sinks) {
            self.error = Some(e);
        } else if let Some(message) = self.sinks.iter().find_map(StepSink::failure) {
            self.error = Some(StepError::Output(message));
        }
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
    /// Fails once stepping has failed (the step error itself is [`StepPipeline::finish`]'s), so planning stops.
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        let buffer = match queue {
            Queue::Toolhead => &mut self.toolhead,
            Queue::Extruder => &mut self.extruder_pieces,
        };
        mv.push_pieces(buffer);
        if buffer.len() >= CHUNK_PIECES {
            self.run_buffered();
        }
        match &self.error {
            Some(e) => Err(SinkError::new(e.to_string())),
            None => Ok(()),
        }
    }

    fn set_position(&mut self, xyz: Vec3, e: f64) -> Result<(), SinkError> {
        self.run_buffered();
        self.finish_generator();
        if self.error.is_none() {
            let extruder = self.extruder.clone().map(|spec| ExtruderSpec {
                start_position: e,
                ..spec
            });
            match StepGenerator::new(self.kin, xyz, extruder, self.config) {
                Ok(generator) => self.generator = Some(generator),
                Err(e) => self.error = Some(e),
            }
        }
        match &self.error {
            Some(e) => Err(SinkError::new(e.to_string())),
            None => Ok(()),
        }
    }
}

/// One chunk of planned pieces, shared by every motor's thread.
#[derive(Debug, Default)]
struct Chunk {
    toolhead: Vec<Piece>,
    extruder: Vec<Piece>,
}

/// What the planning thread hands each motor's thread.
#[derive(Debug, Clone)]
enum Message {
    Chunk(Arc<Chunk>),
    SetPosition { xyz: Vec3, e: f64 },
}

/// Chunks queued per motor: bounded, so memory stays bounded and the planner waits for the slowest motor.
/// A short queue keeps the slowest motor (a polar bed) from falling far behind while the planner takes a core:
/// when planning ends, at most this many chunks are left for that motor alone, with the other core idle.
const CHUNKS_IN_FLIGHT: usize = 4;

/// The planning side of [`run_in_parallel`]: a [`MoveSink`] that buffers pieces and sends full chunks to
/// every motor's thread.
#[derive(Debug)]
pub struct ChunkSender {
    to_motors: Vec<SyncSender<Message>>,
    /// Chunks sent, oldest first; one that every motor has dropped is reused (no allocation per chunk).
    sent: VecDeque<Arc<Chunk>>,
    buffer: Chunk,
    /// A motor's thread stopped (it failed or was cancelled); later moves are dropped and the error is
    /// reported at the end.
    closed: bool,
}

impl ChunkSender {
    fn send_buffered(&mut self) {
        if self.buffer.toolhead.is_empty() && self.buffer.extruder.is_empty() {
            return;
        }
        let next = self.reusable_chunk();
        let full = std::mem::replace(&mut self.buffer, next);
        let chunk = Arc::new(full);
        self.send(&Message::Chunk(Arc::clone(&chunk)));
        self.sent.push_back(chunk);
        // More than this many cannot be alive at once; older ones are still held only by a slow motor.
        if self.sent.len() > CHUNKS_IN_FLIGHT + 2 {
            self.sent.pop_front();
        }
    }

    /// Empty buffers: the oldest sent chunk if every motor is done with it, else new ones.
    fn reusable_chunk(&mut self) -> Chunk {
        if let Some(oldest) = self.sent.front_mut()
            && let Some(chunk) = Arc::get_mut(oldest)
        {
            let mut reused = std::mem::take(chunk);
            reused.toolhead.clear();
            reused.extruder.clear();
            self.sent.pop_front();
            return reused;
        }
        Chunk {
            toolhead: Vec::with_capacity(CHUNK_PIECES),
            extruder: Vec::with_capacity(CHUNK_PIECES),
        }
    }

    fn send(&mut self, message: &Message) {
        if self.closed {
            return;
        }
        for to_motor in &self.to_motors {
            if to_motor.send(message.clone()).is_err() {
                self.closed = true;
            }
        }
    }
}

impl Drop for ChunkSender {
    /// Whatever is still buffered goes over when the planner is done with the sink.
    fn drop(&mut self) {
        self.send_buffered();
    }
}

impl MoveSink for ChunkSender {
    /// Fails once a motor has stopped (its error is [`run_in_parallel`]'s), so planning stops.
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        let buffer = match queue {
            Queue::Toolhead => &mut self.buffer.toolhead,
            Queue::Extruder => &mut self.buffer.extruder,
        };
        mv.push_pieces(buffer);
        if buffer.len() >= CHUNK_PIECES {
            self.send_buffered();
        }
        match self.closed {
            true => Err(SinkError::new("a motor's step generation stopped")),
            false => Ok(()),
        }
    }

    fn set_position(&mut self, xyz: Vec3, e: f64) -> Result<(), SinkError> {
        self.send_buffered();
        self.send(&Message::SetPosition { xyz, e });
        match self.closed {
            true => Err(SinkError::new("a motor's step generation stopped")),
            false => Ok(()),
        }
    }
}

/// Which motor a stepping thread drives.
#[derive(Debug, Clone, Copy)]
enum Slot {
    /// Toolhead motor number `n` of the kinematics.
    Toolhead(usize),
    Extruder,
}

/// A motor thread's error and the number of the message it failed on. Every motor receives every message up
/// to the first failure, so the earliest failure (then the first motor in sink order) is the error the
/// sequential [`StepPipeline`] reports, whichever thread happened to fail first.
#[derive(Debug)]
struct MotorFailure {
    message: usize,
    error: StepError,
}

/// One motor's stepping thread: its stepper (from the first declared position on), its sink and totals.
struct MotorThread<'k, S> {
    kin: &'k dyn Kinematics,
    slot: Slot,
    extruder: Option<ExtruderSpec>,
    config: StepGenConfig,
    stepper: Option<MotorStepper>,
    sink: S,
    filtered_pairs: u64,
}

impl<S: StepSink> MotorThread<'_, S> {
    /// Step through every message until the planner is done (or stops early), then release the held-back
    /// step. Returns the sink and the count of filtered step pairs.
    fn run(
        mut self,
        messages: Receiver<Message>,
        cancelled: fn() -> bool,
    ) -> Result<(S, u64), MotorFailure> {
        for (index, message) in messages.into_iter().enumerate() {
            let fail = |error| MotorFailure {
                message: index,
                error,
            };
            if cancelled() {
                return Err(fail(StepError::Cancelled));
            }
            match message {
                Message::Chunk(chunk) => self.step_chunk(&chunk).map_err(fail)?,
                Message::SetPosition { xyz, e } => self.restart(xyz, e).map_err(fail)?,
            }
            if let Some(message) = self.sink.failure() {
                return Err(fail(StepError::Output(message)));
            }
        }
        self.finish_stepper();
        Ok((self.sink, self.filtered_pairs))
    }

    fn step_chunk(&mut self, chunk: &Chunk) -> Result<(), StepError> {
        let pieces = match self.slot {
            Slot::Toolhead(_) => &chunk.toolhead,
            Slot::Extruder => &chunk.extruder,
        };
        match self.stepper.as_mut() {
            Some(stepper) => pieces
                .iter()
                .try_for_each(|piece| stepper.process(piece, self.kin, &mut self.sink)),
            None if pieces.is_empty() => Ok(()),
            None => Err(StepError::NoStartPose),
        }
    }

    /// A declared position: finish the running stepper and start afresh at the new pose, as
    /// [`StepPipeline`] does for all motors at once.
    fn restart(&mut self, xyz: Vec3, e: f64) -> Result<(), StepError> {
        self.finish_stepper();
        let stepper = match self.slot {
            Slot::Toolhead(index) => {
                let start_motors = start_motor_positions(self.kin, xyz)?;
                toolhead_motor(self.kin, index, &start_motors, self.config)?
            }
            Slot::Extruder => match self.extruder.clone() {
                Some(spec) => extruder_motor(spec, e, self.config)?,
                None => return Err(StepError::Config("no extruder to restart".into())),
            },
        };
        self.stepper = Some(stepper);
        Ok(())
    }

    fn finish_stepper(&mut self) {
        if let Some(mut stepper) = self.stepper.take() {
            stepper.finish(&mut self.sink);
            self.filtered_pairs += stepper.filtered_pairs();
        }
    }
}

/// Run `produce` (a planner writing into the given [`MoveSink`]; it must drop the sink before it returns, or
/// the motors wait for more) on this thread while every motor steps on a thread of its own, chunk by chunk:
/// planning and the motors overlap, and no motor waits for another (there is no barrier per chunk, so the
/// operating system keeps the cores busy with whichever threads have work). Returns what `produce` returned,
/// the sinks and each motor's count of filtered step pairs. The output is the same as [`StepPipeline`]'s,
/// and so is the error when motors fail (the earliest failure, then the first motor in sink order).
///
/// `cancelled` is polled between chunks: when it turns true, the motors drop the work still queued and the
/// call fails with [`StepError::Cancelled`] (e.g. on Ctrl-C, so partial output is discarded quickly).
pub fn run_in_parallel<S, R, F>(
    kin: &dyn Kinematics,
    extruder: Option<ExtruderSpec>,
    config: StepGenConfig,
    sinks: Vec<S>,
    cancelled: fn() -> bool,
    produce: F,
) -> Result<(R, Vec<S>, Vec<u64>), StepError>
where
    S: StepSink + Send,
    F: FnOnce(ChunkSender) -> R,
{
    let toolhead_motors = kin.motors().len();
    let slots: Vec<Slot> = (0..toolhead_motors)
        .map(Slot::Toolhead)
        .chain(extruder.is_some().then_some(Slot::Extruder))
        .collect();
    if sinks.len() != slots.len() {
        return Err(StepError::Config(format!(
            "{} sinks for {} motors",
            sinks.len(),
            slots.len()
        )));
    }
    std::thread::scope(|scope| {
        let mut to_motors = Vec::with_capacity(slots.len());
        let mut threads = Vec::with_capacity(slots.len());
        for (slot, sink) in slots.into_iter().zip(sinks) {
            let (to_motor, messages) = sync_channel::<Message>(CHUNKS_IN_FLIGHT);
            to_motors.push(to_motor);
            let motor = MotorThread {
                kin,
                slot,
                extruder: extruder.clone(),
                config,
                stepper: None,
                sink,
                filtered_pairs: 0,
            };
            threads.push(scope.spawn(move || motor.run(messages, cancelled)));
        }
        let sender = ChunkSender {
            to_motors,
            sent: VecDeque::with_capacity(CHUNKS_IN_FLIGHT + 3),
            buffer: Chunk {
                toolhead: Vec::with_capacity(CHUNK_PIECES),
                extruder: Vec::with_capacity(CHUNK_PIECES),
            },
            closed: false,
        };
        // `produce` owns the sender; when it drops it, the last chunk goes over and the channels close.
        let produced = produce(sender);
        let mut sinks = Vec::with_capacity(threads.len());
        let mut filtered = Vec::with_capacity(threads.len());
        let mut first_error = None;
        for thread in threads {
            match thread.join() {
                Ok(Ok((sink, pairs))) => {
                    sinks.push(sink);
                    filtered.push(pairs);
                }
                Ok(Err(failure)) => keep_earliest(&mut first_error, failure),
                Err(_) => keep_earliest(
                    &mut first_error,
                    MotorFailure {
                        message: 0,
                        error: StepError::Config("a stepping thread panicked".into()),
                    },
                ),
            }
        }
        match first_error {
            Some(failure) => Err(failure.error),
            None => Ok((produced, sinks, filtered)),
        }
    })
}

/// Keep `failure` if it happened before the one kept so far (on a tie, the one kept comes first in sink order).
fn keep_earliest(kept: &mut Option<MotorFailure>, failure: MotorFailure) {
    if kept
        .as_ref()
        .is_none_or(|first| failure.message < first.message)
    {
        *kept = Some(failure);
    }
}
