//! Step times for motors without a closed form (polar with an offset arm; SCARA joints where the one-motor
//! solver of `crate::scara` does not apply: spans at the reach limits, the FEKT cos quirk), through
//! [`Kinematics::inverse_near`].
//!
//! Along a monotonic span of a piece the motor position `f(s)` is a smooth function of the travelled distance
//! `s`. The solver walks `s` with steps no longer than `δ / M`, where `δ` is the distance from `f` to the
//! nearest step threshold and `M` bounds `|df/ds|`: within such a step `f` cannot reach a threshold, so no
//! crossing is skipped. `M` is 1.5 times the largest directional derivative `|∇f · U|` sampled (from the
//! Jacobian) at 17 points of the span, refined around the largest sample. Walk steps are never shorter than
//! `min(250 µs of travel, step/(2M))`: a crossing and return skipped inside such a window would be a step
//! pair less than 750 µs apart that never reached its commanded position (that needs half a step more
//! motion than the window allows), so the step+dir+step filter would remove it anyway. The walk therefore
//! reproduces the filtered output exactly while sampling a few times per step. A bracketed crossing is then
//! solved by the
//! Illinois variant of regula falsi (bisection safeguard) to ~1e-12 s, and `s` is mapped to time exactly.

use kinematics::{Kinematics, Vec3};
use trapq::Piece;

use crate::error::StepError;
use crate::sink::StepSink;
use crate::step_rule::StepRule;
use crate::timing::Span;

/// Scratch state of a general motor: last motor positions (for unwrapping) and buffers.
#[derive(Debug, Clone)]
pub(crate) struct GeneralState {
    index: usize,
    previous: Vec<f64>,
    scratch: Vec<f64>,
    rows: Vec<Vec3>,
}

impl GeneralState {
    pub(crate) fn new(index: usize, start_motors: &[f64]) -> Self {
        GeneralState {
            index,
            previous: start_motors.to_vec(),
            scratch: vec![0.0; start_motors.len()],
            rows: vec![[0.0; 3]; start_motors.len()],
        }
    }

    /// The last evaluated position of motor `motor` (what the next evaluation unwraps near).
    pub(crate) fn motor(&self, motor: usize) -> Option<f64> {
        self.previous.get(motor).copied()
    }

    /// Set what the next evaluation unwraps motor `motor` near (another solver moved it meanwhile).
    pub(crate) fn set_motor(&mut self, motor: usize, value: f64) {
        if let Some(slot) = self.previous.get_mut(motor) {
            *slot = value;
        }
    }

    /// Motor position at toolhead position `p`, unwrapped near the previous evaluation.
    fn position(&mut self, kin: &dyn Kinematics, p: Vec3) -> Result<f64, kinematics::ReachError> {
        kin.inverse_near(p, &self.previous, &mut self.scratch)?;
        std::mem::swap(&mut self.previous, &mut self.scratch);
        match self.previous.get(self.index) {
            Some(&value) if value.is_finite() => Ok(value),
            _ => Err(kinematics::ReachError::NotFinite),
        }
    }

    /// |df/ds| at `p` for a move along `u`.
    fn slope(
        &mut self,
        kin: &dyn Kinematics,
        p: Vec3,
        u: Vec3,
    ) -> Result<f64, kinematics::ReachError> {
        kin.jacobian(p, &mut self.rows)?;
        let row = self
            .rows
            .get(self.index)
            .copied()
            .ok_or(kinematics::ReachError::NotFinite)?;
        Ok((row[0] * u[0] + row[1] * u[1] + row[2] * u[2]).abs())
    }
}

/// Longest "shortest walk step", in seconds of travel at the span's top speed (well below the 750 µs filter).
const MIN_WALK_TIME: f64 = 250e-6;
/// Target time resolution of a crossing (s).
const ROOT_TIME_TOL: f64 = 1e-12;
const SLOPE_SAMPLES: usize = 17;
/// Safety factor on the largest sampled slope.
const SLOPE_MARGIN: f64 = 1.5;

impl GeneralState {
    /// Steps of this motor (named `motor` in errors) over one span, by `rule`.
    pub(crate) fn span_steps<S: StepSink + ?Sized>(
        &mut self,
        rule: &mut StepRule,
        motor: &str,
        piece: &Piece,
        span: &Span,
        kin: &dyn Kinematics,
        sink: &mut S,
    ) -> Result<(), StepError> {
        let mut walk = Walk::new(self, motor, rule.half_step(), piece, span, kin)?;
        walk.run(rule, sink)
    }
}

/// One general-motor walk along a span.
struct Walk<'a> {
    state: &'a mut GeneralState,
    /// The motor's name, for errors.
    motor: &'a str,
    piece: &'a Piece,
    span: &'a Span,
    kin: &'a dyn Kinematics,
    /// Bound on |df/ds|.
    slope_bound: f64,
    min_ds: f64,
    s_tol: f64,
}

impl<'a> Walk<'a> {
    fn new(
        state: &'a mut GeneralState,
        motor: &'a str,
        half_step: f64,
        piece: &'a Piece,
        span: &'a Span,
        kin: &'a dyn Kinematics,
    ) -> Result<Self, StepError> {
        let v_max = span.max_speed();
        let mut walk = Walk {
            state,
            motor,
            piece,
            span,
            kin,
            slope_bound: 0.0,
            min_ds: v_max * MIN_WALK_TIME,
            s_tol: 0.0,
        };
        walk.s_tol = (v_max * ROOT_TIME_TOL)
            .max(4.0 * f64::EPSILON * span.d0.abs().max(span.d1.abs()).max(1.0));
        walk.slope_bound = walk.bound_slope()?;
        // An unbounded slope (a singular pose in the span) keeps the time-based shortest step: the walk must
        // advance, and the steps between two samples are still found in order by the root solver.
        if walk.slope_bound > 0.0 && walk.slope_bound.is_finite() {
            let half_step_travel = half_step / walk.slope_bound;
            walk.min_ds = walk.min_ds.min(half_step_travel);
        }
        Ok(walk)
    }

    fn point(&self, s: f64) -> Vec3 {
        let (p, u) = (self.piece.start_pos, self.piece.axes_r);
        [p[0] + u[0] * s, p[1] + u[1] * s, p[2] + u[2] * s]
    }

    fn error(&self, s: f64, source: kinematics::ReachError) -> StepError {
        let time = self.piece.print_time + self.span.time_at(s);
        StepError::Unreachable {
            motor: self.motor.to_string(),
            time,
            source,
        }
    }

    fn eval(&mut self, s: f64) -> Result<f64, StepError> {
        let p = self.point(s);
        let result = self.state.position(self.kin, p);
        result.map_err(|e| self.error(s, e))
    }

    fn slope_at(&mut self, s: f64) -> Result<f64, StepError> {
        let p = self.point(s);
        let result = self.state.slope(self.kin, p, self.piece.axes_r);
        match result {
            // On a singular pose (a SCARA arm straight) the motor position has no derivative but is defined:
            // the slope is unbounded, and the walk falls back to its shortest step there.
            Err(kinematics::ReachError::Singular { .. }) => Ok(f64::INFINITY),
            other => other.map_err(|e| self.error(s, e)),
        }
    }

    /// Twice the largest sampled |df/ds|, with extra samples around the largest one.
    fn bound_slope(&mut self) -> Result<f64, StepError> {
        let (d0, d1) = (self.span.d0, self.span.d1);
        let at = |i: f64, n: f64| d0 + (d1 - d0) * i / n;
        let n = (SLOPE_SAMPLES - 1) as f64;
        let (mut best, mut best_i) = (0.0f64, 0usize);
        for i in 0..SLOPE_SAMPLES {
            let g = self.slope_at(at(i as f64, n))?;
            if g > best {
                best = g;
                best_i = i;
            }
        }
        // Refine around the peak sample: a sharp peak between samples raises the bound.
        let centre = best_i as f64;
        for k in 1..8 {
            let offset = k as f64 / 8.0;
            for pos in [centre - offset, centre + offset] {
                if (0.0..=n).contains(&pos) {
                    best = best.max(self.slope_at(at(pos, n))?);
                }
            }
        }
        Ok(SLOPE_MARGIN * best)
    }

    fn run<S: StepSink + ?Sized>(
        &mut self,
        rule: &mut StepRule,
        sink: &mut S,
    ) -> Result<(), StepError> {
        let (d0, d1) = (self.span.d0, self.span.d1);
        let dir = if d1 >= d0 { 1.0 } else { -1.0 };
        let print_time = self.piece.print_time;
        let mut s = d0;
        let mut f = self.eval(s)?;
        rule.settle(f, print_time + self.span.t0, sink);
        while (d1 - s) * dir > 0.0 {
            let gap = (rule.up_level() - f).min(f - rule.down_level()).max(0.0);
            let ds = if self.slope_bound > 0.0 {
                gap / self.slope_bound
            } else {
                f64::INFINITY
            };
            let ds = ds.max(self.min_ds);
            let s_next = if ds >= (d1 - s) * dir {
                d1
            } else {
                s + dir * ds
            };
            let f_next = self.eval(s_next)?;
            // Every threshold crossed between the two samples, in order.
            loop {
                if rule.wants_up(f_next) {
                    let level = rule.up_level();
                    let root = self.solve(s, f, s_next, f_next, level)?;
                    rule.step_up(print_time + self.span.time_at(root), sink);
                    (s, f) = (root, level);
                } else if rule.wants_down(f_next) {
                    let level = rule.down_level();
                    let root = self.solve(s, f, s_next, f_next, level)?;
                    rule.step_down(print_time + self.span.time_at(root), sink);
                    (s, f) = (root, level);
                } else {
                    break;
                }
            }
            rule.check_commit(f_next, sink);
            (s, f) = (s_next, f_next);
        }
        Ok(())
    }

    /// Distance where `f` crosses `level` between `a` and `b` (Illinois regula falsi with bisection safeguard).
    /// If `f(a)` is already past the level (inside the reversal margin) the crossing is taken at `a`.
    fn solve(&mut self, a: f64, fa: f64, b: f64, fb: f64, level: f64) -> Result<f64, StepError> {
        let (mut lo, mut glo) = (a, fa - level);
        let (mut hi, mut ghi) = (b, fb - level);
        if ghi == 0.0 {
            return Ok(hi);
        }
        if glo == 0.0 || glo.signum() == ghi.signum() {
            return Ok(lo);
        }
        let mut side = 0i8;
        for _ in 0..200 {
            if (hi - lo).abs() <= self.s_tol {
                break;
            }
            let mut x = (lo * ghi - hi * glo) / (ghi - glo);
            // Stay strictly inside the bracket; fall back to bisection when the secant point does not.
            let (min, max) = if lo < hi { (lo, hi) } else { (hi, lo) };
            if !(x > min && x < max) {
                x = 0.5 * (lo + hi);
            }
            let gx = self.eval(x)? - level;
            if gx == 0.0 {
                return Ok(x);
            }
            if gx.signum() == ghi.signum() {
                (hi, ghi) = (x, gx);
                if side == 1 {
                    glo *= 0.5;
                }
                side = 1;
            } else {
                (lo, glo) = (x, gx);
                if side == -1 {
                    ghi *= 0.5;
                }
                side = -1;
            }
        }
        Ok(if glo.abs() < ghi.abs() { lo } else { hi })
    }
}
