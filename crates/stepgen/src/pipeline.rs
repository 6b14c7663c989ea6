//! Planned moves in, steps out: a [`MoveSink`] that feeds a [`StepGenerator`] in chunks, so a planner can
//! stream into step generation with bounded memory. A declared position (homing, `SET_KINEMATIC_POSITION`)
//! finishes the running motors and restarts them at the new pose, as Klipper re-seats its steppers.

use kinematics::{Kinematics, Vec3};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
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

/// What the planning thread hands the stepping thread.
enum Message {
    Chunk {
        toolhead: Vec<Piece>,
        extruder: Vec<Piece>,
    },
    SetPosition {
        xyz: Vec3,
        e: f64,
    },
}

/// Chunks in flight between the threads (bounded, so memory stays bounded).
const CHUNKS_IN_FLIGHT: usize = 4;

/// The planning side of [`run_in_parallel`]: a [`MoveSink`] that buffers pieces and sends full chunks over.
#[derive(Debug)]
pub struct ChunkSender {
    to_stepper: SyncSender<Message>,
    recycled: Receiver<(Vec<Piece>, Vec<Piece>)>,
    toolhead: Vec<Piece>,
    extruder: Vec<Piece>,
    /// The stepping thread stopped (it failed); later moves are dropped and the error is reported at the end.
    closed: bool,
}

impl std::fmt::Debug for Message {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Message::Chunk { toolhead, extruder } => {
                write!(f, "Chunk({}, {})", toolhead.len(), extruder.len())
            }
            Message::SetPosition { xyz, e } => write!(f, "SetPosition({xyz:?}, {e})"),
        }
    }
}

impl ChunkSender {
    fn send_buffered(&mut self) {
        if self.toolhead.is_empty() && self.extruder.is_empty() {
            return;
        }
        let (mut toolhead, mut extruder) = self.recycled.try_recv().unwrap_or_else(|_| {
            (
                Vec::with_capacity(CHUNK_PIECES),
                Vec::with_capacity(CHUNK_PIECES),
            )
        });
        std::mem::swap(&mut toolhead, &mut self.toolhead);
        std::mem::swap(&mut extruder, &mut self.extruder);
        self.toolhead.clear();
        self.extruder.clear();
        self.send(Message::Chunk { toolhead, extruder });
    }

    fn send(&mut self, message: Message) {
        if !self.closed && self.to_stepper.send(message).is_err() {
            self.closed = true;
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
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) {
        let buffer = match queue {
            Queue::Toolhead => &mut self.toolhead,
            Queue::Extruder => &mut self.extruder,
        };
        buffer.extend(mv.pieces());
        if buffer.len() >= CHUNK_PIECES {
            self.send_buffered();
        }
    }

    fn set_position(&mut self, xyz: Vec3, e: f64) {
        self.send_buffered();
        self.send(Message::SetPosition { xyz, e });
    }
}

/// Run `produce` (a planner writing into the given [`MoveSink`]; it must drop the sink before it returns, or
/// the stepping thread waits for more) on this thread while the motors step on
/// another, chunk by chunk: planning and stepping overlap. Returns what `produce` returned, the sinks and each
/// motor's count of filtered step pairs. The output is the same as [`StepPipeline`]'s.
///
/// `cancelled` is polled between chunks: when it turns true, the stepping thread drops the work still queued
/// and the call fails with [`StepError::Cancelled`] (e.g. on Ctrl-C, so partial output is discarded quickly).
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
    let (to_stepper, from_planner) = sync_channel::<Message>(CHUNKS_IN_FLIGHT);
    let (recycle, recycled) = sync_channel::<(Vec<Piece>, Vec<Piece>)>(CHUNKS_IN_FLIGHT + 2);
    std::thread::scope(|scope| {
        let stepper = scope.spawn(move || {
            let mut pipeline = StepPipeline::new(kin, extruder, config, sinks);
            for message in from_planner {
                if cancelled() {
                    pipeline.error = Some(StepError::Cancelled);
                    break;
                }
                match message {
                    Message::Chunk {
                        mut toolhead,
                        mut extruder,
                    } => {
                        pipeline.run_pieces(&toolhead, &extruder);
                        toolhead.clear();
                        extruder.clear();
                        let _ = recycle.try_send((toolhead, extruder));
                    }
                    Message::SetPosition { xyz, e } => {
                        MoveSink::set_position(&mut pipeline, xyz, e)
                    }
                }
                if pipeline.error.is_some() {
                    break;
                }
            }
            pipeline.finish()
        });
        let sender = ChunkSender {
            to_stepper,
            recycled,
            toolhead: Vec::with_capacity(CHUNK_PIECES),
            extruder: Vec::with_capacity(CHUNK_PIECES),
            closed: false,
        };
        // `produce` owns the sender; when it drops it, the last chunk goes over and the channel closes.
        let produced = produce(sender);
        let (sinks, filtered) = stepper
            .join()
            .map_err(|_| StepError::Config("the stepping thread panicked".into()))??;
        Ok((produced, sinks, filtered))
    })
}
