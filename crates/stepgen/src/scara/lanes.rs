//! Two `f64` side by side: the two levels a SCARA joint solves at once go through the same arithmetic lane by
//! lane. A `Lanes` is a `wide::f64x2`: on x86_64 one SSE2 register, each operation one packed instruction
//! (the compiler's own vectorising of a plain pair left most of this arithmetic scalar, with its divisions
//! and square roots twice over). Each lane rounds exactly as the scalar operation would (IEEE 754 per
//! lane, no fused operations).

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The lanes' storage: one SSE2 register on x86_64 (`wide` picks the instructions per target).
mod repr {
    use wide::f64x2;

    pub(super) type Repr = f64x2;

    #[inline(always)]
    pub(super) fn new(a: [f64; 2]) -> Repr {
        f64x2::new(a)
    }
    #[inline(always)]
    pub(super) fn splat(x: f64) -> Repr {
        f64x2::splat(x)
    }
    #[inline(always)]
    pub(super) fn array(v: Repr) -> [f64; 2] {
        v.to_array()
    }
    #[inline(always)]
    pub(super) fn add(a: Repr, b: Repr) -> Repr {
        a + b
    }
    #[inline(always)]
    pub(super) fn sub(a: Repr, b: Repr) -> Repr {
        a - b
    }
    #[inline(always)]
    pub(super) fn mul(a: Repr, b: Repr) -> Repr {
        a * b
    }
    #[inline(always)]
    pub(super) fn div(a: Repr, b: Repr) -> Repr {
        a / b
    }
    #[inline(always)]
    pub(super) fn sqrt(a: Repr) -> Repr {
        a.sqrt()
    }
    /// `a`'s magnitude with `sign`'s sign bit, as `f64::copysign`.
    #[inline(always)]
    pub(super) fn copysign(a: Repr, sign: Repr) -> Repr {
        a.copysign(sign)
    }
    #[inline(always)]
    pub(super) fn abs(a: Repr) -> Repr {
        a.abs()
    }
    /// The sign bit flipped, as scalar negation does.
    #[inline(always)]
    pub(super) fn neg(a: Repr) -> Repr {
        -a
    }
    /// Per lane `low < x < high` (false for NaN), as bits 0 and 1.
    #[inline(always)]
    pub(super) fn within_bits(x: Repr, low: f64, high: f64) -> u32 {
        (x.simd_gt(splat(low)) & x.simd_lt(splat(high))).to_bitmask()
    }
    /// Per lane `x > 0` (false for NaN), as bits 0 and 1.
    #[inline(always)]
    pub(super) fn positive_bits(x: Repr) -> u32 {
        x.simd_gt(f64x2::ZERO).to_bitmask()
    }
    /// Per lane `|x| ≤ bound` (false for NaN), as bits 0 and 1.
    #[inline(always)]
    pub(super) fn small_bits(x: Repr, bound: f64) -> u32 {
        x.abs().simd_le(splat(bound)).to_bitmask()
    }
}

/// Two values, one per lane.
#[derive(Clone, Copy)]
pub(super) struct Lanes(repr::Repr);

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
        Lanes(repr::new(values))
    }

    #[inline(always)]
    pub(super) fn splat(x: f64) -> Self {
        Lanes(repr::splat(x))
    }

    /// The two values.
    #[inline(always)]
    pub(super) fn array(self) -> [f64; 2] {
        repr::array(self.0)
    }

    /// The first lane's value.
    #[inline(always)]
    pub(super) fn first(self) -> f64 {
        self.array()[0]
    }

    #[inline(always)]
    pub(super) fn sqrt(self) -> Self {
        Lanes(repr::sqrt(self.0))
    }

    #[inline(always)]
    pub(super) fn abs(self) -> Self {
        Lanes(repr::abs(self.0))
    }

    /// Per lane: this magnitude with `sign`'s sign.
    #[inline(always)]
    pub(super) fn copysign(self, sign: Lanes) -> Self {
        Lanes(repr::copysign(self.0, sign.0))
    }

    /// Per lane: whether `low < x < high` (false for NaN).
    #[inline(always)]
    pub(super) fn strictly_within(self, low: f64, high: f64) -> Mask {
        Mask(repr::within_bits(self.0, low, high))
    }

    /// Per lane: whether `x > 0` (false for NaN).
    #[inline(always)]
    pub(super) fn positive(self) -> Mask {
        Mask(repr::positive_bits(self.0))
    }

    /// Per lane: whether `|x| ≤ bound` (false for NaN).
    #[inline(always)]
    pub(super) fn small(self, bound: f64) -> Mask {
        Mask(repr::small_bits(self.0, bound))
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
                Lanes(repr::$method(self.0, other.0))
            }
        }

        impl $trait<f64> for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: f64) -> Lanes {
                Lanes(repr::$method(self.0, repr::splat(other)))
            }
        }

        impl $trait<Lanes> for f64 {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: Lanes) -> Lanes {
                Lanes(repr::$method(repr::splat(self), other.0))
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
        Lanes(repr::neg(self.0))
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
