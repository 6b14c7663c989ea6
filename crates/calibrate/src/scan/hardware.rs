//! What the scan needs from a machine, and the scan's clock over it: every move and reading goes through
//! [`Scanner`], which counts the readings and the machine time they take.

use super::error::{HardwareError, ScanError};
use super::params::ScanParams;

/// What the scan needs from a machine. Positions are as the machine believes them (arm mm from its zero,
/// bed rad from its declared zero); commanded positions may be quantised to whole steps by the hardware,
/// and `position` reports the quantised value.
pub trait ScanHardware {
    /// Move the arm to `r` (mm, absolute).
    fn move_arm(&mut self, r: f64) -> Result<(), HardwareError>;
    /// Turn the bed to `theta` (rad, absolute, unbounded).
    fn turn_bed(&mut self, theta: f64) -> Result<(), HardwareError>;
    /// Read the Hall sensor, in tesla.
    fn read_sensor(&mut self) -> Result<f64, HardwareError>;
    /// Current (arm mm, bed rad).
    fn position(&self) -> (f64, f64);
}

/// Time of a point-to-point trapezoidal (or triangular) move of length `d` with speed `v` and accel `a`.
pub fn trapezoid_time(d: f64, v: f64, a: f64) -> f64 {
    let d = d.abs();
    if d == 0.0 {
        0.0
    } else if d >= v * v / a {
        d / v + v / a
    } else {
        2.0 * (d / a).sqrt()
    }
}

/// The scan in progress: hardware, settings, and the motion clock.
pub(super) struct Scanner<'a, H: ScanHardware> {
    pub(super) hw: &'a mut H,
    pub(super) p: &'a ScanParams,
    pub(super) time: f64,
    pub(super) reads: usize,
}

impl<'a, H: ScanHardware> Scanner<'a, H> {
    pub(super) fn new(hw: &'a mut H, p: &'a ScanParams) -> Self {
        Scanner {
            hw,
            p,
            time: 0.0,
            reads: 0,
        }
    }
}

impl<H: ScanHardware> Scanner<'_, H> {
    pub(super) fn go(&mut self, r: f64, theta: f64) -> Result<(), ScanError> {
        let (r0, t0) = self.hw.position();
        if r != r0 {
            self.hw.move_arm(r)?;
        }
        if theta != t0 {
            self.hw.turn_bed(theta)?;
        }
        let (r1, t1) = self.hw.position();
        // Axes move one after the other: a conservative estimate of the machine time.
        self.time += trapezoid_time(r1 - r0, self.p.arm_speed, self.p.arm_accel)
            + trapezoid_time(t1 - t0, self.p.bed_speed, self.p.bed_accel);
        Ok(())
    }

    /// Move, read, and return (believed r, believed θ, field).
    pub(super) fn sample(&mut self, r: f64, theta: f64) -> Result<(f64, f64, f64), ScanError> {
        self.go(r, theta)?;
        let b = self.hw.read_sensor()?;
        self.reads += 1;
        self.time += self.p.read_time;
        let (rr, tt) = self.hw.position();
        Ok((rr, tt, b))
    }

    /// Bed angle per mm of arc at arm reading `r` (arc radius ≈ |r|).
    pub(super) fn rad_per_mm(&self, r: f64) -> f64 {
        1.0 / r.abs().max(0.25 * self.p.ring_radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_time_closed_forms() {
        // Triangle: d = a·t²/4 → t = 2√(d/a).
        assert!((trapezoid_time(1.0, 100.0, 100.0) - 0.2).abs() < 1e-12);
        // Trapezoid: d/v + v/a.
        assert!((trapezoid_time(100.0, 50.0, 1000.0) - (2.0 + 0.05)).abs() < 1e-12);
        assert_eq!(trapezoid_time(0.0, 1.0, 1.0), 0.0);
    }
}
