//! The Hall sensor's tilt, measured and removed with a second scan at another height.
//!
//! A sensor tilted by `α` reads the field along its own axis, so it peaks over each magnet beside it, not under
//! it: every peak moves by the same vector in the arm's frame, and `dx`, `dy` with it. For a magnet's dipole far
//! field the move scales with the distance `h` between the sensor and the magnet's centre, exactly (the field of
//! a dipole is the same shape at every scale): `δ(h) = h·u` with `u` set by the tilt (`|u| = tan α / 4` for
//! small tilts). Two scans at distances `h` and `h + Δ` (the nozzle raised by `Δ` between them) measure
//! `d + h·u` and `d + (h + Δ)·u`, so `u` is their difference over `Δ` and the true offsets are the lower scan's
//! less `h·u`. The distance `h` comes from the scans themselves: a dipole's peak field falls as `1/h³`, so the
//! two scans' median peak fields give `h = Δ / ((B_low / B_high)^(1/3) − 1)`.
//!
//! What this cannot remove: a sensor mounted beside the nozzle's axis moves every peak by the same amount at
//! every height, and stays in `sensor_alignment`.

use super::error::ScanError;
use super::result::{CentreResult, TiltCorrection};

/// Median of the peak fields the scan found, both sides of the centre.
fn median_peak(result: &CentreResult) -> Option<f64> {
    let peaks: Vec<f64> = result
        .magnets
        .iter()
        .filter(|m| m.used)
        .flat_map(|m| [m.near, m.far])
        .flatten()
        .map(|d| d.peak.abs())
        .filter(|p| p.is_finite() && *p > 0.0)
        .collect();
    if peaks.is_empty() {
        return None;
    }
    Some(super::median(&peaks))
}

/// The offsets of `low` (a scan at the working height) with the sensor's tilt removed, from `high` (the same
/// scan with the nozzle raised by `raise` mm).
pub fn remove_tilt(
    low: &CentreResult,
    high: &CentreResult,
    raise: f64,
) -> Result<TiltCorrection, ScanError> {
    if !(raise.is_finite() && raise > 0.0) {
        return Err(ScanError::InvalidParams(format!(
            "the second scan's raise must be a positive number of mm, got {raise}"
        )));
    }
    let (Some(b_low), Some(b_high)) = (median_peak(low), median_peak(high)) else {
        return Err(ScanError::BadFit(
            "a scan has no peak fields (a detections file without its peak_mt column?): the sensor's distance \
             to the magnets cannot be found"
                .into(),
        ));
    };
    let ratio = (b_low / b_high).cbrt();
    if ratio.is_nan() || ratio <= 1.0 + 1e-6 {
        return Err(ScanError::BadFit(format!(
            "the raised scan's peaks ({:.2} mT) are not weaker than the lower scan's ({:.2} mT): was the second \
             scan made {raise} mm higher?",
            1e3 * b_high,
            1e3 * b_low
        )));
    }
    let distance = raise / (ratio - 1.0);
    let lower = [low.arm_zero_offset, low.arm_lateral_offset];
    let upper = [high.arm_zero_offset, high.arm_lateral_offset];
    let bias: [f64; 2] = std::array::from_fn(|k| (upper[k] - lower[k]) * distance / raise);
    let gain = distance / raise;
    let sigma_scan: [f64; 2] = std::array::from_fn(|k| {
        ((1.0 + gain) * low.sigma_scan[k]).hypot(gain * high.sigma_scan[k])
    });
    let alignment = low.sensor_alignment;
    Ok(TiltCorrection {
        arm_zero_offset: lower[0] - bias[0],
        arm_lateral_offset: lower[1] - bias[1],
        sigma: sigma_scan.map(|s| s.hypot(alignment)),
        sigma_scan,
        tilt_deg: (4.0 * bias[0].hypot(bias[1]) / distance)
            .atan()
            .to_degrees(),
        bias,
        distance,
        raise,
    })
}

/// `low` with the sensor's tilt removed by `high` (the same ring scanned with the nozzle raised by `raise` mm):
/// its offsets, their uncertainty (the two scans' scatter carried through, the sensor's mounting alignment
/// added; the covariance kept diagonal) and what was removed (`tilt`).
pub fn with_tilt_removed(
    low: CentreResult,
    high: &CentreResult,
    raise: f64,
) -> Result<CentreResult, ScanError> {
    let t = remove_tilt(&low, high, raise)?;
    Ok(CentreResult {
        arm_zero_offset: t.arm_zero_offset,
        arm_lateral_offset: t.arm_lateral_offset,
        sigma_arm_zero_offset: t.sigma[0],
        sigma_arm_lateral_offset: t.sigma[1],
        covariance: [[t.sigma[0].powi(2), 0.0], [0.0, t.sigma[1].powi(2)]],
        sigma_scan: t.sigma_scan,
        tilt: Some(t),
        ..low
    })
}
