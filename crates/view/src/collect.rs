//! The planned print as the page shows it, gathered from the estimate's own planning pass: the planned moves (a
//! [`MoveSink`]) and what the file says between them (a [`printjob::Observer`]: layers, feeds, refused moves).
//! Moves arrive after their commands (the lookahead), so what the reader saw waits in queues until the moves of its
//! line come; each layer is merged for display when its last move has come.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use gcode::{Command, Meta, Spanned};
use printjob::Observer;
use trapq::{Motion, MoveSink, Queue, SinkError, TrapezoidMove};

use crate::decimate::{self, EXTRUDING, JUMP, MOTORS, SLOWED, Scales, Segment};
use crate::motors::{FIRST_MOTOR, MotorProbe, REFUSED};
use crate::series::Series;

/// Two segments whose ends are this close (mm) form one chain.
const JOINED: f32 = 1e-3;
/// The most refused moves kept (all are counted).
const REFUSED_KEPT: usize = 10_000;
/// The largest merging tolerance (mm): a few pixels with the whole bed on the screen. A print that still has more
/// segments than the budget keeps them.
pub const MAX_TOLERANCE: f64 = 0.5;

/// A layer: from its marker's line (or the Z its first extrusion reached, without markers) on.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    pub name: String,
    pub z: Option<f64>,
    /// The marker's line (0: before the first marker, or no markers in the file).
    pub line: u64,
    pub segments: Vec<Segment>,
    /// Segments before merging.
    pub planned: usize,
    /// All its segments are on the page; `false`: only the telling ones ([`decimate::telling`]), runs of one look
    /// as chords, the page being over its budget.
    pub whole: bool,
}

/// A move the machine refused, where it would have gone.
#[derive(Debug, Clone, PartialEq)]
pub struct Refused {
    pub line: u64,
    pub from: [f32; 3],
    pub to: [f32; 3],
    pub reason: String,
}

/// How much to keep for display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    /// Merging tolerance to start with (mm).
    pub tolerance: f64,
    /// The most segments per layer, and in all (beyond these only where the largest tolerance leaves more).
    pub per_layer: usize,
    pub total: usize,
    /// The most points of the motor plots.
    pub series: usize,
}

/// What the reader has seen that the moves have not reached yet.
#[derive(Debug, Default)]
struct Pending {
    /// Layer markers: (line, name, z).
    layers: VecDeque<(u64, String, Option<f64>)>,
    /// The speed each move line asks for (mm/s, the feed within the velocity limit then set).
    feeds: VecDeque<(u64, f64)>,
    refused: Vec<Refused>,
    refused_total: u64,
    markers: bool,
}

/// The reader's side.
#[derive(Debug)]
pub struct Reader {
    pending: Rc<RefCell<Pending>>,
    max_velocity: f64,
}

impl Observer for Reader {
    fn command(&mut self, command: &Spanned<Command>) {
        let line = command.span.line;
        let mut pending = self.pending.borrow_mut();
        match &command.value {
            Command::Move(mv) => pending
                .feeds
                .push_back((line, mv.feed.min(self.max_velocity))),
            Command::Arc(arc) => pending
                .feeds
                .push_back((line, arc.feed.min(self.max_velocity))),
            Command::SetVelocityLimit(l) => {
                self.max_velocity = l.velocity.unwrap_or(self.max_velocity);
            }
            Command::Meta(Meta::LayerChange { index, z }) => {
                let name = index.map_or_else(
                    || z.map_or_else(|| format!("line {line}"), |z| format!("Z{z}")),
                    |i| i.to_string(),
                );
                pending.layers.push_back((line, name, *z));
                pending.markers = true;
            }
            _ => {}
        }
    }

    fn refused(&mut self, command: &Spanned<Command>, at: [f64; 4], reason: &str) {
        let target = match &command.value {
            Command::Move(mv) => mv.target,
            Command::Arc(arc) => arc.target,
            _ => at,
        };
        let mut pending = self.pending.borrow_mut();
        pending.refused_total += 1;
        if pending.refused.len() < REFUSED_KEPT {
            pending.refused.push(Refused {
                line: command.span.line,
                from: point(at),
                to: point(target),
                reason: reason.to_string(),
            });
        }
    }
}

fn point(p: [f64; 4]) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}

/// The planned moves' side.
#[derive(Debug)]
pub struct Collector {
    pending: Rc<RefCell<Pending>>,
    probe: MotorProbe,
    budget: Budget,
    tolerance: f64,
    origin: u64,
    /// The requested speed of the current origin line.
    requested: f64,
    layers: Vec<Layer>,
    /// The current layer's segments, before merging.
    current: Vec<Segment>,
    kept: usize,
    /// Merge every layer again when more than this many segments are kept.
    recheck: usize,
    /// Every `stride`-th layer is kept whole; the others only with their telling segments.
    stride: usize,
    scales: Scales,
    series: Series,
    end: Option<[f32; 3]>,
}

/// Both sides of one collection.
pub fn collector(
    probe: MotorProbe,
    max_velocity: f64,
    budget: Budget,
    scales: Scales,
) -> (Reader, Collector) {
    let pending = Rc::new(RefCell::new(Pending::default()));
    let reader = Reader {
        pending: Rc::clone(&pending),
        max_velocity,
    };
    let first = Layer {
        name: "start".into(),
        z: None,
        line: 0,
        segments: Vec::new(),
        planned: 0,
        whole: true,
    };
    let collector = Collector {
        pending,
        probe,
        budget,
        tolerance: budget.tolerance,
        origin: 0,
        requested: max_velocity,
        layers: vec![first],
        current: Vec::new(),
        kept: 0,
        recheck: budget.total,
        stride: 1,
        scales,
        series: Series::new(budget.series),
        end: None,
    };
    (reader, collector)
}

/// What was collected.
#[derive(Debug, Clone)]
pub struct Collected {
    pub layers: Vec<Layer>,
    pub refused: Vec<Refused>,
    pub refused_total: u64,
    pub series: crate::series::Columns,
    pub scales: Scales,
    /// The merging tolerance the page was made with (mm).
    pub tolerance: f64,
    /// Every `stride`-th layer is whole on the page.
    pub stride: usize,
}

impl Collector {
    /// The current origin's requested speed, and a new layer where a marker's line has been reached.
    fn reach(&mut self, origin: u64) {
        let mut pending = self.pending.borrow_mut();
        while let Some(&(line, feed)) = pending.feeds.front() {
            if line > origin {
                break;
            }
            self.requested = feed;
            pending.feeds.pop_front();
        }
        let mut starts = Vec::new();
        while let Some((line, _, _)) = pending.layers.front() {
            if *line > origin {
                break;
            }
            starts.extend(pending.layers.pop_front());
        }
        drop(pending);
        for (line, name, z) in starts {
            self.start_layer(line, name, z);
        }
    }

    fn start_layer(&mut self, line: u64, name: String, z: Option<f64>) {
        self.close_layer();
        self.layers.push(Layer {
            name,
            z,
            line,
            segments: Vec::new(),
            planned: 0,
            whole: true,
        });
    }

    /// Merge the current layer's segments; when all kept segments exceed the budget, merge everything again
    /// with twice the tolerance.
    fn close_layer(&mut self) {
        let segments = std::mem::take(&mut self.current);
        let index = self.layers.len().saturating_sub(1);
        let thin = self.stride > 1 && !index.is_multiple_of(self.stride);
        let planned = segments.len();
        let mut merged = decimate::merge(segments, self.tolerance, &self.scales);
        let mut tolerance = self.tolerance;
        while merged.len() > self.budget.per_layer && tolerance < MAX_TOLERANCE {
            tolerance = (tolerance * 2.0).min(MAX_TOLERANCE);
            merged = decimate::merge(merged, tolerance, &self.scales);
        }
        if thin {
            merged = self.thinned(merged);
        }
        let Some(layer) = self.layers.last_mut() else {
            return;
        };
        layer.planned += planned;
        layer.whole &= !thin;
        self.kept += merged.len();
        layer.segments.extend(merged);
        if self.kept > self.recheck {
            self.merge_all();
        }
    }

    /// Merge every layer again with twice the tolerance until the page is within its budget; where even the largest
    /// tolerance leaves more, keep fewer layers whole (every 2nd, 4th, …; the others keep their limit hits, slowed
    /// moves, bed turns and refusals). Where even that leaves more, the next attempt waits until the page has
    /// doubled, so the layers are merged again a few times over the whole print, not at every layer.
    fn merge_all(&mut self) {
        while self.kept > self.budget.total && self.tolerance < MAX_TOLERANCE {
            self.tolerance = (self.tolerance * 2.0).min(MAX_TOLERANCE);
            self.kept = 0;
            for layer in &mut self.layers {
                let segments = std::mem::take(&mut layer.segments);
                layer.segments = decimate::merge(segments, self.tolerance, &self.scales);
                self.kept += layer.segments.len();
            }
        }
        // Still over: every other layer of those kept whole keeps only its telling segments.
        while self.kept > self.budget.total && self.stride < self.layers.len() {
            self.stride *= 2;
            self.kept = 0;
            for (i, layer) in self.layers.iter_mut().enumerate() {
                if layer.whole && !i.is_multiple_of(self.stride) {
                    let segments = decimate::telling_only(std::mem::take(&mut layer.segments));
                    layer.segments = decimate::merge_coarse(segments, &self.scales);
                    layer.whole = false;
                }
                self.kept += layer.segments.len();
            }
        }
        self.recheck = if self.kept > self.budget.total {
            2 * self.kept
        } else {
            self.budget.total
        };
    }

    /// A layer not kept whole: its telling segments, runs of one look drawn as chords.
    fn thinned(&self, segments: Vec<Segment>) -> Vec<Segment> {
        decimate::merge_coarse(decimate::telling_only(segments), &self.scales)
    }

    /// Without layer markers, a new layer starts where an extruding move first reaches a higher Z: the last
    /// segment (that move) opens it.
    fn layer_by_height(&mut self) {
        if self.pending.borrow().markers {
            return;
        }
        let Some(z) = self.current.last().map(|s| f64::from(s.to[2])) else {
            return;
        };
        let layer = self.layers.last().and_then(|l| l.z);
        if layer.is_none_or(|current| z > current + 1e-4)
            && let Some(opening) = self.current.pop()
        {
            self.start_layer(opening.line, format!("Z{z}"), Some(z));
            self.current.push(opening);
        }
    }

    fn toolhead(&mut self, mv: &TrapezoidMove) {
        let motors = self.probe.pass(mv);
        let cause = self.probe.cause(mv, self.requested, &motors);
        let from = [0, 1, 2].map(|i| mv.start_pos[i] as f32);
        let to = if mv.motion == Motion::BedTurn {
            from
        } else {
            point([mv.end_pos()[0], mv.end_pos()[1], mv.end_pos()[2], 0.0])
        };
        let jump = self
            .end
            .is_none_or(|end| (0..3).any(|i| (end[i] - from[i]).abs() > JOINED));
        self.end = Some(to);
        let slow = cause >= FIRST_MOTOR
            && mv.cruise_v < motion::toolhead::SLOW_MOVE_FRACTION * self.requested;
        let flags = if jump { JUMP } else { 0 } | if slow { SLOWED } else { 0 };
        let speed = mv.cruise_v.abs();
        self.series.push(mv.print_time, speed, &motors);
        self.scales.speed = self.scales.speed.max(speed);
        grow(&mut self.scales.motor_speed, &motors.speed);
        grow(&mut self.scales.motor_accel, &motors.accel);
        self.current.push(Segment {
            line: self.origin,
            from,
            to,
            start: mv.print_time,
            duration: mv.duration(),
            speed: speed as f32,
            requested: self.requested as f32,
            cause,
            flags,
            motor_speed: fixed(&motors.speed),
            motor_accel: fixed(&motors.accel),
        });
    }

    /// Everything collected, the last layer merged.
    pub fn finish(mut self) -> Collected {
        self.close_layer();
        let mut pending = self.pending.borrow_mut();
        let refused = std::mem::take(&mut pending.refused);
        let refused_total = pending.refused_total;
        drop(pending);
        // What came before the first marker is shown only when it moved.
        let layers = self
            .layers
            .into_iter()
            .enumerate()
            .filter(|(i, l)| *i > 0 || l.planned > 0)
            .map(|(_, l)| l)
            .collect();
        Collected {
            layers,
            refused,
            refused_total,
            series: self.series.columns(),
            scales: self.scales,
            tolerance: self.tolerance,
            stride: self.stride,
        }
    }
}

/// The first [`MOTORS`] values.
fn fixed(values: &[f64]) -> [f32; MOTORS] {
    let mut out = [0.0; MOTORS];
    for (o, v) in out.iter_mut().zip(values) {
        *o = *v as f32;
    }
    out
}

/// Each full scale at least the value seen.
fn grow(scales: &mut Vec<f64>, values: &[f64]) {
    if scales.len() < values.len() {
        scales.resize(values.len(), 0.0);
    }
    for (s, v) in scales.iter_mut().zip(values) {
        *s = s.max(*v);
    }
}

impl MoveSink for Collector {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        match queue {
            Queue::Toolhead => self.toolhead(mv),
            Queue::Extruder => {
                let last = self.current.last_mut();
                if let Some(last) = last.filter(|s| s.start == mv.print_time)
                    && mv.cruise_v > 0.0
                {
                    last.flags |= EXTRUDING;
                    self.layer_by_height();
                }
            }
        }
        Ok(())
    }

    fn origin(&mut self, origin: u64) {
        self.origin = origin;
        self.reach(origin);
    }

    fn set_position(&mut self, xyz: trapq::Vec3, _e: f64) -> Result<(), SinkError> {
        self.probe.place(xyz);
        self.end = None;
        Ok(())
    }
}

/// Refused moves as the page draws them: a segment each, of the refusal's colour.
pub fn refused_segments(refused: &[Refused]) -> Vec<Segment> {
    refused
        .iter()
        .map(|r| Segment {
            line: r.line,
            from: r.from,
            to: r.to,
            start: 0.0,
            duration: 0.0,
            speed: 0.0,
            requested: 0.0,
            cause: REFUSED,
            flags: JUMP,
            motor_speed: [0.0; MOTORS],
            motor_accel: [0.0; MOTORS],
        })
        .collect()
}
