//! The motor model of the machine as built: how far a motor really turns for the steps it is given.
//!
//! True motor position after `n` net steps from its homing reading `m0` (believed step `s`):
//! `m0 + n·s·(1 + scale_error) + microstep error`, then passed through the backlash dead band.
//! - `scale_error`: a wrong `rotation_distance`/gearing (e.g. +0.002 = the axis travels 0.2 % too far).
//! - Microstep error: drivers do not place microsteps exactly; the error repeats every electrical cycle
//!   (4 full steps). Modelled as a sinusoid of amplitude `microstep_error` × one full step over that cycle
//!   (0 = ideal driver). 0.01 of a 1.8° step is 0.018°: the centring thesis' stepper + driver model reports
//!   a positioning error below 0.02°.
//! - Backlash: the output follows the motor only after the dead band `backlash` (motor units) is taken up,
//!   so after a reversal it lags by `backlash`.

use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Assembly/driver errors of one motor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MotorError {
    /// Relative error of the travel per step (true = believed × (1 + scale_error)).
    pub scale_error: f64,
    /// Microstep positioning error amplitude, as a fraction of one full step.
    pub microstep_error: f64,
    /// Microsteps per full step (the electrical cycle is `4·microsteps` steps).
    pub microsteps: u32,
    /// Dead band in the motor's unit (mm or rad).
    pub backlash: f64,
}

impl Default for MotorError {
    /// An ideal motor with 16 microsteps.
    fn default() -> Self {
        MotorError {
            scale_error: 0.0,
            microstep_error: 0.0,
            microsteps: 16,
            backlash: 0.0,
        }
    }
}

impl MotorError {
    /// Checks that every value is usable (finite, non-negative where it must be).
    pub fn validate(&self, name: &str) -> Result<(), String> {
        if !(self.scale_error.is_finite() && self.scale_error > -1.0) {
            return Err(format!(
                "{name}: scale error {} must be > −1",
                self.scale_error
            ));
        }
        if !(self.microstep_error.is_finite() && self.microstep_error >= 0.0) {
            return Err(format!(
                "{name}: microstep error {} must be ≥ 0",
                self.microstep_error
            ));
        }
        if self.microsteps == 0 {
            return Err(format!("{name}: microsteps must be ≥ 1"));
        }
        if !(self.backlash.is_finite() && self.backlash >= 0.0) {
            return Err(format!("{name}: backlash {} must be ≥ 0", self.backlash));
        }
        Ok(())
    }

    /// Whether this motor does exactly what it is told.
    pub fn is_ideal(&self) -> bool {
        self.scale_error == 0.0 && self.microstep_error == 0.0 && self.backlash == 0.0
    }
}

/// One motor's running state on the true machine.
#[derive(Debug, Clone)]
pub(crate) struct MotorTrack {
    error: MotorError,
    /// Believed travel per step.
    step: f64,
    /// Reading at the last declared position (homing).
    reading0: f64,
    /// Absolute microstep index of `reading0`, for the phase of the microstep error.
    phase0: i64,
    /// Net steps since the declared position.
    steps: i64,
    /// Output position after the backlash dead band.
    output: f64,
}

impl MotorTrack {
    pub(crate) fn new(error: MotorError, step: f64, reading: f64) -> Self {
        let mut track = MotorTrack {
            error,
            step,
            reading0: reading,
            phase0: (reading / step).round() as i64,
            steps: 0,
            output: 0.0,
        };
        track.output = track.driven_position();
        track
    }

    /// The motor is declared to read `reading` (homing): the mechanism settles there.
    pub(crate) fn reseat(&mut self, reading: f64) {
        *self = MotorTrack::new(self.error, self.step, reading);
    }

    /// One step up (`true`) or down.
    pub(crate) fn step(&mut self, up: bool) {
        self.steps += if up { 1 } else { -1 };
        let driven = self.driven_position();
        let half = 0.5 * self.error.backlash;
        if driven - self.output > half {
            self.output = driven - half;
        } else if self.output - driven > half {
            self.output = driven + half;
        }
    }

    /// What the firmware believes the motor reads.
    pub(crate) fn reading(&self) -> f64 {
        self.reading0 + self.steps as f64 * self.step
    }

    /// Where the motor really is (after backlash).
    pub(crate) fn position(&self) -> f64 {
        self.output
    }

    /// Where the rotor is, before the backlash dead band.
    fn driven_position(&self) -> f64 {
        let travel = self.steps as f64 * self.step * (1.0 + self.error.scale_error);
        self.reading0 + travel + self.microstep_offset()
    }

    fn microstep_offset(&self) -> f64 {
        if self.error.microstep_error == 0.0 {
            return 0.0;
        }
        let per_cycle = 4 * i64::from(self.error.microsteps);
        let phase = (self.phase0 + self.steps).rem_euclid(per_cycle) as f64 / per_cycle as f64;
        let full_step = f64::from(self.error.microsteps) * self.step;
        self.error.microstep_error * full_step * (phase * TAU).sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ideal_motor_is_at_its_reading() {
        let mut m = MotorTrack::new(MotorError::default(), 0.0125, 10.0);
        for _ in 0..37 {
            m.step(true);
        }
        m.step(false);
        assert!((m.position() - (10.0 + 36.0 * 0.0125)).abs() < 1e-12);
        assert_eq!(m.position(), m.reading());
    }

    #[test]
    fn scale_error_grows_with_travel() {
        let e = MotorError {
            scale_error: 0.01,
            ..MotorError::default()
        };
        let mut m = MotorTrack::new(e, 0.01, 0.0);
        for _ in 0..1000 {
            m.step(true);
        }
        // 10 mm commanded, 10.1 mm travelled.
        assert!((m.position() - 10.1).abs() < 1e-9);
    }

    #[test]
    fn microstep_error_peaks_a_quarter_cycle_in() {
        let e = MotorError {
            microstep_error: 0.05,
            microsteps: 16,
            ..MotorError::default()
        };
        let mut m = MotorTrack::new(e, 0.0125, 0.0);
        for _ in 0..16 {
            m.step(true);
        }
        // One full step (0.2 mm) into the 4-full-step cycle: sin(π/2) = 1, error 5 % of 0.2 mm.
        assert!((m.position() - 0.21).abs() < 1e-12);
        for _ in 0..16 {
            m.step(true);
        }
        assert!((m.position() - 0.4).abs() < 1e-12);
    }

    #[test]
    fn backlash_lags_after_a_reversal() {
        let e = MotorError {
            backlash: 0.1,
            ..MotorError::default()
        };
        let mut m = MotorTrack::new(e, 0.01, 0.0);
        for _ in 0..100 {
            m.step(true);
        }
        // Moving up: the output trails by half the dead band.
        assert!((m.position() - 0.95).abs() < 1e-9);
        for _ in 0..5 {
            m.step(false);
        }
        // Reversal of 0.05 mm is swallowed by the dead band.
        assert!((m.position() - 0.95).abs() < 1e-9);
        for _ in 0..100 {
            m.step(false);
        }
        assert!((m.position() - (-0.05 + 0.05)).abs() < 1e-9);
    }
}
