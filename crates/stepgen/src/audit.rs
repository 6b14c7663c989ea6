//! What a real MCU needs of one motor's step stream, checked on the stream itself (the steps as they would be
//! sent), not on the generator's own state: no two steps on one clock tick, no interval shorter than the
//! motor's maximum step rate allows, and a net position that agrees with where the planned path takes the motor.

use kinematics::{Kinematics, Vec3};

use crate::sink::StepSink;

/// The first thing found wrong in a step stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepProblem {
    /// A step on the same clock tick as the one before it (an MCU cannot time it).
    SameClock { clock: u64 },
    /// A step sooner after the one before it than the maximum step rate allows.
    TooFast {
        clock: u64,
        interval_ticks: u64,
        min_ticks: u64,
    },
}

impl StepProblem {
    /// The clock tick of the offending step.
    pub fn clock(&self) -> u64 {
        match *self {
            StepProblem::SameClock { clock } | StepProblem::TooFast { clock, .. } => clock,
        }
    }

    /// What is wrong, for a message that adds the motor, time and place.
    pub fn describe(&self, clock_hz: f64) -> String {
        match *self {
            StepProblem::SameClock { .. } => "two steps on one clock tick".to_string(),
            StepProblem::TooFast {
                interval_ticks,
                min_ticks,
                ..
            } => format!(
                "steps {interval_ticks} ticks apart ({:.0} steps/s), closer than its maximum step rate allows \
                 ({min_ticks} ticks)",
                clock_hz / interval_ticks as f64
            ),
        }
    }
}

/// Watches one motor's steps (a [`StepSink`]) and keeps the first problem.
#[derive(Debug, Clone)]
pub struct StepAudit {
    /// Shortest interval allowed (ticks, at least 1: two steps never share a tick).
    min_ticks: u64,
    last: Option<u64>,
    net: i64,
    problem: Option<StepProblem>,
}

impl StepAudit {
    /// An audit for a motor stepping at most `max_step_rate` steps/s (any rate when `None`, but never two steps
    /// on one tick) on an MCU clock of `clock_hz`. One tick of clock rounding is allowed below `clock_hz / rate`.
    pub fn new(max_step_rate: Option<f64>, clock_hz: f64) -> Self {
        let min_ticks = max_step_rate
            .filter(|r| *r > 0.0 && r.is_finite())
            .map(|rate| (clock_hz / rate).floor() as u64)
            .map_or(1, |ticks| ticks.saturating_sub(1).max(1));
        StepAudit {
            min_ticks,
            last: None,
            net: 0,
            problem: None,
        }
    }

    /// The first problem found, if any.
    pub fn problem(&self) -> Option<StepProblem> {
        self.problem
    }

    /// Sum of +1 / −1 over the steps seen.
    pub fn net_steps(&self) -> i64 {
        self.net
    }

    #[cold]
    fn found(&mut self, clock: u64, last: u64) {
        if self.problem.is_some() {
            return;
        }
        self.problem = Some(if clock <= last {
            StepProblem::SameClock { clock }
        } else {
            StepProblem::TooFast {
                clock,
                interval_ticks: clock - last,
                min_ticks: self.min_ticks,
            }
        });
    }
}

impl StepSink for StepAudit {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        if let Some(last) = self.last
            && clock < last.saturating_add(self.min_ticks)
        {
            self.found(clock, last);
        }
        self.last = Some(clock);
        self.net += if dir { 1 } else { -1 };
    }
}

/// How far each motor must have moved along the planned path, from the positions the planner handed over (its
/// moves' ends and declared positions), through the kinematics alone: for each stretch between two declared
/// positions (`SET_KINEMATIC_POSITION`, homing), the motor position at its last point minus the one at its first;
/// for the extruder, the sum of its moves (a `G92 E` declares a position without moving the motor).
/// A [`trapq::MoveSink`] beside step generation.
#[derive(Debug)]
pub struct ExpectedTravel<'k> {
    kin: &'k dyn Kinematics,
    /// Motor travel so far, kinematic motors then the extruder; `None` once a stretch ended where the
    /// kinematics give no motor position (a polar bed on its centre): that motor cannot be checked.
    travel: Vec<Option<f64>>,
    toolhead: Stretch<Vec3>,
    /// Declared positions so far: each starts the motors afresh off the step grid (as Klipper's
    /// `SET_KINEMATIC_POSITION` does), so each stretch may round by up to one step.
    declared: u32,
}

/// The first and last point of the current stretch.
#[derive(Debug, Clone, Copy, Default)]
struct Stretch<T> {
    first: Option<T>,
    last: Option<T>,
}

impl<T: Copy> Stretch<T> {
    fn reach(&mut self, start: T, end: T) {
        self.first.get_or_insert(start);
        self.last = Some(end);
    }

    /// Close the stretch (its ends) and start a new one at `at`.
    fn restart(&mut self, at: T) -> Option<(T, T)> {
        let ends = self.first.zip(self.last);
        *self = Stretch {
            first: Some(at),
            last: Some(at),
        };
        ends
    }
}

impl<'k> ExpectedTravel<'k> {
    /// For the motors of `kin`, plus an extruder when `extruder` is set.
    pub fn new(kin: &'k dyn Kinematics, extruder: bool) -> Self {
        ExpectedTravel {
            kin,
            travel: vec![Some(0.0); kin.motors().len() + usize::from(extruder)],
            toolhead: Stretch::default(),
            declared: 0,
        }
    }

    fn close_toolhead(&mut self, ends: Option<(Vec3, Vec3)>) {
        let Some((first, last)) = ends else { return };
        let n = self.kin.motors().len();
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        let known =
            self.kin.inverse(first, &mut a).is_ok() && self.kin.inverse(last, &mut b).is_ok();
        for (i, travel) in self.travel.iter_mut().take(n).enumerate() {
            *travel = travel.filter(|_| known).map(|t| t + b[i] - a[i]);
        }
    }

    /// Each motor's travel (motor units), kinematic motors then the extruder (`None` where unknown), and how
    /// many stretches it was planned in (the steps may differ from the travel by up to a step per stretch).
    pub fn finish(mut self) -> (Vec<Option<f64>>, u32) {
        let toolhead = self.toolhead.first.zip(self.toolhead.last);
        self.close_toolhead(toolhead);
        (self.travel, self.declared + 1)
    }
}

impl trapq::MoveSink for ExpectedTravel<'_> {
    fn append(&mut self, queue: trapq::Queue, mv: &trapq::TrapezoidMove) {
        match queue {
            trapq::Queue::Toolhead => self.toolhead.reach(mv.start_pos, mv.end_pos()),
            trapq::Queue::Extruder => {
                let n = self.kin.motors().len();
                if let Some(Some(travel)) = self.travel.get_mut(n) {
                    *travel += mv.distance();
                }
            }
        }
    }

    fn set_position(&mut self, xyz: Vec3, _e: f64) {
        self.declared += 1;
        let toolhead = self.toolhead.restart(xyz);
        self.close_toolhead(toolhead);
    }
}

/// Whether `net` steps of `step_distance` agree with a motor that moved by `expected` (motor units) along the
/// planned path in `stretches` stretches: within one step per stretch (a stretch need not start on the step
/// grid), modulo `period` for a motor that turns without end (a polar bed: 2π).
pub fn net_agrees(
    net: i64,
    step_distance: f64,
    expected: f64,
    period: Option<f64>,
    stretches: u32,
) -> bool {
    let mut gap = net as f64 * step_distance - expected;
    if let Some(period) = period {
        gap -= period * (gap / period).round();
    }
    gap.abs() <= step_distance * f64::from(stretches.max(1)) * (1.0 + 1e-9)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn audit(max_rate: Option<f64>, clocks: &[u64]) -> Option<StepProblem> {
        let mut audit = StepAudit::new(max_rate, 16e6);
        for &c in clocks {
            audit.step(c, true);
        }
        audit.problem()
    }

    #[test]
    fn a_clean_stream_passes() {
        assert_eq!(audit(None, &[10, 11, 12, 1000]), None);
        // 20 000 steps/s on 16 MHz: 800 ticks; one tick of rounding is allowed.
        assert_eq!(audit(Some(20_000.0), &[0, 800, 1599, 2400]), None);
    }

    #[test]
    fn two_steps_on_one_clock_are_found() {
        assert_eq!(
            audit(None, &[10, 20, 20, 30]),
            Some(StepProblem::SameClock { clock: 20 })
        );
    }

    #[test]
    fn steps_too_fast_for_the_rate_are_found_and_the_first_is_kept() {
        let problem = audit(Some(20_000.0), &[0, 800, 1500, 1600, 1601]);
        assert_eq!(
            problem,
            Some(StepProblem::TooFast {
                clock: 1500,
                interval_ticks: 700,
                min_ticks: 799
            })
        );
        let text = problem.expect("found").describe(16e6);
        assert!(text.contains("700 ticks apart"), "{text}");
    }

    #[test]
    fn the_net_position_agrees_within_a_step_and_modulo_a_turn() {
        assert!(net_agrees(100, 0.01, 1.005, None, 1));
        assert!(!net_agrees(100, 0.01, 1.02, None, 1));
        assert!(net_agrees(100, 0.01, 1.02, None, 2));
        let step = std::f64::consts::TAU / 16000.0;
        let turn = Some(std::f64::consts::TAU);
        // 8000 steps up is half a turn, which a bed also reaches by turning the other way.
        assert!(net_agrees(8000, step, -std::f64::consts::PI, turn, 1));
        assert!(!net_agrees(4000, step, -std::f64::consts::PI, turn, 1));
    }
}
