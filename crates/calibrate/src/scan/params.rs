//! The scan's settings: geometry expectations, search steps, motion limits for the time estimate, and the
//! checks that refuse settings a scan cannot work with.

use super::error::ScanError;
use serde::{Deserialize, Serialize};

/// How a magnet's centre is taken from the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum PeakMethod {
    /// Alternating 1-D profiles in θ and R, each fitted with a parabola (sub-step vertex), re-centred.
    #[default]
    Interpolated,
    /// The thesis' method: sample a step grid, take the mean of the step positions where the comparator
    /// fires (`signal ≥ comparator_threshold`). The thesis then averages bed step indices of all detections,
    /// which is no centre at all; here its magnet positions go through the same two-sided geometry so the
    /// comparison isolates the peaking method.
    ThesisAveraging,
}

/// Scan settings: geometry expectations, search steps and the motion limits used for the time estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ScanParams {
    pub magnet_count: usize,
    /// Nominal radius of the magnet ring (mm).
    pub ring_radius: f64,
    /// Arm position outside the bed where the scan starts (mm).
    pub arm_home: f64,
    /// Lowest arm position the machine can reach (mm); must be below `−ring_radius` for the far side.
    pub arm_min: f64,
    /// Largest expected |dx|, |dy| (mm); sizes the far-side search window.
    pub max_offset: f64,
    /// Field that counts as "magnet here" during the search (T).
    pub detection_threshold: f64,
    /// Comparator level for `ThesisAveraging` (T).
    pub comparator_threshold: f64,
    /// Search grid step (mm along the arm and along the bed arc).
    pub coarse_step: f64,
    /// Profile sampling step for peaking (mm).
    pub fine_step: f64,
    /// Half width of a peaking profile (mm).
    pub peak_half_width: f64,
    /// Alternations θ/R when peaking.
    pub peak_rounds: usize,
    /// Half width of the `ThesisAveraging` grid (mm); must cover the whole region above the comparator level.
    pub thesis_half_width: f64,
    /// Pairs farther than this from the median offset (mm) are rejected (or 4 robust σ if larger).
    pub pair_tolerance: f64,
    /// Magnet-map points farther than this from the ring circle (mm) are outliers of the ring fit.
    pub ring_tolerance: f64,
    pub arm_speed: f64,
    pub arm_accel: f64,
    pub bed_speed: f64,
    pub bed_accel: f64,
    /// Settling + ADC time per sensor reading (s).
    pub read_time: f64,
    pub method: PeakMethod,
    /// How well the Hall sensor's axis is known to sit on the nozzle (mm, 1σ per direction). The scan finds
    /// where the *sensor* reads each magnet's peak; a sensor mounted beside the nozzle, or tilted by `α` at
    /// height `h` (it then reads a magnet beside it: `h·tan α / 4` in a dipole's field, `h` from the magnet's
    /// centre), shifts `dx` and `dy` by exactly that offset, and no single scan can see it (a second scan higher
    /// up measures a tilt: [`super::remove_tilt`]). It is added to the reported uncertainty.
    pub sensor_alignment: f64,
    /// A magnet whose peak field differs from the ring's median by more than this fraction is flagged (a
    /// wrong, damaged or sunk magnet).
    pub peak_tolerance: f64,
}

impl Default for ScanParams {
    fn default() -> Self {
        Self {
            magnet_count: 16,
            ring_radius: 100.0,
            arm_home: 110.0,
            arm_min: -112.0,
            max_offset: 3.0,
            detection_threshold: 0.010,
            comparator_threshold: 0.025,
            coarse_step: 1.5,
            fine_step: 0.2,
            peak_half_width: 2.4,
            peak_rounds: 2,
            thesis_half_width: 3.6,
            pair_tolerance: 0.05,
            ring_tolerance: 0.5,
            arm_speed: 50.0,
            arm_accel: 1000.0,
            bed_speed: 2.0,
            bed_accel: 20.0,
            read_time: 0.004,
            method: PeakMethod::Interpolated,
            sensor_alignment: 0.05,
            peak_tolerance: 0.2,
        }
    }
}

pub(super) fn validate(p: &ScanParams) -> Result<(), ScanError> {
    let positive = [
        ("ring_radius", p.ring_radius),
        ("coarse_step", p.coarse_step),
        ("fine_step", p.fine_step),
        ("peak_half_width", p.peak_half_width),
        ("thesis_half_width", p.thesis_half_width),
        ("detection_threshold", p.detection_threshold),
        ("comparator_threshold", p.comparator_threshold),
        ("pair_tolerance", p.pair_tolerance),
        ("ring_tolerance", p.ring_tolerance),
        ("arm_speed", p.arm_speed),
        ("arm_accel", p.arm_accel),
        ("bed_speed", p.bed_speed),
        ("bed_accel", p.bed_accel),
    ];
    if let Some((name, v)) = positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
        return Err(ScanError::InvalidParams(format!(
            "{name} must be a positive number, got {v}"
        )));
    }
    if p.magnet_count < 3 {
        return Err(ScanError::InvalidParams(
            "magnet_count must be at least 3".into(),
        ));
    }
    let non_negative = [
        ("max_offset", p.max_offset),
        ("read_time", p.read_time),
        ("sensor_alignment", p.sensor_alignment),
        ("peak_tolerance", p.peak_tolerance),
    ];
    if let Some((name, v)) = non_negative
        .iter()
        .find(|(_, v)| !(v.is_finite() && *v >= 0.0))
    {
        return Err(ScanError::InvalidParams(format!(
            "{name} must be a non-negative number, got {v}"
        )));
    }
    if p.arm_home <= p.ring_radius + p.max_offset {
        return Err(ScanError::InvalidParams(
            "arm_home must lie outside the magnet ring".into(),
        ));
    }
    let far_needed = -(p.ring_radius + 2.0 * p.max_offset + p.peak_half_width);
    if p.arm_min > far_needed {
        return Err(ScanError::InvalidParams(format!(
            "arm_min {} cannot reach the far side of the centre (needs ≤ {far_needed:.1} mm): dx and dy are not \
             separable from a one-sided scan",
            p.arm_min
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sided_machines_are_refused() {
        let p = ScanParams {
            arm_min: -10.0,
            ..ScanParams::default()
        };
        assert!(matches!(validate(&p), Err(ScanError::InvalidParams(_))));
        assert!(validate(&ScanParams::default()).is_ok());
    }
}
