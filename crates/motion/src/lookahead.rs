//! Moves and the lookahead queue: junction speeds and velocity-squared planning with Klipper's semantics.
//!
//! Speeds are tracked as velocity squared (`_v2`) throughout, so that "how much speed can change over this
//! move" is the linear quantity `2·d·a`. The arithmetic mirrors Klipper's toolhead so that the planned
//! trapezoids agree with Klipper's to the last bits.

use crate::limits::{LookaheadRule, VelocityLimits};
use trapq::Vec3;

/// Extrude-only moves accelerate "instantly" (Klipper's sentinel acceleration).
const EXTRUDE_ONLY_ACCEL: f64 = 99_999_999.9;
/// Moves shorter than this in XYZ are extrude-only moves.
const MIN_KINEMATIC_DISTANCE: f64 = 1e-9;

/// A requested straight move (toolhead + extruder) with its speed plan.
#[derive(Debug, Clone, PartialEq)]
pub struct Move {
    pub start_pos: [f64; 4],
    pub end_pos: [f64; 4],
    pub axes_d: [f64; 4],
    pub axes_r: [f64; 4],
    /// Path length: XYZ distance, or |ΔE| for extrude-only moves.
    pub move_d: f64,
    pub is_kinematic: bool,
    pub accel: f64,
    pub junction_deviation: f64,
    /// Shortest time the move can take at its cruise speed (lookahead flush bookkeeping).
    pub min_move_t: f64,
    pub max_start_v2: f64,
    pub max_cruise_v2: f64,
    pub delta_v2: f64,
    pub next_junction_v2: f64,
    pub max_mcr_start_v2: f64,
    pub mcr_delta_v2: f64,
    /// Source of the move (opaque to the planner: a G-code line), for error messages downstream.
    pub origin: u64,
    /// The final plan (set when the move leaves the lookahead).
    pub plan: Plan,
}

/// Velocities and phase durations of a planned move.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Plan {
    pub start_v: f64,
    pub cruise_v: f64,
    pub end_v: f64,
    pub accel_t: f64,
    pub cruise_t: f64,
    pub decel_t: f64,
}

impl Plan {
    pub fn duration(&self) -> f64 {
        self.accel_t + self.cruise_t + self.decel_t
    }
}

impl Move {
    /// A move from `start` to `end` at the requested `speed` (mm/s) under the current limits.
    /// Returns `None` for a move that goes nowhere.
    #[inline]
    pub fn new(
        start: [f64; 4],
        end: [f64; 4],
        speed: f64,
        limits: &VelocityLimits,
        origin: u64,
    ) -> Option<Move> {
        let mut end_pos = end;
        let mut axes_d = [0.0; 4];
        for i in 0..4 {
            axes_d[i] = end[i] - start[i];
        }
        let mut move_d =
            (axes_d[0] * axes_d[0] + axes_d[1] * axes_d[1] + axes_d[2] * axes_d[2]).sqrt();
        let mut accel = limits.max_accel;
        let mut velocity = speed.min(limits.max_velocity);
        let is_kinematic = move_d >= MIN_KINEMATIC_DISTANCE;
        if !is_kinematic {
            // Extrude-only move: the XYZ change (if any) is dropped; the path is the filament.
            end_pos[..3].copy_from_slice(&start[..3]);
            axes_d[0] = 0.0;
            axes_d[1] = 0.0;
            axes_d[2] = 0.0;
            move_d = axes_d[3].abs();
            accel = EXTRUDE_ONLY_ACCEL;
            velocity = speed;
        }
        if move_d == 0.0 {
            return None;
        }
        let inv_move_d = 1.0 / move_d;
        let axes_r = axes_d.map(|d| d * inv_move_d);
        Some(Move {
            start_pos: start,
            end_pos,
            axes_d,
            axes_r,
            move_d,
            is_kinematic,
            accel,
            junction_deviation: limits.junction_deviation(),
            min_move_t: move_d / velocity,
            max_start_v2: 0.0,
            max_cruise_v2: velocity * velocity,
            delta_v2: 2.0 * move_d * accel,
            next_junction_v2: 999_999_999.9,
            max_mcr_start_v2: 0.0,
            mcr_delta_v2: 2.0 * move_d * limits.mcr_pseudo_accel(),
            origin,
            plan: Plan::default(),
        })
    }

    /// Lower the move's cruise speed and acceleration limits (never raises them).
    pub fn limit_speed(&mut self, speed: f64, accel: f64) {
        let speed2 = speed * speed;
        if speed2 < self.max_cruise_v2 {
            self.max_cruise_v2 = speed2;
            self.min_move_t = self.move_d / speed;
        }
        self.accel = self.accel.min(accel);
        self.delta_v2 = 2.0 * self.move_d * self.accel;
        self.mcr_delta_v2 = self.mcr_delta_v2.min(self.delta_v2);
    }

    /// Cap the speed at the junction after this move.
    pub fn limit_next_junction_speed(&mut self, speed: f64) {
        self.next_junction_v2 = self.next_junction_v2.min(speed * speed);
    }

    /// XYZ direction (unit vector) of a kinematic move.
    pub fn direction(&self) -> Vec3 {
        [self.axes_r[0], self.axes_r[1], self.axes_r[2]]
    }

    /// Maximum junction speed² from `prev` into this move: "approximated centripetal velocity" (a circle of
    /// radius derived from the junction deviation touching both moves), capped by each move's own limits and
    /// by `extra_v2` (the extruder's corner limit).
    pub fn calc_junction(&mut self, prev: &Move, extra_v2: f64) {
        if !self.is_kinematic || !prev.is_kinematic {
            return;
        }
        let mut max_start_v2 = self
            .max_cruise_v2
            .min(prev.max_cruise_v2)
            .min(prev.next_junction_v2)
            .min(prev.max_start_v2 + prev.delta_v2)
            .min(extra_v2);
        let r = self.direction();
        let pr = prev.direction();
        let cos_theta = -(r[0] * pr[0] + r[1] * pr[1] + r[2] * pr[2]);
        let sin_half = (0.5 * (1.0 - cos_theta)).max(0.0).sqrt();
        let cos_half = (0.5 * (1.0 + cos_theta)).max(0.0).sqrt();
        let one_minus_sin_half = 1.0 - sin_half;
        if one_minus_sin_half > 0.0 && cos_half > 0.0 {
            let r_jd = sin_half / one_minus_sin_half;
            let move_jd_v2 = r_jd * self.junction_deviation * self.accel;
            let prev_jd_v2 = r_jd * prev.junction_deviation * prev.accel;
            // The circle must touch each move no further than its middle.
            let quarter_tan_half = 0.25 * sin_half / cos_half;
            let move_centripetal_v2 = self.delta_v2 * quarter_tan_half;
            let prev_centripetal_v2 = prev.delta_v2 * quarter_tan_half;
            max_start_v2 = max_start_v2
                .min(move_jd_v2)
                .min(prev_jd_v2)
                .min(move_centripetal_v2)
                .min(prev_centripetal_v2);
        }
        self.max_start_v2 = max_start_v2;
        self.max_mcr_start_v2 = max_start_v2.min(prev.max_mcr_start_v2 + prev.mcr_delta_v2);
    }

    /// Fix the move's speeds: start, cruise and end velocity squared.
    pub fn set_junction(&mut self, start_v2: f64, cruise_v2: f64, end_v2: f64) {
        let half_inv_accel = 0.5 / self.accel;
        let accel_d = (cruise_v2 - start_v2) * half_inv_accel;
        let decel_d = (cruise_v2 - end_v2) * half_inv_accel;
        let cruise_d = self.move_d - accel_d - decel_d;
        let start_v = start_v2.sqrt();
        let cruise_v = cruise_v2.sqrt();
        let end_v = end_v2.sqrt();
        self.plan = Plan {
            start_v,
            cruise_v,
            end_v,
            accel_t: accel_d / ((start_v + cruise_v) * 0.5),
            cruise_t: cruise_d / cruise_v,
            decel_t: decel_d / ((end_v + cruise_v) * 0.5),
        };
    }
}

/// Time worth of queued moves after which the lookahead tries a lazy flush (s).
const LOOKAHEAD_FLUSH_TIME: f64 = 0.150;
/// Time worth of moves queued after a full flush before the first lazy flush (Klipper's `BUFFER_TIME_HIGH`).
pub const BUFFER_TIME_HIGH: f64 = 1.0;

/// Speeds found for one move by the backward pass; `cruise_v2` is `None` when the move cannot accelerate
/// and takes its cruise speed from the move before it.
#[derive(Debug, Clone, Copy)]
struct Junction {
    start_v2: f64,
    cruise_v2: Option<f64>,
    end_v2: f64,
}

/// A move that cannot accelerate, waiting for the peak before it (Kalico's rule): its index, start and end speed².
#[derive(Debug, Clone, Copy)]
struct Delayed {
    index: usize,
    start_v2: f64,
    end_v2: f64,
}

/// Moves waiting for their speeds to be fixed.
#[derive(Debug, Default)]
pub struct LookAhead {
    queue: std::collections::VecDeque<Move>,
    junction_flush: f64,
    scratch: Vec<Junction>,
    rule: LookaheadRule,
    delayed: Vec<Delayed>,
}

impl LookAhead {
    pub fn new(rule: LookaheadRule) -> Self {
        LookAhead {
            queue: Default::default(),
            junction_flush: BUFFER_TIME_HIGH,
            scratch: Vec::new(),
            rule,
            delayed: Vec::new(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    pub fn last_mut(&mut self) -> Option<&mut Move> {
        self.queue.back_mut()
    }

    pub fn last(&self) -> Option<&Move> {
        self.queue.back()
    }

    pub fn set_flush_time(&mut self, flush_time: f64) {
        self.junction_flush = flush_time;
    }

    /// Queue a move (its junction with the previous move must already be computed). Returns true when enough
    /// time is queued that a lazy flush should be tried.
    #[inline]
    pub fn push(&mut self, mv: Move) -> bool {
        let first = self.queue.is_empty();
        let min_move_t = mv.min_move_t;
        self.queue.push_back(mv);
        if first {
            return false;
        }
        self.junction_flush -= min_move_t;
        self.junction_flush <= 0.0
    }

    /// Plan queued moves and hand over those whose speeds are final.
    ///
    /// Backward pass: assume a stop after the last queued move and find each move's highest reachable start
    /// speed, on two tracks — the real acceleration, and the minimum-cruise-ratio pseudo acceleration, which
    /// bounds how high a short accelerate-then-decelerate move may peak. Forward pass: moves that cannot
    /// accelerate inherit the cruise speed of the move before them. A lazy flush only releases moves up to the
    /// last point where a later move can no longer change them. Returns how many moves at the front of the
    /// queue are final; the caller reads them with [`Self::ready`] and then [`Self::release`]s them (no copy).
    pub fn flush(&mut self, lazy: bool) -> usize {
        self.junction_flush = LOOKAHEAD_FLUSH_TIME;
        if self.rule == LookaheadRule::Kalico {
            return self.flush_as_kalico(lazy);
        }
        let mut update_flush_count = lazy;
        let mut flush_count = self.queue.len();
        self.scratch.clear();
        self.scratch.resize(
            flush_count,
            Junction {
                start_v2: 0.0,
                cruise_v2: None,
                end_v2: 0.0,
            },
        );
        let mut next_start_v2 = 0.0;
        let mut next_mcr_start_v2 = 0.0;
        let mut peak_cruise_v2 = 0.0;
        let mut pending_cruise_assign = 0usize;
        for i in (0..flush_count).rev() {
            let mv = &self.queue[i];
            let reachable_start_v2 = next_start_v2 + mv.delta_v2;
            let start_v2 = mv.max_start_v2.min(reachable_start_v2);
            let mut cruise_v2 = None;
            pending_cruise_assign += 1;
            let reachable_mcr_start_v2 = next_mcr_start_v2 + mv.mcr_delta_v2;
            let mcr_start_v2 = mv.max_mcr_start_v2.min(reachable_mcr_start_v2);
            if mcr_start_v2 < reachable_mcr_start_v2 {
                // This move can accelerate.
                if mcr_start_v2 + mv.mcr_delta_v2 > next_mcr_start_v2 || pending_cruise_assign > 1 {
                    // It can both accelerate and decelerate, or it is a full acceleration followed by a
                    // full deceleration: its peak is final.
                    if update_flush_count && peak_cruise_v2 != 0.0 {
                        flush_count = i + pending_cruise_assign;
                        update_flush_count = false;
                    }
                    peak_cruise_v2 = (mcr_start_v2 + reachable_mcr_start_v2) * 0.5;
                }
                cruise_v2 = Some(
                    ((start_v2 + reachable_start_v2) * 0.5)
                        .min(mv.max_cruise_v2)
                        .min(peak_cruise_v2),
                );
                pending_cruise_assign = 0;
            }
            self.scratch[i] = Junction {
                start_v2,
                cruise_v2,
                end_v2: next_start_v2,
            };
            next_start_v2 = start_v2;
            next_mcr_start_v2 = mcr_start_v2;
        }
        if update_flush_count || flush_count == 0 {
            return 0;
        }
        let mut prev_cruise_v2: f64 = 0.0;
        for (i, junction) in self.scratch.iter().take(flush_count).enumerate() {
            let cruise_v2 = junction
                .cruise_v2
                .unwrap_or(prev_cruise_v2.min(junction.start_v2));
            self.queue[i].set_junction(
                junction.start_v2.min(cruise_v2),
                cruise_v2,
                junction.end_v2.min(cruise_v2),
            );
            prev_cruise_v2 = cruise_v2;
        }
        flush_count
    }

    /// [`Self::flush`] under [`LookaheadRule::Kalico`]: the same two tracks in one backward pass, each move's
    /// speeds fixed as soon as the peak before it is known.
    fn flush_as_kalico(&mut self, lazy: bool) -> usize {
        let mut update_flush_count = lazy;
        let mut flush_count = self.queue.len();
        self.delayed.clear();
        let (mut next_end_v2, mut next_mcr_start_v2, mut peak_cruise_v2) = (0.0, 0.0, 0.0);
        for i in (0..self.queue.len()).rev() {
            let mv = &self.queue[i];
            let (delta_v2, mcr_delta_v2, max_cruise_v2) =
                (mv.delta_v2, mv.mcr_delta_v2, mv.max_cruise_v2);
            let reachable_start_v2 = next_end_v2 + delta_v2;
            let start_v2 = mv.max_start_v2.min(reachable_start_v2);
            let reachable_mcr_start_v2 = next_mcr_start_v2 + mcr_delta_v2;
            let mcr_start_v2 = mv.max_mcr_start_v2.min(reachable_mcr_start_v2);
            if mcr_start_v2 < reachable_mcr_start_v2 {
                // This move can accelerate.
                if mcr_start_v2 + mcr_delta_v2 > next_mcr_start_v2 || !self.delayed.is_empty() {
                    // It can decelerate too, or it is a full acceleration after a full deceleration.
                    if update_flush_count && peak_cruise_v2 != 0.0 {
                        flush_count = i;
                        update_flush_count = false;
                    }
                    peak_cruise_v2 =
                        max_cruise_v2.min((mcr_start_v2 + reachable_mcr_start_v2) * 0.5);
                    if !update_flush_count && i < flush_count {
                        self.plan_delayed(peak_cruise_v2);
                    }
                    self.delayed.clear();
                }
                if !update_flush_count && i < flush_count {
                    let cruise_v2 = ((start_v2 + reachable_start_v2) * 0.5)
                        .min(max_cruise_v2)
                        .min(peak_cruise_v2);
                    self.queue[i].set_junction(
                        start_v2.min(cruise_v2),
                        cruise_v2,
                        next_end_v2.min(cruise_v2),
                    );
                }
            } else {
                // Planned with the next peak found further back.
                self.delayed.push(Delayed {
                    index: i,
                    start_v2,
                    end_v2: next_end_v2,
                });
            }
            next_end_v2 = start_v2;
            next_mcr_start_v2 = mcr_start_v2;
        }
        if update_flush_count {
            return 0;
        }
        flush_count
    }

    /// The waiting moves, first to last, cruise at the peak before them or lower where one must start slower.
    fn plan_delayed(&mut self, peak_cruise_v2: f64) {
        let mut cruise_v2 = peak_cruise_v2;
        for d in self.delayed.iter().rev() {
            cruise_v2 = cruise_v2.min(d.start_v2);
            self.queue[d.index].set_junction(
                d.start_v2.min(cruise_v2),
                cruise_v2,
                d.end_v2.min(cruise_v2),
            );
        }
    }

    /// The first `count` queued moves (those a [`Self::flush`] made final), in order.
    pub fn ready(&self, count: usize) -> impl Iterator<Item = &Move> {
        self.queue.range(..count)
    }

    /// Drop the first `count` queued moves once they have been handed on.
    pub fn release(&mut self, count: usize) {
        self.queue.drain(..count);
    }

    /// Drop every queued move (after an error).
    pub fn clear(&mut self) {
        self.queue.clear();
        self.junction_flush = LOOKAHEAD_FLUSH_TIME;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> VelocityLimits {
        VelocityLimits {
            max_velocity: 100.0,
            max_accel: 1000.0,
            square_corner_velocity: 5.0,
            minimum_cruise_ratio: 0.5,
        }
    }

    #[test]
    fn lone_move_is_a_symmetric_trapezoid() {
        let mut mv =
            Move::new([0.0; 4], [100.0, 0.0, 0.0, 0.0], 50.0, &limits(), 1).expect("moves");
        mv.set_junction(0.0, 2500.0, 0.0);
        // 0 → 50 mm/s at 1000 mm/s²: 0.05 s and 1.25 mm each way, 97.5 mm of cruise at 50 mm/s.
        assert!((mv.plan.accel_t - 0.05).abs() < 1e-15);
        assert!((mv.plan.decel_t - 0.05).abs() < 1e-15);
        assert!((mv.plan.cruise_t - 1.95).abs() < 1e-12);
    }

    #[test]
    fn straight_continuation_keeps_full_speed() {
        let l = limits();
        let a = Move::new([0.0; 4], [10.0, 0.0, 0.0, 0.0], 50.0, &l, 1).expect("moves");
        let mut b = Move::new(a.end_pos, [20.0, 0.0, 0.0, 0.0], 50.0, &l, 2).expect("moves");
        b.calc_junction(&a, f64::INFINITY);
        assert_eq!(b.max_start_v2, 2500.0);
    }

    #[test]
    fn reversal_stops() {
        let l = limits();
        let a = Move::new([0.0; 4], [10.0, 0.0, 0.0, 0.0], 50.0, &l, 1).expect("moves");
        let mut b = Move::new(a.end_pos, [0.0, 0.0, 0.0, 0.0], 50.0, &l, 2).expect("moves");
        b.calc_junction(&a, f64::INFINITY);
        assert_eq!(b.max_start_v2, 0.0);
    }

    #[test]
    fn zero_length_move_is_dropped_and_tiny_xyz_becomes_extrude_only() {
        assert!(Move::new([1.0; 4], [1.0; 4], 10.0, &limits(), 1).is_none());
        let mv = Move::new([0.0; 4], [1e-12, 0.0, 0.0, 0.5], 10.0, &limits(), 1).expect("moves");
        assert!(!mv.is_kinematic);
        assert_eq!(mv.end_pos, [0.0, 0.0, 0.0, 0.5]);
        assert_eq!(mv.move_d, 0.5);
    }

    /// From rest, 0.3 mm at up to 100 mm/s, then straight on at 20 mm/s (the junction at 20 mm/s). The short move
    /// can only accelerate on the minimum-cruise-ratio track, so it cruises at the mean of its reachable speeds²
    /// (0 and 20² + 2·0.3·1000: √500) capped by the slow move's peak: Klipper's peak is that track's alone,
    /// Kalico's is also capped by the slow move's own limit (20 mm/s).
    #[test]
    fn a_short_move_before_a_slow_one_peaks_by_the_hosts_rule() {
        let l = limits();
        let cruise = |rule: LookaheadRule| {
            let a = Move::new([0.0; 4], [0.3, 0.0, 0.0, 0.0], 100.0, &l, 1).expect("moves");
            let mut b = Move::new(a.end_pos, [10.0, 0.0, 0.0, 0.0], 20.0, &l, 2).expect("moves");
            b.calc_junction(&a, f64::INFINITY);
            let mut queue = LookAhead::new(rule);
            queue.push(a);
            queue.push(b);
            assert_eq!(queue.flush(false), 2);
            queue.ready(1).next().expect("first move").plan.cruise_v
        };
        assert!((cruise(LookaheadRule::Klipper) - 500f64.sqrt()).abs() < 1e-12);
        assert!((cruise(LookaheadRule::Kalico) - 20.0).abs() < 1e-12);
    }
}
