//! What a real MCU needs of one motor's step stream, checked on the stream itself (the steps as they would be
//! sent), not on the generator's own state: no two steps on one clock tick, no interval shorter than the
//! motor's maximum step rate allows, and a net position that agrees with where the planned path takes the motor.

use kinematics::{Kinematics, Vec3};

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

/// The shortest step interval (ticks) a motor stepping at most `max_step_rate` steps/s may have on an MCU clock of
/// `clock_hz`: one tick of clock rounding below `clock_hz / rate`, and never less than one tick (two steps on one
/// tick cannot be timed); 1 without a rate.
pub fn min_step_ticks(max_step_rate: Option<f64>, clock_hz: f64) -> u64 {
    max_step_rate
        .filter(|r| *r > 0.0 && r.is_finite())
        .map(|rate| (clock_hz / rate).floor() as u64)
        .map_or(1, |ticks| ticks.saturating_sub(1).max(1))
}

/// The first step of `clocks` (which follow a step at `previous`, if any) closer than `min_ticks` to the one
/// before it.
pub(crate) fn first_short_step(
    clocks: &[u64],
    previous: Option<u64>,
    min_ticks: u64,
) -> Option<StepProblem> {
    let mut before = previous;
    for &clock in clocks {
        if let Some(last) = before
            && clock < last.saturating_add(min_ticks)
        {
            return Some(if clock <= last {
                StepProblem::SameClock { clock }
            } else {
                StepProblem::TooFast {
                    clock,
                    interval_ticks: clock - last,
                    min_ticks,
                }
            });
        }
        before = Some(clock);
    }
    None
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
    /// kinematics give no motor position (a polar bed's is followed move by move instead, `bed`).
    travel: Vec<Option<f64>>,
    /// Where the current stretch starts, and its last move so far (whose end is computed only when the
    /// stretch closes).
    stretch_start: Option<Vec3>,
    last_move: Option<trapq::TrapezoidMove>,
    /// Declared positions so far: each starts the motors afresh off the step grid (as Klipper's
    /// `SET_KINEMATIC_POSITION` does), so each stretch may round by up to one step.
    declared: u32,
    /// A polar bed, followed move by move (at its centre its angle is no point's: the stretches cannot give it).
    bed: Option<BedTravel>,
}

/// A polar bed's turns along the planned path, move by move: a line away from the centre turns it by the change of
/// the nozzle's angle (less than half a turn: the planner cuts every line that meets the centre there), a line to or
/// from the centre not at all (the bed was turned to its direction in place), a turn in place by its angle.
#[derive(Debug, Clone, Copy)]
struct BedTravel {
    motor: usize,
    centre: [f64; 2],
    tolerance: f64,
    turned: f64,
}

impl BedTravel {
    fn of(kin: &dyn Kinematics) -> Option<BedTravel> {
        let c = kin.rotation_centre()?;
        Some(BedTravel {
            motor: c.bed,
            centre: c.point,
            tolerance: c.tolerance,
            turned: 0.0,
        })
    }

    fn add(&mut self, mv: &trapq::TrapezoidMove) {
        if mv.motion == trapq::Motion::BedTurn {
            self.turned += mv.distance();
            return;
        }
        let angle = |p: Vec3| (p[1] - self.centre[1]).atan2(p[0] - self.centre[0]);
        let near = |p: Vec3| (p[0] - self.centre[0]).hypot(p[1] - self.centre[1]) <= self.tolerance;
        let (a, b) = (mv.start_pos, mv.end_pos());
        if near(a) || near(b) {
            return;
        }
        let turn = angle(b) - angle(a);
        self.turned += turn - std::f64::consts::TAU * (turn / std::f64::consts::TAU).round();
    }
}

impl<'k> ExpectedTravel<'k> {
    /// For the motors of `kin`, plus an extruder when `extruder` is set.
    pub fn new(kin: &'k dyn Kinematics, extruder: bool) -> Self {
        ExpectedTravel {
            kin,
            travel: vec![Some(0.0); kin.motors().len() + usize::from(extruder)],
            stretch_start: None,
            last_move: None,
            declared: 0,
            bed: BedTravel::of(kin),
        }
    }

    /// Add the current stretch's travel: from its start to where its last move ends (nothing if none moved).
    fn close_stretch(&mut self) {
        let (Some(first), Some(mv)) = (self.stretch_start, self.last_move.take()) else {
            return;
        };
        let n = self.kin.motors().len();
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        // Near the previous reading, so a stretch that starts or ends on a polar centre still has its other motors.
        let known = self.kin.inverse_near(first, &vec![0.0; n], &mut a).is_ok()
            && self.kin.inverse_near(mv.end_pos(), &a, &mut b).is_ok();
        let bed = self.bed.map(|bed| bed.motor);
        for (i, travel) in self.travel.iter_mut().take(n).enumerate() {
            if Some(i) != bed {
                *travel = travel.filter(|_| known).map(|t| t + b[i] - a[i]);
            }
        }
    }

    /// Each motor's travel (motor units), kinematic motors then the extruder (`None` where unknown), and how
    /// many stretches it was planned in (the steps may differ from the travel by up to a step per stretch).
    pub fn finish(mut self) -> (Vec<Option<f64>>, u32) {
        self.close_stretch();
        if let Some(bed) = self.bed {
            self.travel[bed.motor] = Some(bed.turned);
        }
        (self.travel, self.declared + 1)
    }
}

impl trapq::MoveSink for ExpectedTravel<'_> {
    fn append(
        &mut self,
        queue: trapq::Queue,
        mv: &trapq::TrapezoidMove,
    ) -> Result<(), trapq::SinkError> {
        match queue {
            trapq::Queue::Toolhead => {
                self.stretch_start.get_or_insert(mv.start_pos);
                self.last_move = Some(*mv);
                if let Some(bed) = &mut self.bed {
                    bed.add(mv);
                }
            }
            trapq::Queue::Extruder => {
                let n = self.kin.motors().len();
                if let Some(Some(travel)) = self.travel.get_mut(n) {
                    *travel += mv.distance();
                }
            }
        }
        Ok(())
    }

    fn set_position(&mut self, xyz: Vec3, _e: f64) -> Result<(), trapq::SinkError> {
        self.close_stretch();
        self.declared += 1;
        self.stretch_start = Some(xyz);
        Ok(())
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
    use crate::sink::StepSink;
    use crate::stats::StepStats;

    /// The problem the statistics sink finds in `clocks`, handed over one step at a time or as one run.
    fn audit(max_rate: Option<f64>, clocks: &[u64]) -> Option<StepProblem> {
        let mut one = StepStats::new(16e6).audited(max_rate);
        let mut run = StepStats::new(16e6).audited(max_rate);
        for &c in clocks {
            one.step(c, true);
        }
        run.steps(clocks, true);
        assert_eq!(one.problem(), run.problem(), "{clocks:?}");
        one.problem()
    }

    /// A straight move from `a` to `b` at constant speed.
    fn line(a: Vec3, b: Vec3) -> trapq::TrapezoidMove {
        let d = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt();
        trapq::TrapezoidMove {
            print_time: 0.0,
            accel_t: 0.0,
            cruise_t: d / 10.0,
            decel_t: 0.0,
            start_pos: a,
            axes_r: [(b[0] - a[0]) / d, (b[1] - a[1]) / d, (b[2] - a[2]) / d],
            start_v: 10.0,
            cruise_v: 10.0,
            accel: 0.0,
            motion: trapq::Motion::Travel,
        }
    }

    /// Through a polar centre and on: the bed's travel is the sum of its turns (geometry worked out here: a quarter
    /// turn on the way to (0, 50), half a turn in place, an eighth on the last line), and the arm stays checked
    /// after the stretch that ended on the centre.
    #[test]
    fn a_polar_bed_is_followed_through_its_centre() {
        use trapq::{MoveSink, Queue, TrapezoidMove};
        let params = kinematics::MachineParams::Polar(kinematics::PolarParams::klipper_example());
        let kin = kinematics::build(&params).expect("polar");
        let mut travel = ExpectedTravel::new(kin.as_ref(), false);
        let moves = [
            line([50.0, 0.0, 0.0], [0.0, 50.0, 0.0]),
            line([0.0, 50.0, 0.0], [0.0, 0.0, 0.0]),
            TrapezoidMove::bed_turn(1.0, [0.0; 3], std::f64::consts::PI, 5.0, 50.0),
            line([0.0, 0.0, 0.0], [0.0, -40.0, 0.0]),
            line([0.0, -40.0, 0.0], [40.0, -40.0, 0.0]),
        ];
        travel
            .set_position([50.0, 0.0, 0.0], 0.0)
            .expect("declared");
        for mv in &moves[..2] {
            travel.append(Queue::Toolhead, mv).expect("taken");
        }
        // A declared pose on the centre ends a stretch there.
        travel.set_position([0.0, 0.0, 0.0], 0.0).expect("declared");
        for mv in &moves[2..] {
            travel.append(Queue::Toolhead, mv).expect("taken");
        }
        let (travel, stretches) = travel.finish();
        let quarter = std::f64::consts::FRAC_PI_2;
        let bed = travel[kinematics::polar::BED].expect("the bed is known");
        assert!(
            (bed - (quarter + 2.0 * quarter + quarter / 2.0)).abs() < 1e-12,
            "{bed}"
        );
        let arm = travel[kinematics::polar::ARM].expect("the arm is known");
        assert!(
            (arm - ((0.0 - 50.0) + (40.0f64.hypot(40.0) - 0.0))).abs() < 1e-9,
            "{arm}"
        );
        assert_eq!(stretches, 3);
    }

    #[test]
    fn a_clean_stream_passes() {
        assert_eq!(audit(None, &[10, 11, 12, 1000]), None);
        // 20 000 steps/s on 16 MHz: 800 ticks; one tick of rounding is allowed.
        assert_eq!(audit(Some(20_000.0), &[0, 800, 1599, 2400]), None);
        assert_eq!(min_step_ticks(Some(20_000.0), 16e6), 799);
        assert_eq!(min_step_ticks(None, 16e6), 1);
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
    fn a_problem_across_two_runs_is_found() {
        let mut stats = StepStats::new(16e6).audited(Some(20_000.0));
        stats.steps(&[0, 800], true);
        stats.steps(&[1000, 1800], false);
        assert_eq!(
            stats.problem(),
            Some(StepProblem::TooFast {
                clock: 1000,
                interval_ticks: 200,
                min_ticks: 799
            })
        );
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
