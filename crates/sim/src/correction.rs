//! Calibration of the virtual printer through what a real one would offer, and the believed config with the
//! measured values applied:
//! - polar: the Hall-sensor centre scan (`calibrate::scan` over [`crate::hall::HallScanner`] built with the
//!   true arm offsets, magnet placement errors, sensor noise); the measured `arm_zero_offset` and
//!   `arm_lateral_offset` go into the believed config.
//! - SCARA: the believed machine's calibration pattern (`calibrate::scara::machine_pattern`) printed by the
//!   machine as built and its crosses measured as with calipers (`crate::crosses`: 0.02 mm noise, read to
//!   0.01 mm), fitted by `calibrate::scara::identify_in_frame` and judged by `calibrate::scara::judge` as
//!   `calibrate scara` judges it; a fit judged not trustworthy is not applied (a user would not apply it). Link
//!   lengths, offsets, joint zeros and the coupling go into the believed config.
//! - five-bar: the same with the five-bar's pattern (`calibrate::fivebar::machine_pattern`), fit and verdict;
//!   both sides' base positions, link lengths and zeros go into the believed config.

use crate::crosses::{CALIPERS, print_and_measure, print_and_measure_fivebar};
use crate::error::SimulationError;
use crate::hall::{HallBedConfig, HallScanner};
use crate::machine::Machine;
use calibrate::fivebar::{self, FivebarGeometry};
use calibrate::scan::{ScanParams, scan_centre};
use calibrate::scara::{ScaraGeometry, identify_in_frame, judge};
use calibrate::verdict::Verdict;
use config::MachineConfig;
use kinematics::{FivebarParams, MachineParams, PolarParams, ScaraParams};
use rand::SeedableRng;
use rand::rngs::StdRng;
use serde::Serialize;
use std::f64::consts::TAU;

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
    /// What else the calibration found: the measuring noise it assumed, the fit's verdict, warnings.
    pub notes: Vec<String>,
}

/// Why the simulated calibration gave no corrected machine.
#[derive(Debug)]
pub enum Rejected {
    /// It could not be done (a scan that failed, a pattern the machine cannot print, a fit that did not converge).
    Failed(SimulationError),
    /// It was done, and its fit judged not trustworthy: what it measured, and why it is not applied.
    Untrusted {
        summary: Box<CorrectionSummary>,
        reason: String,
    },
}

impl From<SimulationError> for Rejected {
    fn from(e: SimulationError) -> Self {
        Rejected::Failed(e)
    }
}

impl From<Rejected> for SimulationError {
    fn from(r: Rejected) -> Self {
        match r {
            Rejected::Failed(e) => e,
            Rejected::Untrusted { reason, .. } => SimulationError::Calibration(reason),
        }
    }
}

impl std::fmt::Display for Rejected {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rejected::Failed(e) => write!(f, "{e}"),
            Rejected::Untrusted { reason, .. } => write!(f, "{reason}"),
        }
    }
}

/// Calibrate on the true machine and return the believed config with the measured values applied.
pub fn calibrate_and_correct(
    believed: &MachineConfig,
    actual: &Machine,
    seed: u64,
) -> Result<(MachineConfig, CorrectionSummary), Rejected> {
    let (params, summary) = match (&believed.params, actual.params()) {
        (MachineParams::Polar(b), MachineParams::Polar(a)) => {
            let (p, s) = correct_polar(b, a, actual, seed)?;
            (MachineParams::Polar(p), s)
        }
        (MachineParams::Scara(b), MachineParams::Scara(a)) => {
            let (p, s) = correct_scara(believed, b, a, actual, seed)?;
            (MachineParams::Scara(p), s)
        }
        (MachineParams::Fivebar(b), MachineParams::Fivebar(a)) => {
            let (p, s) = correct_fivebar(believed, b, a, actual, seed)?;
            (MachineParams::Fivebar(p), s)
        }
        _ => {
            return Err(Rejected::Failed(SimulationError::Calibration(
                "automatic calibration exists for polar, SCARA and five-bar machines of the same kind".into(),
            )));
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
        notes: Vec::new(),
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

/// Standard deviation of the simulated pattern measurement (mm): calipers, `calibrate scara`'s default method.
pub const PATTERN_NOISE: f64 = CALIPERS.noise;

fn correct_scara(
    believed_config: &MachineConfig,
    believed: &ScaraParams,
    truth: &ScaraParams,
    actual: &Machine,
    seed: u64,
) -> Result<(ScaraParams, CorrectionSummary), Rejected> {
    let mut rng = StdRng::seed_from_u64(seed);
    let measured = print_and_measure(believed_config, actual, CALIPERS, &mut rng)?;
    let (data, frame) = (&measured.data, measured.pattern.frame);
    let start = ScaraGeometry::from(believed);
    let fit = identify_in_frame(data, &start, frame)
        .map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let verdict = judge(data, &fit, &start, frame, CALIPERS.noise);
    let g = fit.geometry;
    let t = ScaraGeometry::from(truth);
    let values = calibrate::scara::PARAM_NAMES
        .iter()
        .zip(start.to_array())
        .zip(g.to_array())
        .zip(t.to_array())
        .map(|(((n, b), m), a)| value(n, b, m, a))
        .collect();
    let summary = pattern_summary("SCARA", data.len(), values, fit.rms, &verdict)?;
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
    Ok((corrected, summary))
}

/// The summary of a calibration from the printed pattern, or the rejection when its verdict is not trustworthy.
fn pattern_summary(
    kind: &str,
    crosses: usize,
    values: Vec<CorrectedValue>,
    rms: f64,
    verdict: &Verdict,
) -> Result<CorrectionSummary, Rejected> {
    let judged = if verdict.trustworthy {
        "trustworthy".to_string()
    } else {
        format!("not trustworthy: {}", verdict.problems.join("; "))
    };
    let summary = CorrectionSummary {
        method: format!(
            "{kind} identification from the {crosses} crosses of the default pattern, printed by the machine as \
             built and measured where their strokes cross"
        ),
        values,
        rms,
        notes: vec![
            format!(
                "crosses measured as with calipers: {} mm noise (1σ per coordinate), read to {} mm",
                CALIPERS.noise, CALIPERS.resolution
            ),
            format!(
                "verdict at {} mm: chi-square {:.1} of at most {:.1} ({} degrees of freedom): {judged}",
                verdict.noise, verdict.chi_square, verdict.chi_square_limit, verdict.dof
            ),
        ],
    };
    if !verdict.trustworthy {
        let reason = format!("the pattern's fit is {judged}; a user would not apply it");
        return Err(Rejected::Untrusted {
            summary: Box::new(summary),
            reason,
        });
    }
    Ok(summary)
}

/// A five-bar calibrated from its printed pattern: both sides' base positions, link lengths and zeros.
fn correct_fivebar(
    believed_config: &MachineConfig,
    believed: &FivebarParams,
    truth: &FivebarParams,
    actual: &Machine,
    seed: u64,
) -> Result<(FivebarParams, CorrectionSummary), Rejected> {
    let mut rng = StdRng::seed_from_u64(seed);
    let (_, data) = print_and_measure_fivebar(believed_config, actual, CALIPERS, &mut rng)?;
    let start = FivebarGeometry::from(believed);
    let fit = fivebar::identify(&data, &start)
        .map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let verdict = fivebar::judge(&data, &fit, &start, CALIPERS.noise);
    let g = fit.geometry;
    let values = fivebar::PARAM_NAMES
        .iter()
        .zip(start.to_array())
        .zip(g.to_array())
        .zip(FivebarGeometry::from(truth).to_array())
        .map(|(((n, b), m), a)| value(n, b, m, a))
        .collect();
    let summary = pattern_summary("five-bar", data.len(), values, fit.rms, &verdict)?;
    let mut corrected = believed.clone();
    for (arm, side) in [
        (&mut corrected.left, g.left),
        (&mut corrected.right, g.right),
    ] {
        arm.base = side.base;
        arm.proximal = side.proximal;
        arm.distal = side.distal;
        arm.zero = side.zero;
    }
    Ok((corrected, summary))
}
