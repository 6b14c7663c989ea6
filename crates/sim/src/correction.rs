//! Calibration of the virtual printer through what a real one would offer, and the believed config with the
//! measured values applied:
//! - polar: the Hall-sensor centre scan (`calibrate::scan` over [`crate::hall::HallScanner`] built with the
//!   true arm offsets, magnet placement errors, sensor noise); the measured `arm_zero_offset` and
//!   `arm_lateral_offset` go into the believed config.
//! - SCARA: a printed calibration pattern measured on the bed: the nozzle XY at commanded motor angles on the
//!   true machine plus 0.02 mm (1σ) measurement noise, fitted by `calibrate::scara::identify`; link lengths,
//!   offsets, joint zeros and the coupling go into the believed config.

use crate::error::SimulationError;
use crate::hall::{HallBedConfig, HallScanner};
use crate::machine::Machine;
use calibrate::scan::{ScanParams, scan_centre};
use calibrate::scara::{Measurement, ScaraGeometry, identify};
use config::MachineConfig;
use kinematics::{MachineParams, PolarParams, ScaraFrame, ScaraParams};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::f64::consts::{PI, TAU};

/// One corrected parameter: believed before, measured, true value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CorrectedValue {
    pub name: String,
    pub believed: f64,
    pub measured: f64,
    pub actual: f64,
}

/// What the calibration measured and applied.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CorrectionSummary {
    pub method: String,
    pub values: Vec<CorrectedValue>,
    /// Fit quality: RMS residual (mm).
    pub rms: f64,
}

/// Calibrate on the true machine and return the believed config with the measured values applied.
pub fn calibrate_and_correct(
    believed: &MachineConfig,
    actual: &Machine,
    seed: u64,
) -> Result<(MachineConfig, CorrectionSummary), SimulationError> {
    let (params, summary) = match (&believed.params, actual.params()) {
        (MachineParams::Polar(b), MachineParams::Polar(a)) => {
            let (p, s) = correct_polar(b, a, actual, seed)?;
            (MachineParams::Polar(p), s)
        }
        (MachineParams::Scara(b), MachineParams::Scara(a)) => {
            let (p, s) = correct_scara(b, a, actual, seed)?;
            (MachineParams::Scara(p), s)
        }
        _ => {
            return Err(SimulationError::Calibration(
                "automatic calibration exists for polar and SCARA machines of the same kind".into(),
            ));
        }
    };
    let mut corrected = believed.clone();
    corrected.params = params;
    Ok((corrected, summary))
}

fn correct_polar(
    believed: &PolarParams,
    truth: &PolarParams,
    actual: &Machine,
    seed: u64,
) -> Result<(PolarParams, CorrectionSummary), SimulationError> {
    let motors = actual.motor_errors();
    let microstep_error = motors
        .iter()
        .take(2)
        .map(|m| m.microstep_error)
        .fold(0.0, f64::max);
    let hw_cfg = HallBedConfig {
        arm_zero_offset: truth.arm_zero_offset,
        arm_lateral_offset: truth.arm_lateral_offset,
        arm_steps_per_mm: 1.0 / truth.arm.step_distance,
        bed_steps_per_rev: TAU / truth.bed.step_distance,
        microsteps: motors.get(1).map_or(16, |m| m.microsteps),
        microstep_error,
        seed,
        ..HallBedConfig::default()
    };
    let mut hw =
        HallScanner::new(hw_cfg).map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let result = scan_centre(&mut hw, &ScanParams::default())
        .map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let corrected = PolarParams {
        arm_zero_offset: result.arm_zero_offset,
        arm_lateral_offset: result.arm_lateral_offset,
        ..believed.clone()
    };
    let rms = result.ring.as_ref().map_or(0.0, |r| r.rms);
    let summary = CorrectionSummary {
        method: format!(
            "Hall-sensor centre scan: {} of {} magnet pairs, {} sensor reads, {:.0} s of machine time",
            result.pairs_used, result.magnet_count, result.sensor_reads, result.scan_time
        ),
        values: vec![
            value(
                "arm_zero_offset",
                believed.arm_zero_offset,
                result.arm_zero_offset,
                truth.arm_zero_offset,
            ),
            value(
                "arm_lateral_offset",
                believed.arm_lateral_offset,
                result.arm_lateral_offset,
                truth.arm_lateral_offset,
            ),
        ],
        rms,
    };
    Ok((corrected, summary))
}

fn value(name: &str, believed: f64, measured: f64, actual: f64) -> CorrectedValue {
    CorrectedValue {
        name: name.to_string(),
        believed,
        measured,
        actual,
    }
}

/// Motor angles of an 11×11 grid of joint poses (q1 90° ± 60°, q2 40°…130°) on the believed machine.
fn calibration_poses(g: &ScaraGeometry) -> Vec<(f64, f64)> {
    let mut poses = Vec::new();
    for i in 0..11 {
        let q1 = (-60.0 + 12.0 * f64::from(i)).to_radians() + 0.5 * PI;
        for k in 0..11 {
            let q2 = (40.0 + 9.0 * f64::from(k)).to_radians();
            poses.push((
                q1 + g.shoulder_zero,
                q2 + g.elbow_coupling * q1 + g.elbow_zero,
            ));
        }
    }
    poses
}

/// Standard deviation of the simulated pattern measurement (mm).
pub const PATTERN_NOISE: f64 = 0.02;

fn correct_scara(
    believed: &ScaraParams,
    truth: &ScaraParams,
    actual: &Machine,
    seed: u64,
) -> Result<(ScaraParams, CorrectionSummary), SimulationError> {
    if believed.frame != ScaraFrame::Standard || truth.frame != ScaraFrame::Standard {
        return Err(SimulationError::Calibration(
            "SCARA identification runs in the standard frame; X-SCARA frame machines are not supported".into(),
        ));
    }
    let start = ScaraGeometry::from(believed);
    let mut rng = StdRng::seed_from_u64(seed);
    let noise =
        Normal::new(0.0, PATTERN_NOISE).map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let scale: Vec<f64> = actual
        .motor_errors()
        .iter()
        .map(|m| 1.0 + m.scale_error)
        .collect();
    let mut data = Vec::new();
    for (line, (a, b)) in calibration_poses(&start).into_iter().enumerate() {
        let motors = [a * scale[0], b * scale[1], 0.0];
        let p = actual
            .kinematics()
            .forward(&motors)
            .map_err(|e| SimulationError::Calibration(e.to_string()))?;
        data.push(Measurement {
            motor_a: a,
            motor_b: b,
            x: p[0] + noise.sample(&mut rng),
            y: p[1] + noise.sample(&mut rng),
            line: line + 1,
        });
    }
    let fit = identify(&data, &start).map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let g = fit.geometry;
    let corrected = ScaraParams {
        link1_length: g.link1_length,
        link2_length: g.link2_length,
        offset_x: g.offset_x,
        offset_y: g.offset_y,
        shoulder_zero: g.shoulder_zero,
        elbow_zero: g.elbow_zero,
        elbow_coupling: g.elbow_coupling,
        ecr: None,
        ..believed.clone()
    };
    let t = ScaraGeometry::from(truth);
    let names = calibrate::scara::PARAM_NAMES;
    let values = names
        .iter()
        .zip(start.to_array())
        .zip(g.to_array())
        .zip(t.to_array())
        .map(|(((n, b), m), a)| value(n, b, m, a))
        .collect();
    let summary = CorrectionSummary {
        method: format!(
            "SCARA identification from {} measured pattern crosses ({PATTERN_NOISE} mm noise)",
            data.len()
        ),
        values,
        rms: fit.rms,
    };
    Ok((corrected, summary))
}
