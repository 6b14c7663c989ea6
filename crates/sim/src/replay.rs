//! Replay: plan a G-code stream on the *believed* machine, generate its step streams with `stepgen`, execute
//! them on the *true* machine (motor model + true forward kinematics) and compare the reconstructed nozzle
//! path with the intended (planned) one.
//!
//! Streaming: pieces are handed to the step generator in chunks; the steps of all motors are merged in clock
//! order up to a horizon that no later step can precede. A motor whose last step is still held back by the
//! step+dir+step filter (its pending step may come out later) holds the horizon at its last released step,
//! so queued steps and pieces stay bounded by how long a motor rests mid-step (at most a layer for Z).
//!
//! Samples: just before every step event (where quantisation error peaks) and every `grid_interval`.
//! Each sample gives the time error (actual vs intended at the same instant) and the path deviation
//! (distance from the actual XY to the nearest intended segment, searched along the path around that
//! instant for twice the time error: a nozzle 1 mm behind on its path is not 1 mm off the path).

use crate::error::SimulationError;
use crate::machine::Machine;
use crate::metrics::{Analysis, DeviationStats, LayerStats, PathPoint, Sample, segment_distance};
use crate::motor::MotorTrack;
use ::machine::MachineSetup;
use kinematics::Kinematics;
use printjob::{PipelineError, plan_gcode};
use std::collections::VecDeque;
use std::io::BufRead;
use stepgen::{Step, StepGenConfig, StepGenerator};
use trapq::{MoveSink, Piece, Queue, SinkError, TrapezoidMove, Vec3};

/// Extra path length searched for the nearest intended point beyond twice the time error (mm).
const PATH_REACH_MARGIN: f64 = 0.1;

/// How densely to sample and how much to keep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayOptions {
    /// Samples at least this often (s), besides one before every step event.
    pub grid_interval: f64,
    /// Planned pieces are kept this long before and after a sample, for the nearest-path search (s).
    pub path_window: f64,
    /// Kept path points are at least this far apart (mm); doubles whenever `max_points` is reached.
    pub decimate: f64,
    pub max_points: usize,
    /// Toolhead pieces handed to the step generator at a time (results do not depend on it).
    pub chunk_pieces: usize,
    pub step_config: StepGenConfig,
    /// Also compute the local step resolution at every sample (3 extra forward solutions per sample).
    pub track_resolution: bool,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            grid_interval: 1e-3,
            path_window: 2.0,
            decimate: 0.05,
            max_points: 400_000,
            chunk_pieces: 4096,
            step_config: StepGenConfig::default(),
            track_resolution: false,
        }
    }
}

/// What a replay found.
#[derive(Debug, Clone)]
pub struct Replay {
    /// Statistics over deposited samples (extruding while moving).
    pub deposited: DeviationStats,
    /// Statistics over every sample, travel included.
    pub all: DeviationStats,
    /// Per-layer statistics (at most [`crate::metrics::MAX_LAYER_ROWS`] rows; consecutive layers merged beyond).
    pub layers: Vec<LayerStats>,
    /// Layers found (from Z changes while extruding; a spiral vase gives one per turn).
    pub layer_count: usize,
    /// Decimated path (intended and actual), in time order.
    pub path: Vec<PathPoint>,
    /// Spacing the kept path ended with (mm).
    pub decimate: f64,
    /// Largest ratio time error / local step resolution, when tracked.
    pub worst_resolution_ratio: Option<f64>,
    /// Steps executed per motor (name, count).
    pub steps: Vec<(String, u64)>,
    pub end_time: f64,
    pub warnings: Vec<String>,
}

/// Plan `gcode` on `believed`, execute its steps on `actual` and measure the deviation.
pub fn replay(
    believed: &MachineSetup,
    actual: &Machine,
    gcode: impl BufRead,
    source_name: &str,
    options: &ReplayOptions,
) -> Result<Replay, SimulationError> {
    let believed_kin = believed.kinematics.as_ref();
    if believed_kin.name() != actual.kinematics().name()
        || believed_kin.motors().len() != actual.kinematics().motors().len()
    {
        return Err(SimulationError::Machine(format!(
            "the believed machine ({}) and the true machine ({}) have different motors",
            believed_kin.name(),
            actual.kinematics().name()
        )));
    }
    let recorder = Recorder::new(believed_kin, actual, *options);
    let (recorder, summary) =
        plan_gcode(believed, gcode, source_name, recorder).map_err(simulation_error)?;
    let mut replay = recorder.finish()?;
    replay.end_time = summary.end_time;
    replay.warnings = summary
        .warnings
        .iter()
        .map(|w| w.message.clone())
        .chain(summary.gcode_warnings.iter().map(|w| w.to_string()))
        .collect();
    Ok(replay)
}

/// Planned pieces still needed for sampling, with a cursor at the piece covering the last sample time.
#[derive(Debug, Default)]
struct History {
    pieces: VecDeque<Piece>,
    cursor: usize,
}

impl History {
    fn push(&mut self, piece: Piece) {
        self.pieces.push_back(piece);
    }

    fn clear(&mut self) {
        self.pieces.clear();
        self.cursor = 0;
    }

    /// The last piece starting at or before `t` (times only increase between calls).
    fn at(&mut self, t: f64) -> Option<&Piece> {
        while self.cursor + 1 < self.pieces.len() && self.pieces[self.cursor + 1].print_time <= t {
            self.cursor += 1;
        }
        self.pieces.get(self.cursor).filter(|p| p.print_time <= t)
    }

    /// Drop pieces that ended before `t` (never the cursor piece).
    fn prune(&mut self, t: f64) {
        while self.cursor > 0 && self.pieces.front().is_some_and(|p| p.end_time() < t) {
            self.pieces.pop_front();
            self.cursor -= 1;
        }
    }

    /// XY distance from `p` to the intended path within `reach` mm of path length either side of the
    /// cursor piece (the nearest point of the path is that close when the time error is below reach/2).
    fn path_distance(&self, p: Vec3, reach: f64) -> Option<f64> {
        let current = self.pieces.get(self.cursor)?;
        let mut best = piece_distance(p, current);
        let mut walked = 0.0;
        for piece in self.pieces.range(..self.cursor).rev() {
            best = best.min(piece_distance(p, piece));
            walked += piece.distance(piece.duration).abs();
            if walked > reach {
                break;
            }
        }
        walked = 0.0;
        for piece in self.pieces.range(self.cursor + 1..) {
            best = best.min(piece_distance(p, piece));
            walked += piece.distance(piece.duration).abs();
            if walked > reach {
                break;
            }
        }
        Some(best)
    }

    fn end_time(&self) -> Option<f64> {
        self.pieces.back().map(Piece::end_time)
    }
}

/// The move sink that runs the whole simulation.
#[derive(Debug)]
struct Recorder<'k> {
    believed: &'k dyn Kinematics,
    actual: &'k Machine,
    options: ReplayOptions,
    generator: Option<StepGenerator<'k>>,
    chunk: Vec<Piece>,
    sinks: Vec<Vec<Step>>,
    queues: Vec<VecDeque<Step>>,
    emitted_net: Vec<i64>,
    last_emitted: Vec<Option<u64>>,
    tracks: Vec<MotorTrack>,
    step_counts: Vec<u64>,
    toolhead: History,
    extruder: History,
    /// Intended position before the first piece after a declared position.
    declared: Vec3,
    next_grid: u64,
    grid_ticks: u64,
    /// Next clock that may still be sampled.
    unsampled_from: u64,
    analysis: Analysis,
    motors: Vec<f64>,
    probe: Vec<f64>,
    error: Option<SimulationError>,
}

impl<'k> Recorder<'k> {
    fn new(believed: &'k dyn Kinematics, actual: &'k Machine, options: ReplayOptions) -> Self {
        let n = believed.motors().len();
        let tracks = believed
            .motors()
            .iter()
            .zip(actual.motor_errors())
            .map(|(m, e)| MotorTrack::new(*e, m.step_distance, 0.0))
            .collect();
        let grid_ticks = (options.grid_interval * options.step_config.clock_hz)
            .round()
            .max(1.0) as u64;
        Recorder {
            believed,
            actual,
            options,
            generator: None,
            chunk: Vec::with_capacity(options.chunk_pieces.max(1)),
            sinks: vec![Vec::new(); n],
            queues: vec![VecDeque::new(); n],
            emitted_net: vec![0; n],
            last_emitted: vec![None; n],
            tracks,
            step_counts: vec![0; n],
            toolhead: History::default(),
            extruder: History::default(),
            declared: [0.0; 3],
            next_grid: 0,
            grid_ticks,
            unsampled_from: 0,
            analysis: Analysis::new(options.decimate, options.max_points),
            motors: vec![0.0; n],
            probe: vec![0.0; n],
            error: None,
        }
    }

    fn hz(&self) -> f64 {
        self.options.step_config.clock_hz
    }

    fn clock_of(&self, t: f64) -> u64 {
        (t * self.hz() + 0.5).max(0.0) as u64
    }

    fn fail(&mut self, e: SimulationError) {
        self.error.get_or_insert(e);
    }

    /// Declared position (homing, or the first move's start): restart the generator and re-seat the motors.
    fn start_at(&mut self, xyz: Vec3) -> Result<(), SimulationError> {
        let mut readings = vec![0.0; self.tracks.len()];
        self.believed
            .inverse(xyz, &mut readings)
            .map_err(|e| {
                SimulationError::Machine(format!(
                    "declared position ({:.3}, {:.3}, {:.3}) is unreachable on the believed machine: {e}",
                    xyz[0], xyz[1], xyz[2]
                ))
            })?;
        for (track, r) in self.tracks.iter_mut().zip(&readings) {
            track.reseat(*r);
        }
        self.emitted_net.iter_mut().for_each(|n| *n = 0);
        self.last_emitted.iter_mut().for_each(|c| *c = None);
        self.declared = xyz;
        self.toolhead.clear();
        self.extruder.clear();
        self.generator = Some(StepGenerator::new(
            self.believed,
            xyz,
            None,
            self.options.step_config,
        )?);
        Ok(())
    }

    /// Run the step generator over the buffered chunk and sample as far as is safe.
    fn process_chunk(&mut self) -> Result<(), SimulationError> {
        let Some(t_end) = self.chunk.last().map(Piece::end_time) else {
            return Ok(());
        };
        let Some(generator) = self.generator.as_mut() else {
            return Ok(());
        };
        self.sinks.iter_mut().for_each(Vec::clear);
        generator.run_chunk(&self.chunk, &[], &mut self.sinks)?;
        self.chunk.clear();
        self.drain_sinks();
        let horizon = self.horizon(t_end);
        self.advance(horizon)
    }

    fn drain_sinks(&mut self) {
        for (i, sink) in self.sinks.iter_mut().enumerate() {
            for step in sink.drain(..) {
                self.emitted_net[i] += if step.dir { 1 } else { -1 };
                self.last_emitted[i] = Some(step.clock);
                self.queues[i].push_back(step);
            }
        }
    }

    /// Latest clock up to which every step has been released.
    fn horizon(&self, t_end: f64) -> u64 {
        let mut h = self
            .clock_of(t_end - self.options.path_window)
            .saturating_sub(1);
        if let Some(generator) = &self.generator {
            for i in 0..self.tracks.len() {
                let pushed = generator.motor(i).map_or(0, |m| m.net_steps());
                if pushed != self.emitted_net[i] {
                    // A held-back step: it comes after the last released one.
                    h = h.min(self.last_emitted[i].unwrap_or(0).saturating_sub(1));
                }
            }
        }
        h
    }

    /// Sample and apply every step event up to `horizon` (inclusive).
    fn advance(&mut self, horizon: u64) -> Result<(), SimulationError> {
        if self.generator.is_none() {
            // No declared position yet: the machine's state is unknown, there is nothing to compare.
            return Ok(());
        }
        loop {
            let event = self
                .queues
                .iter()
                .filter_map(|q| q.front().map(|s| s.clock))
                .min()
                .filter(|c| *c <= horizon);
            while self.next_grid < self.unsampled_from {
                self.next_grid += self.grid_ticks;
            }
            let grid = Some(self.next_grid).filter(|c| *c <= horizon);
            let clock = match (event, grid) {
                (None, None) => return Ok(()),
                (Some(e), Some(g)) => e.min(g),
                (Some(e), None) => e,
                (None, Some(g)) => g,
            };
            self.sample(clock)?;
            self.unsampled_from = clock + 1;
            if event == Some(clock) {
                self.apply_steps(clock);
            }
        }
    }

    fn apply_steps(&mut self, clock: u64) {
        for (i, queue) in self.queues.iter_mut().enumerate() {
            while queue.front().is_some_and(|s| s.clock == clock) {
                if let Some(step) = queue.pop_front() {
                    self.tracks[i].step(step.dir);
                    self.step_counts[i] += 1;
                }
            }
        }
    }

    fn sample(&mut self, clock: u64) -> Result<(), SimulationError> {
        let time = clock as f64 / self.hz();
        for (m, track) in self.motors.iter_mut().zip(&self.tracks) {
            *m = track.position();
        }
        let kin = self.actual.kinematics();
        let actual = kin
            .forward(&self.motors)
            .map_err(|source| SimulationError::Forward { time, source })?;
        for (m, track) in self.probe.iter_mut().zip(&self.tracks) {
            *m = track.reading();
        }
        let believed = self
            .believed
            .forward(&self.probe)
            .map_err(|source| SimulationError::Forward { time, source })?;
        let model_error = (actual[0] - believed[0]).hypot(actual[1] - believed[1]);
        let (intended, moving) = match self.toolhead.at(time) {
            Some(p) => {
                let local = (time - p.print_time).min(p.duration);
                (
                    p.position(local),
                    local < p.duration && p.velocity(local) > 1e-9,
                )
            }
            None => (self.declared, false),
        };
        let extruding = self.extruder.at(time).is_some_and(|p| {
            let local = time - p.print_time;
            local <= p.duration && p.velocity(local) * p.axes_r[0] > 1e-9
        });
        let time_error = (actual[0] - intended[0]).hypot(actual[1] - intended[1]);
        let path_deviation = self
            .toolhead
            .path_distance(actual, 2.0 * time_error + PATH_REACH_MARGIN)
            .map_or(time_error, |d| d.min(time_error));
        let resolution = if self.options.track_resolution {
            Some(self.resolution(actual, time)?)
        } else {
            None
        };
        let sample = Sample {
            time,
            intended,
            actual,
            time_error,
            path_deviation,
            model_error,
            deposited: moving && extruding,
            resolution,
        };
        self.analysis.record(&sample);
        let keep_from = time - 2.0 * self.options.path_window;
        self.toolhead.prune(keep_from);
        self.extruder.prune(keep_from);
        Ok(())
    }

    /// XY displacement of one step of each motor, summed: the finest the machine can place the nozzle here.
    fn resolution(&mut self, at: Vec3, time: f64) -> Result<f64, SimulationError> {
        let kin = self.actual.kinematics();
        let mut total = 0.0;
        for (i, motor) in self.believed.motors().iter().enumerate() {
            self.probe.copy_from_slice(&self.motors);
            self.probe[i] += motor.step_distance;
            let p = kin
                .forward(&self.probe)
                .map_err(|source| SimulationError::Forward { time, source })?;
            total += (p[0] - at[0]).hypot(p[1] - at[1]);
        }
        Ok(total)
    }

    /// Everything queued: finish the generator (its held-back steps are final) and sample to the end.
    fn flush_all(&mut self) -> Result<(), SimulationError> {
        let end = self
            .toolhead
            .end_time()
            .or(self.chunk.last().map(Piece::end_time));
        self.process_chunk()?;
        if let Some(generator) = self.generator.as_mut() {
            generator.finish(&mut self.sinks)?;
            self.drain_sinks();
        }
        let last_step = self
            .last_emitted
            .iter()
            .flatten()
            .copied()
            .max()
            .unwrap_or(0);
        let horizon = end.map_or(0, |t| self.clock_of(t)).max(last_step);
        self.advance(horizon)
    }

    fn finish(mut self) -> Result<Replay, SimulationError> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.flush_all()?;
        let steps = self
            .believed
            .motors()
            .iter()
            .zip(&self.step_counts)
            .map(|(m, n)| (m.name.clone(), *n))
            .collect();
        Ok(Replay {
            deposited: self.analysis.deposited,
            all: self.analysis.all,
            layers: self.analysis.layers,
            layer_count: self.analysis.layer_count,
            path: self.analysis.path,
            decimate: self.analysis.decimate,
            worst_resolution_ratio: self.analysis.worst_resolution_ratio,
            steps,
            end_time: 0.0,
            warnings: Vec::new(),
        })
    }
}

impl MoveSink for Recorder<'_> {
    /// A simulation error stops planning; it travels inside the sink error, typed ([`simulation_error`]).
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        self.take(queue, mv);
        match self.error.take() {
            Some(e) => Err(SinkError::new(e)),
            None => Ok(()),
        }
    }

    fn set_position(&mut self, xyz: Vec3, _e: f64) -> Result<(), SinkError> {
        if self.error.is_none() {
            let result = self.flush_all().and_then(|()| self.start_at(xyz));
            if let Err(e) = result {
                self.fail(e);
            }
        }
        match self.error.take() {
            Some(e) => Err(SinkError::new(e)),
            None => Ok(()),
        }
    }
}

impl Recorder<'_> {
    fn take(&mut self, queue: Queue, mv: &TrapezoidMove) {
        if self.error.is_some() {
            return;
        }
        match queue {
            Queue::Toolhead => {
                // The previous move's extruder piece has arrived by now: safe to process.
                if self.chunk.len() >= self.options.chunk_pieces.max(1)
                    && let Err(e) = self.process_chunk()
                {
                    return self.fail(e);
                }
                if self.generator.is_none()
                    && let Err(e) = self.start_at(mv.start_pos)
                {
                    return self.fail(e);
                }
                for piece in mv.pieces() {
                    self.chunk.push(piece);
                    self.toolhead.push(piece);
                }
            }
            Queue::Extruder => mv.pieces().for_each(|p| self.extruder.push(p)),
        }
    }
}

/// A planning error, with the recorder's own error taken back out of a sink error.
fn simulation_error(e: PipelineError) -> SimulationError {
    match e {
        PipelineError::Sink { error, .. } => match error.into_inner().downcast::<SimulationError>()
        {
            Ok(e) => *e,
            Err(other) => SimulationError::Machine(other.to_string()),
        },
        other => SimulationError::Plan(other),
    }
}

fn piece_distance(p: Vec3, piece: &Piece) -> f64 {
    segment_distance(p, piece.start_pos, piece.position(piece.duration))
}
