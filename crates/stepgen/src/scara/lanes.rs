//! Two `f64` side by side: the two levels a SCARA joint solves at once go through the same arithmetic lane by
//! lane. A `Lanes` is a `wide::f64x2`: on x86_64 one SSE2 register, each operation one packed instruction
//! (the compiler's own vectorising of a plain pair left most of this arithmetic scalar, with its divisions
//! and square roots twice over). Each lane rounds exactly as the scalar operation would (IEEE 754 per
//! lane, no fused operations).

use std::ops::{Add, Div, Mul, Neg, Sub};

use wide::f64x2;

/// Two values, one per lane.
#[derive(Clone, Copy)]
pub(super) struct Lanes(f64x2);

/// Per lane, whether a condition holds (bit 0: the first lane, bit 1: the second).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Mask(u32);

impl Mask {
    /// Per lane: both conditions.
    #[inline(always)]
    pub(super) fn and(self, other: Mask) -> Mask {
        Mask(self.0 & other.0)
    }

    /// Whether it holds in both lanes.
    #[inline(always)]
    pub(super) fn all(self) -> bool {
        self.0 == 3
    }

    #[inline(always)]
    pub(super) fn lanes(self) -> [bool; 2] {
        [self.0 & 1 != 0, self.0 & 2 != 0]
    }
}

impl Lanes {
    #[inline(always)]
    pub(super) fn new(values: [f64; 2]) -> Self {
        Lanes(f64x2::new(values))
    }

    #[inline(always)]
    pub(super) fn splat(x: f64) -> Self {
        Lanes(f64x2::splat(x))
    }

    /// The two values.
    #[inline(always)]
    pub(super) fn array(self) -> [f64; 2] {
        self.0.to_array()
    }

    /// The first lane's value.
    #[inline(always)]
    pub(super) fn first(self) -> f64 {
        self.array()[0]
    }

    #[inline(always)]
    pub(super) fn sqrt(self) -> Self {
        Lanes(self.0.sqrt())
    }

    #[inline(always)]
    pub(super) fn abs(self) -> Self {
        Lanes(self.0.abs())
    }

    /// Per lane: this magnitude with `sign`'s sign.
    #[inline(always)]
    pub(super) fn copysign(self, sign: Lanes) -> Self {
        Lanes(self.0.copysign(sign.0))
    }

    /// Per lane: whether `low < x < high` (false for NaN).
    #[inline(always)]
    pub(super) fn strictly_within(self, low: f64, high: f64) -> Mask {
        Mask((self.0.simd_gt(f64x2::splat(low)) & self.0.simd_lt(f64x2::splat(high))).to_bitmask())
    }

    /// Per lane: whether `x > 0` (false for NaN).
    #[inline(always)]
    pub(super) fn positive(self) -> Mask {
        Mask(self.0.simd_gt(f64x2::ZERO).to_bitmask())
    }

    /// Per lane: whether `|x| ≤ bound` (false for NaN).
    #[inline(always)]
    pub(super) fn small(self, bound: f64) -> Mask {
        Mask(self.0.abs().simd_le(f64x2::splat(bound)).to_bitmask())
    }
}

impl std::fmt::Debug for Lanes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("Lanes").field(&self.array()).finish()
    }
}

macro_rules! lane_op {
    ($trait:ident, $method:ident) => {
        impl $trait for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: Lanes) -> Lanes {
                Lanes($trait::$method(self.0, other.0))
            }
        }

        impl $trait<f64> for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: f64) -> Lanes {
                Lanes($trait::$method(self.0, f64x2::splat(other)))
            }
        }

        impl $trait<Lanes> for f64 {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: Lanes) -> Lanes {
                Lanes($trait::$method(f64x2::splat(self), other.0))
            }
        }
    };
}

lane_op!(Add, add);
lane_op!(Sub, sub);
lane_op!(Mul, mul);
lane_op!(Div, div);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        Lanes(-self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_round_as_scalars() {
        let (a, b) = (Lanes::new([0.1, 1e300]), Lanes::new([0.2, 3.0]));
        assert_eq!((a + b).array(), [0.1 + 0.2, 1e300 + 3.0]);
        assert_eq!((a * b - 1.0).array(), [0.1 * 0.2 - 1.0, 1e300 * 3.0 - 1.0]);
        assert_eq!(
            (2.0 * a).sqrt().array(),
            [(0.2f64).sqrt(), (2e300f64).sqrt()]
        );
        assert_eq!((1.0 / b).array(), [1.0 / 0.2, 1.0 / 3.0]);
        assert_eq!((-a).array(), [-0.1, -1e300]);
        assert_eq!((-a).abs().array(), [0.1, 1e300]);
        assert_eq!(a.copysign(Lanes::new([-2.0, 3.0])).array(), [-0.1, 1e300]);
        assert!(Lanes::new([0.5, 1.0]).positive().all());
        assert!(!Lanes::new([0.5, -1.0]).positive().all());
        assert_eq!(
            (-Lanes::splat(0.0)).array()[0].to_bits(),
            (-0.0f64).to_bits()
        );
        assert_eq!(
            Lanes::new([f64::NAN, 0.5])
                .strictly_within(-1.0, 1.0)
                .lanes(),
            [false, true]
        );
        assert_eq!(
            Lanes::new([-0.5, f64::INFINITY]).positive().lanes(),
            [false, true]
        );
        assert_eq!(
            Lanes::new([-0.01, f64::NAN]).small(0.01).lanes(),
            [true, false]
        );
        let both = Lanes::new([1.0, 1.0])
            .positive()
            .and(Lanes::new([1.0, -1.0]).positive());
        assert_eq!(both.lanes(), [true, false]);
    }
}
