//! `JOINTSPACE_SCAN_CENTRE`'s library side: where the sweep's passes go, and what its ADC reports say. The Python
//! command runs the passes, reads every report's arm and bed readings from Klipper's stepper position history
//! and hands them over; this turns them into the magnet detections (`calibrate::sweep`), the detections file
//! `jointspace calibrate centre --scan` reads, and the fit (`calibrate::scan`), or says why the scan is refused.

use std::ffi::c_int;

use calibrate::scan::{
    CentreResult, ScanError, ScanParams, centre_from_detections, write_detections,
};
use calibrate::sweep::{HallAdc, SweepParams, SweepSample, detect};

/// Mirror of `struct jointspace_hall_scan` (`klipper/jointspace_klipper/jointspace.h`): the `[jointspace] hall_*` settings.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HallScanSettings {
    pub magnet_count: c_int,
    pub ring_radius: f64,
    pub max_offset: f64,
    pub pass_pitch: f64,
    pub field_reach: f64,
    pub threshold: f64,
    pub adc_reference: f64,
    pub sensitivity: f64,
    pub saturation: f64,
    /// Largest scatter of the result (mm, 1σ of the scan's own part) that is still stored.
    pub max_sigma: f64,
    /// How well the sensor sits on the nozzle (mm, 1σ): added to the reported uncertainty.
    pub sensor_alignment: f64,
}

impl HallScanSettings {
    pub fn sweep(&self) -> SweepParams {
        SweepParams {
            magnet_count: usize::try_from(self.magnet_count).unwrap_or(0),
            ring_radius: self.ring_radius,
            max_offset: self.max_offset,
            pass_pitch: self.pass_pitch,
            field_reach: self.field_reach,
            detection_threshold: self.threshold,
            adc: HallAdc {
                reference: self.adc_reference,
                sensitivity: self.sensitivity,
                saturation: self.saturation,
            },
        }
    }

    /// The fit's settings: the command line's defaults (so a detections file gives the same result there), with
    /// the printer's magnet count and sensor alignment.
    fn fit(&self) -> ScanParams {
        ScanParams {
            magnet_count: usize::try_from(self.magnet_count).unwrap_or(0),
            ring_radius: self.ring_radius,
            sensor_alignment: self.sensor_alignment,
            ..ScanParams::default()
        }
    }
}

/// A scan that was accepted: the fit and the detections file.
#[derive(Debug, Clone, PartialEq)]
pub struct AcceptedScan {
    pub result: CentreResult,
    pub detections_csv: String,
}

/// The samples as `(pass, arm mm, bed rad, adc 0..1)` rows of four doubles.
pub fn samples_from_rows(rows: &[f64]) -> Result<Vec<SweepSample>, ScanError> {
    rows.chunks_exact(4)
        .enumerate()
        .map(|(i, row)| {
            let pass = row[0];
            if !((0.0..1e6).contains(&pass) && pass.fract() == 0.0) {
                return Err(ScanError::InvalidParams(format!(
                    "sample {i}: pass {pass} is not a pass number"
                )));
            }
            Ok(SweepSample {
                pass: pass as usize,
                arm: row[1],
                bed: row[2],
                adc: row[3],
            })
        })
        .collect()
}

/// Detections, fit and the checks that decide whether the result may be stored.
pub fn scan_centre(
    settings: &HallScanSettings,
    samples: &[SweepSample],
) -> Result<AcceptedScan, ScanError> {
    let slots = detect(&settings.sweep(), samples)?;
    let result = centre_from_detections(&settings.fit(), slots.near, slots.far)?;
    let scatter = result.sigma_scan[0].max(result.sigma_scan[1]);
    // A NaN scatter (never expected) is refused too.
    if scatter.is_nan() || scatter > settings.max_sigma {
        return Err(ScanError::BadFit(format!(
            "the magnet pairs scatter by ±{scatter:.4} mm (more than hall_max_sigma {:.4} mm): loose sensor, \
             backlash or a moving bed?",
            settings.max_sigma
        )));
    }
    let unused = result.magnet_count - result.pairs_used;
    if 4 * unused > result.magnet_count {
        return Err(ScanError::BadFit(format!(
            "{unused} of {} magnet pairs disagree with the others: {}",
            result.magnet_count,
            result.flags.join("; ")
        )));
    }
    Ok(AcceptedScan {
        detections_csv: write_detections(&result),
        result,
    })
}

/// What the command tells the user about an accepted scan.
pub fn summary(result: &CentreResult) -> String {
    let mut text = format!(
        "arm_zero_offset {:+.4} mm (±{:.4}), arm_lateral_offset {:+.4} mm (±{:.4}); {} magnet pairs, \
         scatter ±{:.4} / ±{:.4} mm",
        result.arm_zero_offset,
        result.sigma_arm_zero_offset,
        result.arm_lateral_offset,
        result.sigma_arm_lateral_offset,
        result.pairs_used,
        result.sigma_scan[0],
        result.sigma_scan[1]
    );
    for flag in &result.flags {
        text += &format!("\nwarning: {flag}");
    }
    text
}
