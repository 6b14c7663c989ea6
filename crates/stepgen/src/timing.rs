//! Time along a piece: splitting a piece where its speed changes sign, the exact inverse of the
//! distance law `d(t) = v0·t + h·t²` (numerically stable quadratic roots), and the clamps that keep a
//! computed time or distance inside its range.

use trapq::Piece;

/// A time range of a piece over which the travelled distance changes monotonically.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Span {
    /// Start and end time, relative to the piece start (s).
    pub t0: f64,
    pub t1: f64,
    /// Distance along the piece direction at `t0` and `t1` (mm).
    pub d0: f64,
    pub d1: f64,
    /// Sign of the speed inside the span: +1 or −1 (+1 when the span does not move).
    pub sign: f64,
    /// Piece speed law, copied for the inverse.
    v0: f64,
    half_accel: f64,
}

impl Span {
    /// The constant speed of a cruise span (no acceleration, moving), if it is one.
    #[inline]
    pub fn cruise_speed(&self) -> Option<f64> {
        (self.half_accel == 0.0 && self.v0 != 0.0).then_some(self.v0)
    }

    /// Keep a time inside the span (a computed time only leaves it by rounding).
    #[inline]
    pub fn clamp_time(&self, t: f64) -> f64 {
        clamp_ordered(t, self.t0, self.t1)
    }

    /// Largest |speed| in the span (mm/s).
    pub fn max_speed(&self) -> f64 {
        let va = self.v0 + 2.0 * self.half_accel * self.t0;
        let vb = self.v0 + 2.0 * self.half_accel * self.t1;
        va.abs().max(vb.abs())
    }

    /// Time (relative to the piece start) at which the distance equals `s`, for `s` between `d0` and `d1`.
    ///
    /// Solves `h·t² + v0·t − s = 0` for the root whose speed `v0 + 2ht` has the span's sign. With
    /// `σ√D = v0 + 2ht` (D = v0² + 4hs) the two algebraic forms are `t = 2s / (σ√D + v0)` and
    /// `t = (σ√D − v0) / 2h`; the first is free of cancellation when v0 has the span's sign, the second
    /// otherwise. The result is kept inside the span (it only leaves it by rounding).
    #[inline]
    pub fn time_at(&self, s: f64) -> f64 {
        let (v0, h) = (self.v0, self.half_accel);
        let t = if h == 0.0 {
            // A true division (not a reciprocal multiply): exact step times often sit on half ticks, and
            // Klipper divides too.
            if v0 == 0.0 { self.t0 } else { s / v0 }
        } else {
            let root = self.sign * (v0 * v0 + 4.0 * h * s).max(0.0).sqrt();
            if self.sign * v0 >= 0.0 {
                let den = root + v0;
                if den == 0.0 { self.t0 } else { 2.0 * s / den }
            } else {
                (root - v0) / (2.0 * h)
            }
        };
        self.clamp_time(t)
    }
}

/// Split a piece into at most two spans of monotonic distance (split where the speed crosses zero).
pub(crate) fn monotonic_spans(piece: &Piece) -> ([Span; 2], usize) {
    let (v0, h, dur) = (piece.start_v, piece.half_accel, piece.duration);
    let make = |t0: f64, t1: f64| {
        let d0 = piece.distance(t0);
        let d1 = piece.distance(t1);
        let mid_v = v0 + h * (t0 + t1);
        let sign = if mid_v < 0.0 { -1.0 } else { 1.0 };
        Span {
            t0,
            t1,
            d0,
            d1,
            sign,
            v0,
            half_accel: h,
        }
    };
    let turn = if h != 0.0 { -v0 / (2.0 * h) } else { f64::NAN };
    if turn > 0.0 && turn < dur {
        ([make(0.0, turn), make(turn, dur)], 2)
    } else {
        let span = make(0.0, dur);
        ([span, span], 1)
    }
}

/// Clamp `x` into the closed range between `a` and `b` (in either order); NaN becomes the lower end.
/// Written as comparisons and selects, which compile to single min/max instructions (`f64::min`/`max`
/// add NaN handling): it runs on every step.
#[inline]
pub(crate) fn clamp_between(x: f64, a: f64, b: f64) -> f64 {
    let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
    clamp_ordered(x, lo, hi)
}

/// Clamp `x` into `[lo, hi]` (`lo ≤ hi`); NaN becomes `lo`.
#[inline]
pub(crate) fn clamp_ordered(x: f64, lo: f64, hi: f64) -> f64 {
    let above = if x > lo { x } else { lo };
    if above < hi { above } else { hi }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn piece(v0: f64, half_accel: f64, duration: f64) -> Piece {
        Piece {
            print_time: 0.0,
            duration,
            start_v: v0,
            half_accel,
            start_pos: [0.0; 3],
            axes_r: [1.0, 0.0, 0.0],
            motion: trapq::Motion::Travel,
        }
    }

    fn check_inverse(p: &Piece) {
        let (spans, n) = monotonic_spans(p);
        for span in &spans[..n] {
            for i in 0..=20 {
                let t = span.t0 + (span.t1 - span.t0) * i as f64 / 20.0;
                let back = span.time_at(p.distance(t));
                assert!((back - t).abs() < 1e-9, "t {t} back {back} piece {p:?}");
            }
        }
    }

    #[test]
    fn inverse_of_cruise_accel_decel_and_reversal() {
        check_inverse(&piece(10.0, 0.0, 1.0));
        check_inverse(&piece(0.0, 1500.0, 0.1));
        check_inverse(&piece(100.0, -1500.0, 100.0 / 3000.0));
        check_inverse(&piece(-28.0, 399.0, 0.035));
        check_inverse(&piece(5.0, -100.0, 0.1)); // speed turns at 0.025 s
    }

    #[test]
    fn reversal_splits_into_two_spans() {
        let (spans, n) = monotonic_spans(&piece(5.0, -100.0, 0.1));
        assert_eq!(n, 2);
        assert_eq!(spans[0].t1, 0.025);
        assert_eq!(spans[0].sign, 1.0);
        assert_eq!(spans[1].sign, -1.0);
    }

    #[test]
    fn start_from_rest_has_exact_square_root_law() {
        let p = piece(0.0, 2.0, 1.0);
        let (spans, _) = monotonic_spans(&p);
        // d = 2t² → t = sqrt(d/2)
        assert_eq!(spans[0].time_at(0.5), 0.5);
        assert_eq!(spans[0].time_at(0.0), 0.0);
    }
}
