//! What a print asks of the machine beyond its refusals, for `check` to tell: how far each motor travels (where it
//! is limited) and how close the nozzle comes to each of the machine's special poses, with the G-code line where.
//! A sink on the planned toolhead moves, sampled along each move.

use kinematics::{Clearance, Kinematics, MotorUnit, TurningLimits};
use trapq::{Motion, MoveSink, Queue, SinkError, TrapezoidMove};

/// Samples along a move at most this far apart (mm), both ends included.
pub const SAMPLE_MM: f64 = 0.5;

/// Where a motor's reading reached its extremes over the print (motor units: mm or rad).
#[derive(Debug, Clone, PartialEq)]
pub struct MotorTravel {
    pub name: String,
    pub unit: MotorUnit,
    pub min: f64,
    pub min_line: u64,
    pub max: f64,
    pub max_line: u64,
}

/// The closest the print comes to one special pose: the smallest clearance, its margin and the line.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosestApproach {
    pub label: &'static str,
    pub value: f64,
    pub margin: f64,
    pub line: u64,
    pub at: [f64; 2],
}

/// The travels and closest approaches of a planned print.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Envelope {
    /// Motors whose reading has limits to keep (not a bed that turns freely), in the machine's motor order.
    pub motors: Vec<MotorTravel>,
    pub closest: Vec<ClosestApproach>,
}

/// The sink that builds an [`Envelope`].
pub(crate) struct EnvelopeSink<'a> {
    kin: &'a dyn Kinematics,
    origin: u64,
    /// The motors' readings at the last sample (angles unwrapped from them).
    previous: Vec<f64>,
    readings: Vec<f64>,
    clearances: Vec<Clearance>,
    /// Per motor in the machine's order: whether its travel is reported, and the travel so far.
    tracked: Vec<bool>,
    travel: Vec<Option<MotorTravel>>,
    closest: Vec<ClosestApproach>,
}

impl<'a> EnvelopeSink<'a> {
    pub(crate) fn new(kin: &'a dyn Kinematics) -> EnvelopeSink<'a> {
        let free_bed = kin.turning_limits() == Some(TurningLimits::Bed);
        let tracked = kin
            .motors()
            .iter()
            .map(|m| !(free_bed && m.unit == MotorUnit::Rad))
            .collect();
        let count = kin.motors().len();
        EnvelopeSink {
            kin,
            origin: 0,
            previous: vec![f64::NAN; count],
            readings: vec![0.0; count],
            clearances: Vec::new(),
            tracked,
            travel: vec![None; count],
            closest: Vec::new(),
        }
    }

    /// What the planned moves asked of the machine.
    pub(crate) fn into_envelope(self) -> Envelope {
        Envelope {
            motors: self.travel.into_iter().flatten().collect(),
            closest: self.closest,
        }
    }

    fn sample(&mut self, p: [f64; 3]) {
        if self
            .kin
            .inverse_near(p, &self.previous, &mut self.readings)
            .is_ok()
        {
            self.previous.copy_from_slice(&self.readings);
            self.note_readings();
        }
        self.clearances.clear();
        self.kin.clearances(p, &mut self.clearances);
        for c in &self.clearances {
            note_clearance(&mut self.closest, c, self.origin, [p[0], p[1]]);
        }
    }

    fn note_readings(&mut self) {
        let line = self.origin;
        let motors = self.kin.motors().iter().zip(&self.readings);
        let tracked = motors.zip(&mut self.travel).zip(&self.tracked);
        for ((motor, &value), travel) in tracked.filter(|(_, t)| **t).map(|(m, _)| m) {
            match travel {
                Some(t) => {
                    if value < t.min {
                        (t.min, t.min_line) = (value, line);
                    }
                    if value > t.max {
                        (t.max, t.max_line) = (value, line);
                    }
                }
                None => {
                    *travel = Some(MotorTravel {
                        name: motor.name.clone(),
                        unit: motor.unit,
                        min: value,
                        min_line: line,
                        max: value,
                        max_line: line,
                    })
                }
            }
        }
    }
}

/// Keeps the smallest clearance of each special pose, with its line and place.
fn note_clearance(closest: &mut Vec<ClosestApproach>, c: &Clearance, line: u64, at: [f64; 2]) {
    match closest.iter_mut().find(|a| a.label == c.label) {
        Some(a) if c.value < a.value => (a.value, a.line, a.at) = (c.value, line, at),
        Some(_) => {}
        None => closest.push(ClosestApproach {
            label: c.label,
            value: c.value,
            margin: c.margin,
            line,
            at,
        }),
    }
}

impl MoveSink for EnvelopeSink<'_> {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        if queue != Queue::Toolhead || mv.motion == Motion::BedTurn {
            return Ok(());
        }
        let length = mv.distance();
        let samples = (length / SAMPLE_MM).ceil().max(1.0) as usize;
        for i in 0..=samples {
            let d = length * i as f64 / samples as f64;
            let (p, u) = (mv.start_pos, mv.axes_r);
            self.sample([p[0] + u[0] * d, p[1] + u[1] * d, p[2] + u[2] * d]);
        }
        Ok(())
    }

    fn origin(&mut self, origin: u64) {
        self.origin = origin;
    }
}
