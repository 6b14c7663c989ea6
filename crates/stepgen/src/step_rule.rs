//! The step rule (Klipper itersolve semantics) over one motor's position, shared by every solver: the closed
//! forms of `crate::motor`, the general solver (`crate::general`) and the SCARA joints (`crate::scara`).
//! They find where the motor position goes; this module decides which steps that makes and when.
//!
//! The commanded position `c` starts at the motor position of the start pose. A step in the current
//! direction happens when the ideal position reaches `c ± step/2`; a step against the current direction needs
//! the position to go `1e-9` (motor units) further than that, as in Klipper, but its time is still the crossing
//! of `c ∓ step/2`. After a step `c` moves by one step. When the motor reaches its new commanded position, the
//! pending step is committed (it can no longer be removed by the step+dir+step filter).
//!
//! `c` is updated with Klipper's own arithmetic (`(c ± step/2) ± step/2`, bed angle folded into [−π, π]
//! after each piece). An exact grid `p0 + n·step` differs from it by accumulated rounding (up to ~1e-9 after
//! a million steps), which moved 12% of the extruder clocks of `polar-cura-circle` by a tick; with Klipper's
//! arithmetic they agree.

use std::f64::consts::{PI, TAU};

use crate::filter::{StepFilter, clock_at};
use crate::sink::StepSink;

/// Extra distance past the half-step point that a reversal needs (Klipper: `dist < -(half_step + 1e-9)`).
pub const REVERSAL_MARGIN: f64 = 1e-9;

/// Steps handled per batch in [`StepRule::steps_towards`].
pub(crate) const STEP_BATCH: usize = 64;

/// One motor's commanded position, direction and filter: which steps a motor position makes, and when.
#[derive(Debug, Clone)]
pub(crate) struct StepRule {
    /// Commanded position, updated with Klipper's arithmetic (`c ± ½step ± ½step` per step; a polar bed
    /// angle is brought back into [−π, π] after each piece) so that rounding follows Klipper's exactly.
    commanded: f64,
    half_step: f64,
    /// Net steps taken.
    net: i64,
    /// Current step direction (Klipper's `sdir`; it starts "down").
    dir_up: bool,
    filter: StepFilter,
    /// Clocks of the steps being generated (kept here so that no buffer is zeroed per stretch).
    batch: [u64; STEP_BATCH],
}

impl StepRule {
    /// A motor of `step_distance` starting at `start_position` (motor units, not rounded to the step grid).
    pub(crate) fn new(step_distance: f64, start_position: f64, filter: StepFilter) -> Self {
        StepRule {
            commanded: start_position,
            half_step: 0.5 * step_distance,
            net: 0,
            dir_up: false,
            filter,
            batch: [0; STEP_BATCH],
        }
    }

    /// The commanded position: start position plus the net steps taken so far, times the step distance.
    pub(crate) fn commanded_position(&self) -> f64 {
        self.commanded
    }

    /// Half the step distance.
    pub(crate) fn half_step(&self) -> f64 {
        self.half_step
    }

    /// Net steps taken so far (+1 per step up, −1 per step down, before filtering).
    pub(crate) fn net_steps(&self) -> i64 {
        self.net
    }

    /// Step pairs removed by the step+dir+step filter so far.
    pub(crate) fn filtered_pairs(&self) -> u64 {
        self.filter.filtered_pairs()
    }

    /// Bring a bed angle's commanded position back within about [−π, π], as Klipper does after every piece
    /// (it bounds the rounding however many turns the bed makes); the whole turn added, if one was.
    pub(crate) fn fold_turn(&mut self) -> Option<f64> {
        if self.commanded < -PI {
            self.commanded += TAU;
            Some(TAU)
        } else if self.commanded > PI {
            self.commanded -= TAU;
            Some(-TAU)
        } else {
            None
        }
    }

    /// End of input: the held-back step is final, and every final step goes to the sink.
    pub(crate) fn finish<S: StepSink + ?Sized>(&mut self, sink: &mut S) {
        self.filter.commit(sink);
        self.filter.flush(sink);
    }

    /// Hand the final steps generated so far to the sink (the held-back step stays held back).
    pub(crate) fn flush<S: StepSink + ?Sized>(&mut self, sink: &mut S) {
        self.filter.flush(sink);
    }

    /// Emit, at one instant, the steps a position `f` already demands (a jump by rounding between pieces),
    /// then commit the pending step if the motor has reached its commanded position.
    /// Nearly always nothing is due (the position is where the last stretch left it), so that test is inlined
    /// at every piece and the stepping kept out of line.
    #[inline(always)]
    pub(crate) fn settle<S: StepSink + ?Sized>(&mut self, f: f64, time: f64, sink: &mut S) {
        if self.wants_up(f) || self.wants_down(f) {
            self.settle_steps(f, time, sink);
        }
        self.check_commit(f, sink);
    }

    #[inline(never)]
    fn settle_steps<S: StepSink + ?Sized>(&mut self, f: f64, time: f64, sink: &mut S) {
        while self.wants_up(f) {
            self.step_up(time, sink);
        }
        while self.wants_down(f) {
            self.step_down(time, sink);
        }
    }

    #[inline]
    pub(crate) fn wants_up(&self, f: f64) -> bool {
        let level = self.up_level();
        if self.dir_up {
            f >= level
        } else {
            f > level + REVERSAL_MARGIN
        }
    }

    #[inline]
    pub(crate) fn wants_down(&self, f: f64) -> bool {
        let level = self.down_level();
        if self.dir_up {
            f < level - REVERSAL_MARGIN
        } else {
            f <= level
        }
    }

    /// The position at which the next step up / down happens: `commanded ± ½step`.
    #[inline]
    pub(crate) fn up_level(&self) -> f64 {
        self.commanded + self.half_step
    }

    #[inline]
    pub(crate) fn down_level(&self) -> f64 {
        self.commanded - self.half_step
    }

    #[inline]
    fn wants_step(&self, f: f64, up: bool) -> bool {
        if up {
            self.wants_up(f)
        } else {
            self.wants_down(f)
        }
    }

    /// Move the commanded position one step, with Klipper's arithmetic (`c ± ½step ± ½step`).
    #[inline]
    fn advance(&mut self, up: bool) {
        if up {
            self.net += 1;
            self.commanded = (self.commanded + self.half_step) + self.half_step;
        } else {
            self.net -= 1;
            self.commanded = (self.commanded - self.half_step) - self.half_step;
        }
        self.dir_up = up;
    }

    #[inline]
    pub(crate) fn step_up<S: StepSink + ?Sized>(&mut self, time: f64, sink: &mut S) {
        self.advance(true);
        self.filter.push(time, true, sink);
    }

    #[inline]
    pub(crate) fn step_down<S: StepSink + ?Sized>(&mut self, time: f64, sink: &mut S) {
        self.advance(false);
        self.filter.push(time, false, sink);
    }

    #[inline(always)]
    pub(crate) fn check_commit<S: StepSink + ?Sized>(&mut self, f: f64, sink: &mut S) {
        let commanded = self.commanded_position();
        let reached = if self.dir_up {
            f > commanded
        } else {
            f < commanded
        };
        if reached {
            self.filter.commit(sink);
        }
    }

    /// Steps of a stretch where the position moves monotonically from `fa` (at `t_a`) to `fb`.
    /// `inverse` maps a position level between them to a time relative to the piece start.
    #[inline]
    pub(crate) fn monotonic<S: StepSink + ?Sized, I: LevelInverse>(
        &mut self,
        fa: f64,
        fb: f64,
        t_a: f64,
        print_time: f64,
        inverse: &mut I,
        sink: &mut S,
    ) {
        self.settle(fa, print_time + t_a, sink);
        if fb > fa {
            self.steps_towards::<true, S, I>(fb, print_time, inverse, sink);
        } else if fb != fa {
            self.steps_towards::<false, S, I>(fb, print_time, inverse, sink);
        }
        self.check_commit(fb, sink);
    }

    /// Every step from the commanded position towards `fb` (up or down), a batch at a time: one tight loop
    /// finds each level (Klipper's arithmetic on the commanded position) and its clock, then the filter and
    /// sink take the batch. The levels form one serial chain of additions and a bed's ray rotation another;
    /// with both in one loop and in registers the CPU runs the chains side by side, and the divisions and
    /// square roots of a batch overlap them.
    #[inline]
    fn steps_towards<const UP: bool, S: StepSink + ?Sized, I: LevelInverse>(
        &mut self,
        fb: f64,
        print_time: f64,
        inverse: &mut I,
        sink: &mut S,
    ) {
        // Only the first step can be a reversal (with its margin); after it the direction is `up`, and a
        // step is due while the next level has not passed `fb`.
        let up = UP;
        if !self.wants_step(fb, up) {
            return;
        }
        // Klipper's `(c ± ½step) ± ½step`: adding −½step is the same operation as subtracting ½step.
        let half = if up { self.half_step } else { -self.half_step };
        let dir = if up { 1.0 } else { -1.0 };
        let due = |level: f64| if up { fb >= level } else { fb <= level };
        let mut commanded = self.commanded;
        // Each time becomes its clock as it is found, in the same loop (no second pass over the batch).
        let clock_hz = self.filter.clock_hz();
        let clock = |t: f64| clock_at(print_time + t, clock_hz);
        loop {
            inverse.start_batch(commanded + half, dir);
            let mut count = 0;
            let more = loop {
                let level = commanded + half;
                commanded = level + half;
                if I::PAIRS && count + 2 <= STEP_BATCH && due(commanded + half) {
                    let second = commanded + half;
                    commanded = second + half;
                    let (ta, tb) = inverse.next_pair(level, second);
                    self.batch[count] = clock(ta);
                    self.batch[count + 1] = clock(tb);
                    count += 2;
                } else {
                    self.batch[count] = clock(inverse.next_time(level));
                    count += 1;
                }
                let more = due(commanded + half);
                if count == STEP_BATCH || !more {
                    break more;
                }
            };
            self.net += if up { count as i64 } else { -(count as i64) };
            self.filter.push_run(&self.batch[..count], up, sink);
            if !more {
                break;
            }
        }
        self.commanded = commanded;
        self.dir_up = up;
    }
}

/// Maps position levels to the times (relative to the piece start) at which the motor reaches them. A batch
/// of levels starts at `first` and goes on one step apart in direction `dir` (+1 up, −1 down).
pub(crate) trait LevelInverse {
    /// A batch starts at level `first` (called before its first [`Self::next_time`]).
    #[inline]
    fn start_batch(&mut self, _first: f64, _dir: f64) {}

    /// The time of `level`, the next level of the batch.
    fn next_time(&mut self, level: f64) -> f64;

    /// Whether [`Self::next_pair`] is worth calling (it finds two levels with overlapping arithmetic).
    const PAIRS: bool = false;

    /// The times of the next two levels of the batch, `a` then `b`.
    #[inline]
    fn next_pair(&mut self, a: f64, b: f64) -> (f64, f64) {
        let ta = self.next_time(a);
        (ta, self.next_time(b))
    }
}

impl<F: FnMut(f64) -> f64> LevelInverse for F {
    #[inline(always)]
    fn next_time(&mut self, level: f64) -> f64 {
        self(level)
    }
}
