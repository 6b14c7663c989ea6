//! Estimating a print: the stream planned without steps, its time broken down by layer and feature type (the
//! slicer's markers), the time each motor limit of the machine adds, the slicer's own estimate beside it, and the
//! planned time at chosen lines (progress lines, elapsed-time comments) for rewriting a file's time estimates.
//!
//! The planned time is split at the print time of the first move of each part: a part's time runs from its first
//! move to the next part's first move (waits included), so the parts add up to the total.

use std::cell::RefCell;
use std::collections::{HashMap, VecDeque};
use std::io::BufRead;
use std::rc::Rc;

use gcode::{Command, Meta, Spanned};
use machine::{Machine, MachineSetup, PlanOptions};
use serde::Serialize;
use trapq::{MoveSink, Queue, SinkError, TrapezoidMove};

use crate::plan::{Observer, PipelineError, plan_gcode_watched};
use crate::run::{WarningLine, warning_lines};

/// A part of the print: a layer or a feature type.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Part {
    /// The layer's number (or Z where the slicer gives no number), or the feature type, as the slicer wrote it;
    /// `None`: what comes before the first marker.
    pub name: Option<String>,
    /// The layer's Z, where the slicer gives it.
    pub z: Option<f64>,
    /// The line of its first marker (0: before the first).
    pub line: u64,
    /// Planned time (s).
    pub time: f64,
    /// Time the machine's motor limits add here (s): the planned time less the time planned without them.
    pub lost: f64,
}

/// The time one motor limit adds to the print on its own.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LimitCost {
    /// The stepper's config section.
    pub motor: String,
    /// rad/s, or mm/s for a linear motor; steps/s limits are given as the motor's speed.
    pub max_velocity: Option<f64>,
    pub max_accel: Option<f64>,
    /// Planned time with only this limit, less the time without any motor limit (s).
    pub lost: f64,
}

/// A move a machine limit slowed below a quarter of its requested speed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlowLine {
    pub line: u64,
    pub requested: f64,
    pub allowed: f64,
}

/// What [`estimate`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Estimate {
    /// Print time at which the last move ends (s), as [`crate::plan_gcode`] plans it.
    pub total: f64,
    /// The same file planned without the machine's motor limits (polar bed, SCARA joints, step rates): what
    /// Klipper's own planner makes of the path at the requested speeds (s).
    pub without_motor_limits: f64,
    /// With `--klipper-batch`: the print time Klipper's batch mode logs at the end of the input, for comparisons
    /// with it (the end of the print, or where its step generation could restart when that is later).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub klipper_exit_time: Option<f64>,
    /// A polar machine with `max_angular_velocity`: the planned time under Klipper's own rule instead of the
    /// motor limits (whole moves slowed by the bed's speed at their closest approach to the centre, as Klipper's
    /// `polar` and the plug-in's `centre_slowdown: klipper` plan), in s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub klipper_rule: Option<f64>,
    /// The slicer's own estimate (s), the first the file states.
    pub slicer: Option<f64>,
    pub layers: Vec<Part>,
    pub features: Vec<Part>,
    pub limits: Vec<LimitCost>,
    /// The lines of the first moves slowed hard (each at its slowest), and how many moves in all.
    pub slowed: Vec<SlowLine>,
    pub slowed_total: u64,
    pub warnings: Vec<WarningLine>,
    /// The planned time at each line asked for: when the first move after it starts (the end of the print after
    /// the last move).
    #[serde(skip)]
    pub marks: Vec<(u64, f64)>,
}

/// A source of the same G-code stream, once per planning pass.
pub type Reopen<'a> = &'a dyn Fn() -> std::io::Result<Box<dyn BufRead + 'a>>;

/// Plan the stream of `open` on `machine` (as `options` say) and break its time down. `wanted` says which
/// commands' lines get their planned time in [`Estimate::marks`]. With motor limits, the stream is planned
/// again without them, and once with each alone.
pub fn estimate(
    machine: &Machine,
    options: PlanOptions,
    open: Reopen<'_>,
    name: &str,
    wanted: &dyn Fn(&Command) -> bool,
) -> Result<Estimate, EstimateError> {
    estimate_watched(
        machine,
        options,
        open,
        name,
        wanted,
        &mut (),
        &mut NoObserver,
    )
}

/// [`estimate`], handing the pass whose moves the estimate is (the machine with all its limits) to `moves` and
/// `observer` as well: a consumer that shows the planned print beside its numbers plans nothing itself.
pub fn estimate_watched(
    machine: &Machine,
    options: PlanOptions,
    open: Reopen<'_>,
    name: &str,
    wanted: &dyn Fn(&Command) -> bool,
    moves: &mut dyn MoveSink,
    observer: &mut dyn Observer,
) -> Result<Estimate, EstimateError> {
    let setup = machine.setup_with(options);
    let planned = breakdown(&setup, open, name, wanted, moves, observer)?;
    let mut free = setup.clone();
    free.planner.kinematic_limits.clear();
    let unlimited = if setup.planner.kinematic_limits.is_empty() {
        planned.clone()
    } else {
        breakdown(&free, open, name, &|_| false, &mut (), &mut NoObserver)?
    };
    let mut limits = Vec::new();
    for limit in &setup.planner.kinematic_limits {
        let mut alone = free.clone();
        alone.planner.kinematic_limits = vec![*limit];
        let time = breakdown(&alone, open, name, &|_| false, &mut (), &mut NoObserver)?.total;
        limits.push(LimitCost {
            motor: setup.kinematics.motors()[limit.motor].name.clone(),
            max_velocity: limit.max_velocity,
            max_accel: limit.max_accel,
            lost: time - unlimited.total,
        });
    }
    let klipper_rule = match (
        setup.kinematics.turning_limits(),
        machine.config.limits.max_angular_velocity,
    ) {
        (Some(kinematics::TurningLimits::Bed), Some(v_rad_max)) => {
            let mut rule = free.clone();
            rule.planner.klipper_centre_rule = Some(v_rad_max);
            let pass = breakdown(&rule, open, name, &|_| false, &mut (), &mut NoObserver)?;
            Some(pass.total)
        }
        _ => None,
    };
    let mut estimate = planned.into_estimate(&unlimited, limits);
    estimate.klipper_rule = klipper_rule;
    Ok(estimate)
}

/// Sees nothing (the passes no one watches).
struct NoObserver;

impl Observer for NoObserver {
    fn command(&mut self, _command: &Spanned<Command>) {}
}

/// A watcher's sink, lent for one pass.
struct Lent<'a>(&'a mut dyn MoveSink);

impl MoveSink for Lent<'_> {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        self.0.append(queue, mv)
    }
    fn origin(&mut self, origin: u64) {
        self.0.origin(origin);
    }
    fn flush(&mut self, print_time: f64) -> Result<(), SinkError> {
        self.0.flush(print_time)
    }
    fn set_position(&mut self, xyz: trapq::Vec3, e: f64) -> Result<(), SinkError> {
        self.0.set_position(xyz, e)
    }
}

/// The estimate's reader and a watcher's, one after the other.
struct Both<'a, 'w> {
    reader: &'a mut Markers,
    wanted: &'a dyn Fn(&Command) -> bool,
    watcher: &'w mut dyn Observer,
}

impl Observer for Both<'_, '_> {
    fn command(&mut self, command: &Spanned<Command>) {
        self.reader.observe(command, self.wanted);
        self.watcher.command(command);
    }

    fn refused(&mut self, command: &Spanned<Command>, at: [f64; 4], reason: &str) {
        self.watcher.refused(command, at, reason);
    }
}

/// Why an estimate could not be made.
#[derive(Debug, thiserror::Error)]
pub enum EstimateError {
    #[error("cannot read {name}: {source}")]
    Read {
        name: String,
        source: std::io::Error,
    },
    #[error(transparent)]
    Plan(#[from] PipelineError),
}

/// One planning pass: the time of each layer and feature, and at each wanted line.
#[derive(Debug, Clone)]
struct Breakdown {
    total: f64,
    layers: Vec<Part>,
    features: Vec<Part>,
    slicer: Option<f64>,
    marks: Vec<(u64, f64)>,
    summary: crate::PlanSummary,
}

fn breakdown(
    setup: &MachineSetup,
    open: Reopen<'_>,
    name: &str,
    wanted: &dyn Fn(&Command) -> bool,
    moves: &mut dyn MoveSink,
    watcher: &mut dyn Observer,
) -> Result<Breakdown, EstimateError> {
    let input = open().map_err(|source| EstimateError::Read {
        name: name.to_string(),
        source,
    })?;
    let queued = Rc::new(RefCell::new(Queued::default()));
    let mut reader = Markers::new(Rc::clone(&queued));
    let sink = (Timeline::new(queued), Lent(moves));
    let mut observer = Both {
        reader: &mut reader,
        wanted,
        watcher,
    };
    let ((mut sink, _), summary) = plan_gcode_watched(setup, input, name, sink, &mut observer)?;
    sink.advance(u64::MAX, summary.end_time);
    sink.charge(summary.end_time);
    let mut layers = reader.layers;
    let mut features = reader.features;
    for (part, time) in layers.iter_mut().zip(&sink.layer_time) {
        part.time = *time;
    }
    for (part, time) in features.iter_mut().zip(&sink.feature_time) {
        part.time = *time;
    }
    Ok(Breakdown {
        total: summary.end_time,
        layers,
        features,
        slicer: reader.slicer,
        marks: sink.marks,
        summary,
    })
}

impl Breakdown {
    fn into_estimate(self, unlimited: &Breakdown, limits: Vec<LimitCost>) -> Estimate {
        let lost = |parts: Vec<Part>, free: &[Part]| -> Vec<Part> {
            let mut parts: Vec<Part> = parts
                .into_iter()
                .zip(free)
                .map(|(part, free)| Part {
                    lost: part.time - free.time,
                    ..part
                })
                .collect();
            // What comes before the first marker is listed only when it takes time.
            parts.retain(|p| p.name.is_some() || p.time != 0.0);
            parts
        };
        let slow = &self.summary.slow_moves;
        Estimate {
            total: self.total,
            without_motor_limits: unlimited.total,
            klipper_exit_time: self.summary.klipper_exit_time,
            klipper_rule: None,
            slicer: self.slicer,
            layers: lost(self.layers, &unlimited.layers),
            features: lost(self.features, &unlimited.features),
            limits,
            slowed: slowed_lines(&slow.first),
            slowed_total: slow.total,
            warnings: warning_lines(&self.summary),
            marks: self.marks,
        }
    }
}

/// The slowed moves by line (a move cut into spans is slowed span by span): each line once, at its slowest.
fn slowed_lines(moves: &[motion::SlowMove]) -> Vec<SlowLine> {
    let mut lines: Vec<SlowLine> = Vec::new();
    for s in moves {
        match lines.last_mut() {
            Some(last) if last.line == s.origin => last.allowed = last.allowed.min(s.allowed),
            _ => lines.push(SlowLine {
                line: s.origin,
                requested: s.requested,
                allowed: s.allowed,
            }),
        }
    }
    lines
}

/// What the reader has seen and the planned moves have not yet reached: where each part starts, and the lines
/// whose time is wanted.
#[derive(Debug, Default)]
struct Queued {
    /// From this line on, the moves belong to this layer and feature (indices into the lists).
    boundaries: VecDeque<(u64, usize, usize)>,
    wanted: VecDeque<u64>,
}

/// The reader's side: the parts in file order.
struct Markers {
    queued: Rc<RefCell<Queued>>,
    layers: Vec<Part>,
    features: Vec<Part>,
    feature_index: HashMap<String, usize>,
    layer: usize,
    feature: usize,
    slicer: Option<f64>,
}

fn part(name: Option<String>, z: Option<f64>, line: u64) -> Part {
    Part {
        name,
        z,
        line,
        time: 0.0,
        lost: 0.0,
    }
}

impl Markers {
    fn new(queued: Rc<RefCell<Queued>>) -> Markers {
        Markers {
            queued,
            layers: vec![part(None, None, 0)],
            features: vec![part(None, None, 0)],
            feature_index: HashMap::new(),
            layer: 0,
            feature: 0,
            slicer: None,
        }
    }

    fn observe(&mut self, command: &Spanned<Command>, wanted: &dyn Fn(&Command) -> bool) {
        let line = command.span.line;
        if wanted(&command.value) {
            self.queued.borrow_mut().wanted.push_back(line);
        }
        let Command::Meta(meta) = &command.value else {
            return;
        };
        match meta {
            Meta::LayerChange { index, z } => {
                let name =
                    index.map_or_else(|| z.map(|z| format!("Z{z}")), |i| Some(i.to_string()));
                self.layers.push(part(name, *z, line));
                self.layer = self.layers.len() - 1;
            }
            Meta::Feature(name) => {
                let count = self.features.len();
                self.feature = *self.feature_index.entry(name.clone()).or_insert(count);
                if self.feature == count {
                    self.features.push(part(Some(name.clone()), None, line));
                }
            }
            Meta::PrintTimeEstimate { seconds, silent } if !silent => {
                self.slicer = self.slicer.or(Some(*seconds));
                return;
            }
            _ => return,
        }
        let boundary = (line, self.layer, self.feature);
        self.queued.borrow_mut().boundaries.push_back(boundary);
    }
}

/// The planned moves' side: each part's time, from the print time of the moves as they come.
struct Timeline {
    queued: Rc<RefCell<Queued>>,
    origin: u64,
    last: f64,
    layer: usize,
    feature: usize,
    layer_time: Vec<f64>,
    feature_time: Vec<f64>,
    marks: Vec<(u64, f64)>,
}

impl Timeline {
    fn new(queued: Rc<RefCell<Queued>>) -> Timeline {
        Timeline {
            queued,
            origin: 0,
            last: 0.0,
            layer: 0,
            feature: 0,
            layer_time: vec![0.0],
            feature_time: vec![0.0],
            marks: Vec::new(),
        }
    }

    /// The time from the last boundary to `time` goes to the current part.
    fn charge(&mut self, time: f64) {
        let spent = time - self.last;
        let grow = |times: &mut Vec<f64>, index: usize| {
            if times.len() <= index {
                times.resize(index + 1, 0.0);
            }
            times[index] += spent;
        };
        grow(&mut self.layer_time, self.layer);
        grow(&mut self.feature_time, self.feature);
        self.last = time;
    }

    /// A move of line `origin` starts at `time`: every part that began before it has begun by then, and every
    /// wanted line before it is reached then.
    fn advance(&mut self, origin: u64, time: f64) {
        let time = time.max(self.last);
        let queued = Rc::clone(&self.queued);
        let mut queued = queued.borrow_mut();
        while let Some(&(line, layer, feature)) = queued.boundaries.front() {
            if line > origin {
                break;
            }
            self.charge(time);
            (self.layer, self.feature) = (layer, feature);
            queued.boundaries.pop_front();
        }
        while let Some(&line) = queued.wanted.front() {
            if line >= origin {
                break;
            }
            self.marks.push((line, time));
            queued.wanted.pop_front();
        }
    }
}

impl MoveSink for Timeline {
    fn append(&mut self, _queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        self.advance(self.origin, mv.print_time);
        Ok(())
    }

    fn origin(&mut self, origin: u64) {
        self.origin = origin;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn machine() -> Machine {
        let cfg = "[printer]\nkinematics: cartesian\nmax_velocity: 100\nmax_accel: 1000\n\
            [stepper_x]\nstep_pin: a\ndir_pin: b\nenable_pin: c\nmicrosteps: 16\nrotation_distance: 40\n\
            endstop_pin: d\nposition_endstop: 0\nposition_max: 200\n\
            [stepper_y]\nstep_pin: a\ndir_pin: b\nenable_pin: c\nmicrosteps: 16\nrotation_distance: 40\n\
            endstop_pin: d\nposition_endstop: 0\nposition_max: 200\n\
            [stepper_z]\nstep_pin: a\ndir_pin: b\nenable_pin: c\nmicrosteps: 16\nrotation_distance: 8\n\
            endstop_pin: d\nposition_endstop: 0\nposition_max: 200\n";
        Machine::from_text(cfg, "printer.cfg").expect("machine")
    }

    #[test]
    fn parts_add_up_and_marks_fall_between_moves() {
        let text = ";TIME:99\nG28\nG1 Z0.2 F600\n;LAYER:0\n;TYPE:WALL-OUTER\nG1 X50 F3000\nM73 P50\n\
            ;TYPE:FILL\nG1 Y50\n;LAYER:1\n;TYPE:WALL-OUTER\nG1 X0\nG4 P500\nM73 P100\n";
        let open = || -> std::io::Result<Box<dyn BufRead>> {
            Ok(Box::new(std::io::Cursor::new(text.as_bytes().to_vec())))
        };
        let wanted = |c: &Command| matches!(c, Command::Other { name } if name == "M73");
        let e = estimate(
            &machine(),
            PlanOptions::default(),
            &open,
            "t.gcode",
            &wanted,
        )
        .expect("estimate");
        assert_eq!(e.slicer, Some(99.0));
        let names: Vec<_> = e.layers.iter().map(|p| p.name.clone()).collect();
        assert_eq!(names, [None, Some("0".into()), Some("1".into())]);
        let sum = |parts: &[Part]| parts.iter().map(|p| p.time).sum::<f64>();
        assert!((sum(&e.layers) - e.total).abs() < 1e-9);
        assert!((sum(&e.features) - e.total).abs() < 1e-9);
        let features: Vec<_> = e.features.iter().map(|p| p.name.clone()).collect();
        assert_eq!(
            features,
            [None, Some("WALL-OUTER".into()), Some("FILL".into())]
        );
        // Two 50 mm walls at 50 mm/s, one 50 mm fill move.
        assert!(e.features[1].time > e.features[2].time * 1.5);
        assert_eq!(e.marks.len(), 2);
        assert_eq!(e.marks[0].0, 7);
        assert!(e.marks[0].1 > 0.25 && e.marks[0].1 < e.total);
        assert_eq!(e.marks[1], (14, e.total));
        assert!(e.limits.is_empty() && e.without_motor_limits == e.total);
    }
}
