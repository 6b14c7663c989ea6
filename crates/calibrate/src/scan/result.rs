//! What a scan finds: each magnet's detections, the fitted offsets with their uncertainty, the magnet map;
//! written and read as pretty JSON (`centre.json`, what `convert --calibration` takes).

use super::error::ScanError;
use super::params::PeakMethod;
use crate::circle::{self, CircleFit, Point};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One peaked magnet: arm and bed readings at its centre and the peak field.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub r: f64,
    pub theta: f64,
    pub peak: f64,
}

/// Everything the scan learned about one magnet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MagnetRecord {
    pub index: usize,
    pub near: Option<Detection>,
    pub far: Option<Detection>,
    /// (dx, dy) from this magnet's near/far pair alone.
    pub pair_offset: Option<[f64; 2]>,
    /// Whether the pair passed the robust screen and went into the result.
    pub used: bool,
    /// Position in the bed frame with the fitted offsets (mean of both sides).
    pub position: Option<Point>,
    /// Distance to the ring circle minus its radius (mm).
    pub ring_residual: Option<f64>,
}

/// The scan result, ready to apply as config values (`arm_zero_offset`, `arm_lateral_offset`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CentreResult {
    /// `dx`: arm zero relative to the rotation centre, along the arm (mm).
    pub arm_zero_offset: f64,
    /// `dy`: sideways offset of the arm's line from the rotation centre (mm).
    pub arm_lateral_offset: f64,
    /// Standard errors (mm): the scan's own scatter and the sensor's alignment to the nozzle, which the scan
    /// cannot observe ([`ScanParams::sensor_alignment`]).
    pub sigma_arm_zero_offset: f64,
    pub sigma_arm_lateral_offset: f64,
    /// Covariance of (dx, dy) (mm²), both parts.
    pub covariance: [[f64; 2]; 2],
    /// The scan's own part of the standard errors (scatter of the magnet pairs), mm.
    #[serde(default)]
    pub sigma_scan: [f64; 2],
    /// The sensor-alignment part (1σ per direction, mm).
    #[serde(default)]
    pub sensor_alignment: f64,
    /// What looked wrong and was left out or should be checked: magnets missing or seen on one side only, pairs
    /// off the others (moved or wrong magnets), peaks unlike the others, magnets off the ring.
    #[serde(default)]
    pub flags: Vec<String>,
    pub magnet_count: usize,
    /// Magnets seen on at least one side.
    pub detected: usize,
    /// Pairs used in the result after the robust screen.
    pub pairs_used: usize,
    pub magnets: Vec<MagnetRecord>,
    /// Robust circle fit of the magnet map (ring eccentricity about the rotation axis, radius, residuals).
    pub ring: Option<CircleFit>,
    /// Centroid of the magnet map (equals the ring centre for equally spaced magnets).
    pub map_centroid: Option<Point>,
    /// Time the commanded motion and readings take on the machine (s), from trapezoidal moves.
    pub scan_time: f64,
    pub sensor_reads: usize,
    pub method: PeakMethod,
    /// The sensor's tilt measured by a second scan higher up and removed from the offsets above
    /// ([`super::remove_tilt`]); `None` for a single scan, whose offsets carry any tilt's bias.
    #[serde(default)]
    pub tilt: Option<TiltCorrection>,
}

/// Plain data for a picture of the magnet map: points, the fitted ring, residual vectors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MagnetMapPlot {
    /// Magnet positions in the bed frame (mm).
    pub points: Vec<Point>,
    /// Whether each point was an outlier of the ring fit.
    pub outlier: Vec<bool>,
    /// Fitted ring, if there were enough magnets.
    pub ring: Option<circle::Circle>,
    /// Radial residual vectors (from the ring to each point, mm; scale them up to draw).
    pub residual_vectors: Vec<[f64; 2]>,
    /// The rotation centre in the bed frame (always the origin) and the ring centre.
    pub rotation_centre: Point,
}

impl CentreResult {
    /// Data for the magnet-map plot.
    pub fn plot_data(&self) -> MagnetMapPlot {
        let entries: Vec<(usize, Point)> = self
            .magnets
            .iter()
            .filter_map(|m| m.position.map(|p| (m.index, p)))
            .collect();
        let points: Vec<Point> = entries.iter().map(|e| e.1).collect();
        let ring = self.ring.as_ref().map(|f| f.circle);
        let outlier = (0..points.len())
            .map(|i| self.ring.as_ref().is_some_and(|f| f.outliers.contains(&i)))
            .collect();
        let residual_vectors = points
            .iter()
            .map(|p| match ring {
                Some(c) => {
                    let (ux, uy) = (p[0] - c.cx, p[1] - c.cy);
                    let d = ux.hypot(uy);
                    if d > 0.0 {
                        let res = d - c.r;
                        [res * ux / d, res * uy / d]
                    } else {
                        [0.0, 0.0]
                    }
                }
                None => [0.0, 0.0],
            })
            .collect();
        MagnetMapPlot {
            points,
            outlier,
            ring,
            residual_vectors,
            rotation_centre: [0.0, 0.0],
        }
    }

    /// Write as pretty JSON through a temporary file renamed into place.
    pub fn write_json(&self, path: &Path) -> Result<(), ScanError> {
        let file_err = |e: &dyn std::fmt::Display| file_error(path, e);
        let text = serde_json::to_string_pretty(self).map_err(|e| file_err(&e))?;
        let tmp = path.with_extension("json.tmp");
        std::fs::write(&tmp, text).map_err(|e| file_err(&e))?;
        std::fs::rename(&tmp, path).map_err(|e| file_err(&e))
    }

    /// Read a result written by [`CentreResult::write_json`].
    pub fn read_json(path: &Path) -> Result<Self, ScanError> {
        let file_err = |e: &dyn std::fmt::Display| file_error(path, e);
        let text = std::fs::read_to_string(path).map_err(|e| file_err(&e))?;
        serde_json::from_str(&text).map_err(|e| file_err(&e))
    }
}

/// A result file that could not be read or written, and why.
fn file_error(path: &Path, why: &dyn std::fmt::Display) -> ScanError {
    ScanError::File {
        path: path.display().to_string(),
        message: why.to_string(),
    }
}

/// The offsets with the sensor's tilt removed, and what was removed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TiltCorrection {
    /// `dx` and `dy` (mm) with the tilt's bias removed.
    pub arm_zero_offset: f64,
    pub arm_lateral_offset: f64,
    /// 1σ of `dx` and `dy` from the two scans' own scatter, carried through the extrapolation (mm).
    pub sigma_scan: [f64; 2],
    /// 1σ with the sensor's mounting alignment added (mm).
    pub sigma: [f64; 2],
    /// The bias the tilt put into the lower scan's `dx`, `dy` (mm), removed.
    pub bias: [f64; 2],
    /// Distance from the sensor to the magnets' centres at the lower scan (mm), from the peak fields.
    pub distance: f64,
    /// How far the nozzle was raised for the second scan (mm).
    pub raise: f64,
    /// The tilt that bias stands for in a dipole's field (degrees, `tan α = 4·|bias| / distance`).
    pub tilt_deg: f64,
}
