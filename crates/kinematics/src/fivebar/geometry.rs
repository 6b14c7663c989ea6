//! One side of a five-bar in closed form: its base joint's angle from the nozzle's `(x, y)` alone. The one
//! implementation of the side inverse: [`super::Fivebar`] builds its poses on it, and step solvers that follow one
//! motor (the Klipper plug-in's) carry it as plain `Copy` data.

use std::f64::consts::{PI, TAU};

use super::{REACH_ROUNDING, SIDES};
use crate::{FivebarArm, ReachError};

/// One side's geometry and motor: what its base joint's angle depends on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FivebarSide {
    /// `LEFT` or `RIGHT` (for messages).
    side: usize,
    base: [f64; 2],
    proximal: f64,
    distal: f64,
    /// `+1`: the turn base → elbow → nozzle is counter-clockwise; `−1`: clockwise.
    turn: f64,
    /// Motor reading (rad) when the proximal link points along +X.
    zero: f64,
    /// The angle is given in `(window − π, window + π]`.
    window: f64,
}

/// Both sides of a five-bar (see [`crate::SolverGeometry::Fivebar`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FivebarGeometry {
    pub sides: [FivebarSide; 2],
}

/// Side `k`'s answer for one nozzle position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideAngle {
    /// The proximal link's absolute angle (rad), in the side's window.
    pub theta: f64,
    /// The nozzle's distance from the base joint (mm).
    pub distance: f64,
    /// The angle at the base between base → nozzle and base → elbow (rad, in `[0, π]`).
    pub beta: f64,
}

/// Angle in `(c − π, c + π]`.
pub(super) fn within(angle: f64, c: f64) -> f64 {
    let d = (angle - c).rem_euclid(TAU);
    if d > PI { c + d - TAU } else { c + d }
}

impl FivebarSide {
    pub(super) fn new(side: usize, arm: &FivebarArm, window: f64) -> Self {
        FivebarSide {
            side,
            base: arm.base,
            proximal: arm.proximal,
            distal: arm.distal,
            turn: arm.turn.sign(),
            zero: arm.zero,
            window,
        }
    }

    /// The base joint's angle for the nozzle at `(x, y)` on the configured branch: `atan2` of the nozzle seen from
    /// the base, turned by the law of cosines' angle `β` away from the elbow's side. Fails only where the side has
    /// no pose (beyond its reach or inside its folded reach, beyond rounding; on the base joint itself).
    #[inline]
    pub fn angle(&self, x: f64, y: f64) -> Result<SideAngle, ReachError> {
        let (p, d_len) = (self.proximal, self.distal);
        let (u, v) = (x - self.base[0], y - self.base[1]);
        let d = u.hypot(v);
        let (min, max) = ((p - d_len).abs(), p + d_len);
        // Written so that NaN fails here too (every comparison with NaN is false).
        if !(d - max <= REACH_ROUNDING && min - d <= REACH_ROUNDING && d > 0.0) {
            return Err(self.out_of_reach(x, y, d));
        }
        let cos_b = ((p * p + d * d - d_len * d_len) / (2.0 * p * d)).clamp(-1.0, 1.0);
        let beta = cos_b.acos();
        // Counter-clockwise turn base → elbow → nozzle: the elbow lies clockwise of the base → nozzle line.
        let theta = within(v.atan2(u) - self.turn * beta, self.window);
        Ok(SideAngle {
            theta,
            distance: d,
            beta,
        })
    }

    /// The motor's reading for the nozzle at `(x, y)`: the side's angle plus its zero.
    #[inline]
    pub fn motor(&self, x: f64, y: f64) -> Result<f64, ReachError> {
        self.angle(x, y).map(|a| a.theta + self.zero)
    }

    /// The elbow for the proximal link at `theta` and |sin| of the angle between the proximal and distal links.
    pub(super) fn elbow_and_sin(&self, a: &SideAngle) -> ([f64; 2], f64) {
        let elbow = [
            self.base[0] + self.proximal * a.theta.cos(),
            self.base[1] + self.proximal * a.theta.sin(),
        ];
        (elbow, (a.distance * a.beta.sin() / self.distal).min(1.0))
    }

    fn out_of_reach(&self, x: f64, y: f64, distance: f64) -> ReachError {
        if !(x.is_finite() && y.is_finite()) {
            return ReachError::NotFinite;
        }
        ReachError::ArmReach {
            arm: SIDES[self.side],
            x,
            y,
            distance,
            min: (self.proximal - self.distal).abs(),
            max: self.proximal + self.distal,
        }
    }
}
