//! Two `f64` side by side: the two levels a SCARA joint solves at once go through the same arithmetic lane by
//! lane, which the compiler turns into packed SSE2 instructions (two evaluations for the price of one, and
//! half the instructions of two scalar ones). Each lane rounds exactly as the scalar operation would.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// Two values, one per lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Lanes(pub(super) [f64; 2]);

impl Lanes {
    #[inline(always)]
    pub(super) fn splat(x: f64) -> Self {
        Lanes([x, x])
    }

    #[inline(always)]
    pub(super) fn map(self, op: impl Fn(f64) -> f64) -> Self {
        Lanes([op(self.0[0]), op(self.0[1])])
    }

    #[inline(always)]
    fn zip(self, other: Self, op: impl Fn(f64, f64) -> f64) -> Self {
        Lanes([op(self.0[0], other.0[0]), op(self.0[1], other.0[1])])
    }

    #[inline(always)]
    pub(super) fn sqrt(self) -> Self {
        self.map(f64::sqrt)
    }

    /// Per lane: whether `low < x < high` (false for NaN).
    #[inline(always)]
    pub(super) fn strictly_within(self, low: f64, high: f64) -> [bool; 2] {
        self.0.map(|x| x > low && x < high)
    }

    /// Per lane: whether `x > 0` (false for NaN).
    #[inline(always)]
    pub(super) fn positive(self) -> [bool; 2] {
        self.0.map(|x| x > 0.0)
    }

    /// Per lane: whether `|x| ≤ bound` (false for NaN).
    #[inline(always)]
    pub(super) fn small(self, bound: f64) -> [bool; 2] {
        self.0.map(|x| x.abs() <= bound)
    }
}

macro_rules! lane_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: Lanes) -> Lanes {
                self.zip(other, |a, b| a $op b)
            }
        }

        impl $trait<f64> for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: f64) -> Lanes {
                self.map(|a| a $op other)
            }
        }

        impl $trait<Lanes> for f64 {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: Lanes) -> Lanes {
                other.map(|b| self $op b)
            }
        }
    };
}

lane_op!(Add, add, +);
lane_op!(Sub, sub, -);
lane_op!(Mul, mul, *);
lane_op!(Div, div, /);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        self.map(|x| -x)
    }
}

/// Per lane: both conditions.
#[inline(always)]
pub(super) fn both(a: [bool; 2], b: [bool; 2]) -> [bool; 2] {
    [a[0] && b[0], a[1] && b[1]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_round_as_scalars() {
        let (a, b) = (Lanes([0.1, 1e300]), Lanes([0.2, 3.0]));
        assert_eq!((a + b).0, [0.1 + 0.2, 1e300 + 3.0]);
        assert_eq!((a * b - 1.0).0, [0.1 * 0.2 - 1.0, 1e300 * 3.0 - 1.0]);
        assert_eq!((2.0 * a).sqrt().0, [(0.2f64).sqrt(), (2e300f64).sqrt()]);
        assert_eq!((1.0 / b).0, [1.0 / 0.2, 1.0 / 3.0]);
        assert_eq!(
            Lanes([f64::NAN, 0.5]).strictly_within(-1.0, 1.0),
            [false, true]
        );
    }
}
