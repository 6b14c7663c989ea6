//! The polar centre scan: an algorithm over a small hardware trait that finds every bed magnet with the Hall
//! sensor, peaks each one with sub-step interpolation, and turns the magnet detections into the arm's zero
//! offset `dx` and lateral offset `dy` relative to the bed's rotation centre.
//!
//! # Conventions: the machine's own (`kinematics::polar`, Klipper's polar, what `convert` writes)
//! Machine frame: origin on the bed's rotation axis, +x along the arm. With the arm reading `r` the sensor
//! (aligned with the nozzle) sits at `N(r) = (r + dx, dy)`: `dx` = `arm_zero_offset` (where the arm's zero
//! really is, along the arm), `dy` = `arm_lateral_offset` (sideways offset of the arm's line). The bed angle
//! `θ` is the bed motor's reading with the kinematics' sign: the bed point under the sensor is
//! `p = Rot(θ)·N(r)` (an ideal machine puts bed point `(r cos θ, r sin θ)` under the nozzle, as
//! `kinematics::polar` and Klipper's polar do; `convert` writes this `θ`). So a magnet `m` (bed frame) is
//! under the sensor when `m = Rot(θ)·(r + dx, dy)`: the polar inverse `θ = atan2(m) − atan2(dy, dx + r)`.
//! Physically the bed has turned by `−θ`; logs that record the physical rotation must negate it.
//!
//! # What a scan can observe
//! Seen from one side of the centre only, every magnet gives `(r + dx)² + dy² = ρ²` and an angle that is
//! confounded with the (declared) bed zero: `dx` and `dy` cannot be separated from the unknown magnet
//! radii. The scan therefore peaks every magnet twice, on the near side (`r⁺ ≈ ρ`) and on the far side of
//! the centre (`r⁻ ≈ −ρ`, bed turned by ≈ π). For one magnet, exactly and independently of where it was
//! placed: `dx = −(r⁺ + r⁻)/2`, `h = (r⁺ − r⁻)/2`, `θ⁺ − θ⁻ = π − 2·atan(dy/h)`. The per-magnet pairs are
//! combined robustly (median screen, then mean and covariance). The magnet map (each magnet in the bed frame
//! with the fitted offsets) gets a robust geometric circle fit, which gives the ring's own eccentricity and
//! per-magnet residuals for the plot. The arm must reach `−ρ` (`arm_min`); a machine whose arm passes the
//! centre only a little can use a small inner ring (e.g. 4 magnets at 10 mm, tested), and one whose arm
//! cannot pass the centre at all cannot separate `dx` from the ring radius nor measure `dy` with this
//! sensor: the scan refuses such parameters instead of guessing.

use crate::circle::{self, CircleFit, Point};
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};
use std::path::Path;

/// Failure reported by scan hardware (real or simulated).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct HardwareError(pub String);

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
    /// height `h` (it then reads a magnet `h·tan α` away), shifts `dx` and `dy` by exactly that offset, and no
    /// scan can see it. It is added to the reported uncertainty.
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

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScanError {
    #[error("hardware: {0}")]
    Hardware(#[from] HardwareError),
    #[error("invalid scan parameter: {0}")]
    InvalidParams(String),
    #[error("no magnet found between arm {from:.2} mm and {to:.2} mm")]
    NoMagnetFound { from: f64, to: f64 },
    #[error("only {found} magnets were seen on both sides of the centre; at least 3 are needed")]
    TooFewPairs { found: usize },
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    #[error(
        "the scan recorded no sensor readings (no ADC data: batch mode, or the sensor is not reporting)"
    )]
    NoSamples,
    #[error("the Hall sensor saturates: {0}")]
    Saturated(String),
    #[error("the {side} side of the scan shows {found} magnets, the ring has {expected}")]
    WrongMagnetCount {
        side: String,
        found: usize,
        expected: usize,
    },
    #[error("the magnet at {angle_deg:.1}° on the {side} side cannot be peaked: {why}")]
    BadPeak {
        side: String,
        angle_deg: f64,
        why: String,
    },
    #[error("the fit is poor: {0}")]
    BadFit(String),
    #[error("cannot read or write the result file {path}: {message}")]
    File { path: String, message: String },
}

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
        let file_err = |e: &dyn std::fmt::Display| ScanError::File {
            path: path.display().to_string(),
            message: e.to_string(),
        };
        let text = serde_json::to_string_pretty(self).map_err(|e| file_err(&e))?;
        let tmp = path.with_extension("json.tmp");
        std::fs::write(&tmp, text).map_err(|e| file_err(&e))?;
        std::fs::rename(&tmp, path).map_err(|e| file_err(&e))
    }

    /// Read a result written by [`CentreResult::write_json`].
    pub fn read_json(path: &Path) -> Result<Self, ScanError> {
        let file_err = |e: &dyn std::fmt::Display| ScanError::File {
            path: path.display().to_string(),
            message: e.to_string(),
        };
        let text = std::fs::read_to_string(path).map_err(|e| file_err(&e))?;
        serde_json::from_str(&text).map_err(|e| file_err(&e))
    }
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

fn validate(p: &ScanParams) -> Result<(), ScanError> {
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

/// The scan in progress: hardware, settings, and the motion clock.
struct Scanner<'a, H: ScanHardware> {
    hw: &'a mut H,
    p: &'a ScanParams,
    time: f64,
    reads: usize,
}

impl<H: ScanHardware> Scanner<'_, H> {
    fn go(&mut self, r: f64, theta: f64) -> Result<(), ScanError> {
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
    fn sample(&mut self, r: f64, theta: f64) -> Result<(f64, f64, f64), ScanError> {
        self.go(r, theta)?;
        let b = self.hw.read_sensor()?;
        self.reads += 1;
        self.time += self.p.read_time;
        let (rr, tt) = self.hw.position();
        Ok((rr, tt, b))
    }

    /// Bed angle per mm of arc at arm reading `r` (arc radius ≈ |r|).
    fn rad_per_mm(&self, r: f64) -> f64 {
        1.0 / r.abs().max(0.25 * self.p.ring_radius)
    }

    /// Strongest reading on a grid around (r, θ): `r_half`, `arc_half` half widths (mm), `step` (mm).
    /// Rows alternate direction so the bed does not rewind.
    fn grid_max(
        &mut self,
        r: f64,
        theta: f64,
        r_half: f64,
        arc_half: f64,
        step: f64,
    ) -> Result<(f64, f64, f64), ScanError> {
        let nr = (r_half / step).ceil() as i64;
        let nt = (arc_half / step).ceil() as i64;
        let dth = step * self.rad_per_mm(r);
        let mut best = (r, theta, f64::NEG_INFINITY);
        for (row, i) in (-nr..=nr).enumerate() {
            let rr = r + i as f64 * step;
            for j in -nt..=nt {
                let j = if row % 2 == 0 { j } else { -j };
                let s = self.sample(rr, theta + j as f64 * dth)?;
                if s.2 > best.2 {
                    best = s;
                }
            }
        }
        Ok(best)
    }

    /// The thesis' first search: from outside the bed step the arm inwards; at each arm step sweep the bed
    /// over one magnet spacing until the field exceeds the detection threshold.
    fn find_first(&mut self) -> Result<(f64, f64), ScanError> {
        let p = self.p;
        let spacing = TAU / p.magnet_count as f64;
        let stop = p.ring_radius - 2.0 * p.max_offset - p.peak_half_width;
        let mut r = p.arm_home;
        let mut forward = true;
        while r >= stop {
            let dth = p.coarse_step * self.rad_per_mm(r);
            let n = (spacing / dth).ceil() as i64 + 1;
            for k in 0..=n {
                let theta = if forward {
                    k as f64 * dth
                } else {
                    (n - k) as f64 * dth
                };
                let (rr, tt, b) = self.sample(r, theta)?;
                if b >= p.detection_threshold {
                    return Ok((rr, tt));
                }
            }
            forward = !forward;
            r -= p.coarse_step;
        }
        Err(ScanError::NoMagnetFound {
            from: p.arm_home,
            to: stop,
        })
    }

    /// Coarse grid around a prediction, then the peak; `None` when nothing exceeds the threshold.
    fn locate(&mut self, r: f64, theta: f64, half: f64) -> Result<Option<Detection>, ScanError> {
        let (rr, tt, b) = self.grid_max(r, theta, half, half, self.p.coarse_step)?;
        if b < self.p.detection_threshold {
            return Ok(None);
        }
        self.refine(rr, tt).map(Some)
    }

    fn refine(&mut self, r: f64, theta: f64) -> Result<Detection, ScanError> {
        match self.p.method {
            PeakMethod::Interpolated => self.peak_interpolated(r, theta),
            PeakMethod::ThesisAveraging => self.peak_thesis(r, theta),
        }
    }

    /// Alternate θ and R profiles; each profile's vertex re-centres the next.
    fn peak_interpolated(&mut self, mut r: f64, mut theta: f64) -> Result<Detection, ScanError> {
        let mut peak = 0.0;
        for _ in 0..self.p.peak_rounds.max(1) {
            let (t, _) = self.profile(r, theta, Axis::Bed)?;
            theta = t;
            let (rr, b) = self.profile(r, theta, Axis::Arm)?;
            r = rr;
            peak = b;
        }
        Ok(Detection { r, theta, peak })
    }

    /// One 1-D profile through (r, θ) along `axis`; returns the vertex coordinate and the peak value.
    /// If the vertex falls outside the sampled window the window moves to the best sample and retries.
    fn profile(&mut self, r: f64, theta: f64, axis: Axis) -> Result<(f64, f64), ScanError> {
        let p = self.p;
        let n = (p.peak_half_width / p.fine_step).round().max(2.0) as i64;
        let step = match axis {
            Axis::Arm => p.fine_step,
            Axis::Bed => p.fine_step * self.rad_per_mm(r),
        };
        let mut centre = match axis {
            Axis::Arm => r,
            Axis::Bed => theta,
        };
        for _ in 0..4 {
            let mut xs = Vec::with_capacity(2 * n as usize + 1);
            let mut ys = Vec::with_capacity(2 * n as usize + 1);
            for k in -n..=n {
                let target = centre + k as f64 * step;
                let (rr, tt, b) = match axis {
                    Axis::Arm => self.sample(target, theta)?,
                    Axis::Bed => self.sample(r, target)?,
                };
                xs.push(match axis {
                    Axis::Arm => rr,
                    Axis::Bed => tt,
                });
                ys.push(b);
            }
            let half = n as f64 * step;
            if let Some((x, y)) =
                parabola_vertex(&xs, &ys, centre).filter(|(x, _)| (x - centre).abs() <= 0.5 * half)
            {
                return Ok((x, y));
            }
            let best = ys
                .iter()
                .enumerate()
                .fold(0, |bi, (i, y)| if *y > ys[bi] { i } else { bi });
            centre = xs[best];
        }
        let (rr, tt, b) = self.sample(r, theta)?;
        Ok((if axis == Axis::Arm { rr } else { tt }, b))
    }

    /// Thesis-style peak: step grid over the magnet, mean of the positions where the comparator fires.
    fn peak_thesis(&mut self, r: f64, theta: f64) -> Result<Detection, ScanError> {
        let p = self.p;
        let n = (p.thesis_half_width / p.fine_step).round() as i64;
        let dth = p.fine_step * self.rad_per_mm(r);
        let (mut sr, mut st, mut count, mut peak) = (0.0, 0.0, 0usize, 0.0f64);
        for (row, i) in (-n..=n).enumerate() {
            for j in -n..=n {
                let j = if row % 2 == 0 { j } else { -j };
                let (rr, tt, b) =
                    self.sample(r + i as f64 * p.fine_step, theta + j as f64 * dth)?;
                if b >= p.comparator_threshold {
                    sr += rr;
                    st += tt;
                    count += 1;
                    peak = peak.max(b);
                }
            }
        }
        if count == 0 {
            return Ok(Detection {
                r,
                theta,
                peak: 0.0,
            });
        }
        Ok(Detection {
            r: sr / count as f64,
            theta: st / count as f64,
            peak,
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Axis {
    Arm,
    Bed,
}

/// Least-squares parabola through (x, y) in coordinates relative to `origin`; its vertex if it is a maximum.
pub(crate) fn parabola_vertex(xs: &[f64], ys: &[f64], origin: f64) -> Option<(f64, f64)> {
    let mut ata = nalgebra::Matrix3::zeros();
    let mut atb = nalgebra::Vector3::zeros();
    for (x, y) in xs.iter().zip(ys) {
        let u = x - origin;
        let row = nalgebra::Vector3::new(u * u, u, 1.0);
        ata += row * row.transpose();
        atb += row * *y;
    }
    let s = ata.lu().solve(&atb)?;
    let (a, b, c) = (s[0], s[1], s[2]);
    if a.is_nan() || a >= 0.0 {
        return None;
    }
    let u = -b / (2.0 * a);
    let v = c - b * b / (4.0 * a);
    (u.is_finite() && v.is_finite()).then_some((origin + u, v))
}

/// Offsets from one magnet seen on both sides (exact for any magnet placement). With `h = (r⁺ − r⁻)/2` the
/// sensor is at `(h, dy)` on the near side and `(−h, dy)` on the far side, and the magnet's bed angle is
/// `θ⁺ + atan(dy/h) = θ⁻ + π − atan(dy/h)`: `θ⁺ − θ⁻ = π − 2·atan(dy/h)`.
pub fn pair_offsets(near: &Detection, far: &Detection) -> [f64; 2] {
    let dx = -0.5 * (near.r + far.r);
    let h = 0.5 * (near.r - far.r);
    let delta = PI - (near.theta - far.theta).rem_euclid(TAU);
    [dx, h * (0.5 * delta).tan()]
}

/// What a scan found wrong with the ring (see [`CentreResult::flags`]).
fn flags(
    params: &ScanParams,
    magnets: &[MagnetRecord],
    median_offset: [f64; 2],
    ring: Option<&CircleFit>,
) -> Vec<String> {
    let mut flags = Vec::new();
    for m in magnets {
        let k = m.index;
        match (m.near, m.far, m.pair_offset) {
            (None, None, _) => flags.push(format!("magnet {k} was not found (missing?)")),
            (Some(_), None, _) => flags.push(format!(
                "magnet {k} was seen on the near side only: not used"
            )),
            (None, Some(_), _) => flags.push(format!(
                "magnet {k} was seen on the far side only: not used"
            )),
            (_, _, Some(p)) if !m.used => flags.push(format!(
                "magnet {k}'s pair gives dx {:+.4}, dy {:+.4} mm, {:.4} mm from the others' median: not used \
                 (moved between the two sides, or not a magnet of the ring)",
                p[0],
                p[1],
                (p[0] - median_offset[0]).hypot(p[1] - median_offset[1])
            )),
            _ => {}
        }
    }
    let peaks: Vec<(usize, f64)> = magnets
        .iter()
        .flat_map(|m| {
            m.near
                .iter()
                .chain(m.far.iter())
                .map(move |d| (m.index, d.peak))
        })
        .filter(|(_, p)| *p != 0.0)
        .collect();
    if peaks.len() >= 3 {
        let typical = median(&peaks.iter().map(|p| p.1).collect::<Vec<_>>());
        let mut flagged = Vec::new();
        for (k, peak) in peaks {
            if (peak - typical).abs() > params.peak_tolerance * typical.abs()
                && !flagged.contains(&k)
            {
                flagged.push(k);
                flags.push(format!(
                    "magnet {k} peaks at {:.1} mT against the ring's {:.1} mT (a different, damaged or sunk \
                     magnet?)",
                    peak * 1e3,
                    typical * 1e3
                ));
            }
        }
    }
    if let Some(fit) = ring {
        let placed: Vec<&MagnetRecord> = magnets.iter().filter(|m| m.position.is_some()).collect();
        for &i in &fit.outliers {
            if let Some(m) = placed.get(i)
                && let Some(residual) = m.ring_residual
            {
                flags.push(format!(
                    "magnet {} is {:.3} mm off the ring (placement; dx and dy do not depend on it)",
                    m.index,
                    residual.abs()
                ));
            }
        }
    }
    flags
}

/// Median of a non-empty slice.
pub(crate) fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Run the centre scan on `hw`. See the module docs for the geometry and conventions.
pub fn scan_centre<H: ScanHardware>(
    hw: &mut H,
    params: &ScanParams,
) -> Result<CentreResult, ScanError> {
    validate(params)?;
    let mut s = Scanner {
        hw,
        p: params,
        time: 0.0,
        reads: 0,
    };
    let n = params.magnet_count;
    let spacing = TAU / n as f64;
    s.go(params.arm_home, 0.0)?;

    let (r_hit, t_hit) = s.find_first()?;
    let first = s.refine(r_hit, t_hit)?;
    let window = 2.0 * params.coarse_step;
    let mut near: Vec<Option<Detection>> = vec![None; n];
    near[0] = Some(first);
    let mut last_r = first.r;
    for (k, slot) in near.iter_mut().enumerate().skip(1) {
        let found = s.locate(last_r, first.theta + k as f64 * spacing, window)?;
        if let Some(d) = found {
            last_r = d.r;
        }
        *slot = found;
    }

    let far = scan_far_side(&mut s, &near)?;
    let (time, reads) = (s.time, s.reads);
    assemble(params, near, far, time, reads)
}

/// Visit every near-side magnet again on the far side of the centre (bed turned by ≈ π, arm at ≈ −r⁺).
fn scan_far_side<H: ScanHardware>(
    s: &mut Scanner<'_, H>,
    near: &[Option<Detection>],
) -> Result<Vec<Option<Detection>>, ScanError> {
    let p = s.p;
    let n = near.len();
    let mut far: Vec<Option<Detection>> = vec![None; n];
    // Visit in increasing unwrapped bed angle from where the bed is now.
    let (_, now) = s.hw.position();
    let mut order: Vec<(usize, f64)> = near
        .iter()
        .enumerate()
        .filter_map(|(k, d)| d.map(|d| (k, d.theta + PI)))
        .map(|(k, t)| (k, t + ((now - t) / TAU).ceil().max(0.0) * TAU))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut estimate: Option<[f64; 2]> = None;
    let wide = 2.0 * p.max_offset + p.coarse_step;
    for (k, target) in order {
        let Some(nd) = near[k] else { continue };
        let turn = target - (nd.theta + PI);
        let found = match estimate {
            None => s.locate(-nd.r, target, wide)?,
            Some([dx, dy]) => {
                let h = nd.r + dx;
                let r_pred = -nd.r - 2.0 * dx;
                let t_pred = nd.theta + PI + 2.0 * (dy / h).atan() + turn;
                s.locate(r_pred, t_pred, 2.0 * p.coarse_step)?
            }
        };
        if let Some(fd) = found {
            let d = Detection {
                theta: fd.theta - turn,
                ..fd
            };
            if estimate.is_none() {
                estimate = Some(pair_offsets(&nd, &d));
            }
            far[k] = Some(d);
        }
    }
    Ok(far)
}

/// Fit the offsets from recorded detections (e.g. a scan file): `near[k]` and `far[k]` are magnet `k` seen
/// on the near and far side. Uses `pair_tolerance`, `ring_tolerance` and `method` (recorded only) from
/// `params`; the scan time and read count are zero.
pub fn centre_from_detections(
    params: &ScanParams,
    near: Vec<Option<Detection>>,
    far: Vec<Option<Detection>>,
) -> Result<CentreResult, ScanError> {
    if near.len() != far.len() {
        return Err(ScanError::InvalidParams(format!(
            "{} near-side and {} far-side magnet slots",
            near.len(),
            far.len()
        )));
    }
    let p = ScanParams {
        magnet_count: near.len(),
        ..params.clone()
    };
    assemble(&p, near, far, 0.0, 0)
}

/// The header of a detections file.
pub const DETECTIONS_HEADER: [&str; 4] = ["magnet", "side", "arm_mm", "bed_deg"];

/// Parse a detections file: `#` comments, blank lines skipped, a header `magnet,side,arm_mm,bed_deg`, then
/// one detection per line (`magnet` a 0-based index, `side` `near` or `far`, the arm reading in mm and the
/// unwrapped bed motor reading in degrees at the magnet's centre, in the kinematics' sign: see the module
/// documentation). Returns (near, far) slots per magnet index.
/// Errors carry `file:line:column`.
pub fn parse_detections(text: &str, file: &str) -> Result<DetectionSlots, ScanError> {
    let located = |e: crate::csv::CsvError| ScanError::Parse {
        file: file.to_string(),
        line: e.line,
        column: e.column,
        message: e.message,
    };
    let mut rows: Vec<(usize, bool, Detection)> = Vec::new();
    for row in crate::csv::data_rows(text, &DETECTIONS_HEADER).map_err(located)? {
        let magnet_text = row.fields[0].1;
        let magnet: usize = magnet_text
            .parse()
            .ok()
            .filter(|&m: &usize| m < 10_000)
            .ok_or_else(|| {
                located(row.error_at(0, format!("`{magnet_text}` is not a magnet index")))
            })?;
        let side = row.fields[1].1;
        let far = match side.to_ascii_lowercase().as_str() {
            "near" => false,
            "far" => true,
            _ => {
                return Err(located(
                    row.error_at(1, format!("side `{side}` should be `near` or `far`")),
                ));
            }
        };
        let r = row.number(2).map_err(located)?;
        let theta = row.number(3).map_err(located)?;
        if rows.iter().any(|r| r.0 == magnet && r.1 == far) {
            return Err(located(
                row.error_at(0, format!("magnet {magnet} {side} given twice")),
            ));
        }
        rows.push((
            magnet,
            far,
            Detection {
                r,
                theta: theta.to_radians(),
                peak: 0.0,
            },
        ));
    }
    let n = rows.iter().map(|r| r.0 + 1).max().unwrap_or(0);
    let mut slots = DetectionSlots {
        near: vec![None; n],
        far: vec![None; n],
    };
    for (k, far, d) in rows {
        if far {
            slots.far[k] = Some(d);
        } else {
            slots.near[k] = Some(d);
        }
    }
    Ok(slots)
}

/// The header comment of a detections file written by [`write_detections`]: what each column means and which
/// sign the bed angle has.
pub const DETECTIONS_PREAMBLE: &str = "\
# jointspace centre scan: each magnet's centre as the Hall sensor peaked it, on the near and the far side
# of the bed's rotation centre.
# arm_mm: the arm's reading (mm from its zero). bed_deg: the bed motor's reading (degrees, unwrapped) in the
# machine's sign, as Klipper's polar kinematics and `jointspace convert` use it: an ideal machine has bed
# point (r*cos(bed), r*sin(bed)) under the nozzle. The bed itself has turned by -bed_deg.
";

/// A detections file (see [`parse_detections`]) of a scan's result: the preamble, the header, and one line per
/// detection with every digit of the readings.
pub fn write_detections(result: &CentreResult) -> String {
    let mut text = String::from(DETECTIONS_PREAMBLE);
    text += &DETECTIONS_HEADER.join(",");
    text.push('\n');
    for m in &result.magnets {
        for (side, d) in [("near", m.near), ("far", m.far)] {
            if let Some(d) = d {
                text += &format!("{},{side},{},{}\n", m.index, d.r, d.theta.to_degrees());
            }
        }
    }
    text
}

/// Detections per magnet index, near and far side.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct DetectionSlots {
    pub near: Vec<Option<Detection>>,
    pub far: Vec<Option<Detection>>,
}

/// Combine the pairs robustly and build the magnet map and the result.
fn assemble(
    params: &ScanParams,
    near: Vec<Option<Detection>>,
    far: Vec<Option<Detection>>,
    scan_time: f64,
    sensor_reads: usize,
) -> Result<CentreResult, ScanError> {
    let mut magnets: Vec<MagnetRecord> = near
        .iter()
        .zip(&far)
        .enumerate()
        .map(|(index, (n, f))| MagnetRecord {
            index,
            near: *n,
            far: *f,
            pair_offset: n.zip(*f).map(|(a, b)| pair_offsets(&a, &b)),
            used: false,
            position: None,
            ring_residual: None,
        })
        .collect();
    let pairs: Vec<[f64; 2]> = magnets.iter().filter_map(|m| m.pair_offset).collect();
    if pairs.len() < 3 {
        return Err(ScanError::TooFewPairs { found: pairs.len() });
    }
    let med = [
        median(&pairs.iter().map(|p| p[0]).collect::<Vec<_>>()),
        median(&pairs.iter().map(|p| p[1]).collect::<Vec<_>>()),
    ];
    let mad = |axis: usize| {
        1.4826
            * median(
                &pairs
                    .iter()
                    .map(|p| (p[axis] - med[axis]).abs())
                    .collect::<Vec<_>>(),
            )
    };
    let tol = [
        params.pair_tolerance.max(4.0 * mad(0)),
        params.pair_tolerance.max(4.0 * mad(1)),
    ];
    for m in &mut magnets {
        m.used = m
            .pair_offset
            .is_some_and(|p| (p[0] - med[0]).abs() <= tol[0] && (p[1] - med[1]).abs() <= tol[1]);
    }
    let used: Vec<[f64; 2]> = magnets
        .iter()
        .filter(|m| m.used)
        .filter_map(|m| m.pair_offset)
        .collect();
    if used.len() < 3 {
        return Err(ScanError::TooFewPairs { found: used.len() });
    }
    let k = used.len() as f64;
    let mean = [
        used.iter().map(|p| p[0]).sum::<f64>() / k,
        used.iter().map(|p| p[1]).sum::<f64>() / k,
    ];
    let mut cov = [[0.0; 2]; 2];
    for p in &used {
        let d = [p[0] - mean[0], p[1] - mean[1]];
        for a in 0..2 {
            for b in 0..2 {
                // Sample covariance of one pair, divided by k for the covariance of the mean.
                cov[a][b] += d[a] * d[b] / ((k - 1.0) * k);
            }
        }
    }
    let sigma_scan = [cov[0][0].sqrt(), cov[1][1].sqrt()];
    let alignment = params.sensor_alignment * params.sensor_alignment;
    cov[0][0] += alignment;
    cov[1][1] += alignment;
    let [dx, dy] = mean;
    for m in &mut magnets {
        // The bed point under the sensor: Rot(θ)·(r + dx, dy).
        let to_bed = |d: &Detection| -> Point {
            let (x, y) = (d.r + dx, dy);
            let (s, c) = d.theta.sin_cos();
            [c * x - s * y, s * x + c * y]
        };
        let pts: Vec<Point> = m.near.iter().chain(m.far.iter()).map(to_bed).collect();
        if !pts.is_empty() {
            let c = pts.len() as f64;
            m.position = Some([
                pts.iter().map(|p| p[0]).sum::<f64>() / c,
                pts.iter().map(|p| p[1]).sum::<f64>() / c,
            ]);
        }
    }
    let map: Vec<Point> = magnets.iter().filter_map(|m| m.position).collect();
    let ring = circle::robust(&map, params.ring_tolerance).ok();
    if let Some(fit) = &ring {
        for m in &mut magnets {
            m.ring_residual = m.position.map(|p| fit.circle.residual(p));
        }
    }
    let map_centroid = circle::centroid(&map).ok();
    let flags = flags(params, &magnets, med, ring.as_ref());
    Ok(CentreResult {
        arm_zero_offset: dx,
        arm_lateral_offset: dy,
        sigma_arm_zero_offset: cov[0][0].sqrt(),
        sigma_arm_lateral_offset: cov[1][1].sqrt(),
        covariance: cov,
        sigma_scan,
        sensor_alignment: params.sensor_alignment,
        flags,
        magnet_count: params.magnet_count,
        detected: magnets
            .iter()
            .filter(|m| m.near.is_some() || m.far.is_some())
            .count(),
        pairs_used: used.len(),
        magnets,
        ring,
        map_centroid,
        scan_time,
        sensor_reads,
        method: params.method,
    })
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

    #[test]
    fn parabola_vertex_of_exact_parabola() {
        let xs: Vec<f64> = (0..9).map(|i| i as f64 * 0.3).collect();
        let ys: Vec<f64> = xs.iter().map(|x| 5.0 - 2.0 * (x - 1.1).powi(2)).collect();
        let (x, y) = parabola_vertex(&xs, &ys, 1.2).expect("vertex");
        assert!((x - 1.1).abs() < 1e-12 && (y - 5.0).abs() < 1e-12);
        let up: Vec<f64> = xs.iter().map(|x| x * x).collect();
        assert!(parabola_vertex(&xs, &up, 0.0).is_none());
    }

    #[test]
    fn pair_offsets_invert_the_geometry() {
        // Magnet at bed-frame angle α, radius ρ; sensor line offset (dx, dy).
        let (rho, alpha, dx, dy) = (97.3f64, 0.8f64, 1.2f64, -0.7f64);
        let h = (rho * rho - dy * dy).sqrt();
        let near = Detection {
            r: h - dx,
            theta: alpha - dy.atan2(h),
            peak: 0.0,
        };
        let far = Detection {
            r: -h - dx,
            theta: alpha - dy.atan2(-h) + 4.0 * PI,
            peak: 0.0,
        };
        let [ex, ey] = pair_offsets(&near, &far);
        assert!((ex - dx).abs() < 1e-12 && (ey - dy).abs() < 1e-12);
    }

    #[test]
    fn detections_file_parses_and_reports_positions() {
        let text =
            "# scan\nmagnet,side,arm_mm,bed_deg\n0,near,98.5,1.0\n0, far ,-101.5,181.0 # ok\n";
        let slots = parse_detections(text, "d.csv").expect("parse");
        assert_eq!(slots.near.len(), 1);
        assert!(slots.far[0].is_some_and(|d| d.r == -101.5));
        let bad = "magnet,side,arm_mm,bed_deg\n0,middle,1,2\n";
        assert_eq!(
            parse_detections(bad, "d.csv"),
            Err(ScanError::Parse {
                file: "d.csv".into(),
                line: 2,
                column: 3,
                message: "side `middle` should be `near` or `far`".into()
            })
        );
        let dup = "magnet,side,arm_mm,bed_deg\n0,near,1,2\n0,near,1,2\n";
        assert!(matches!(
            parse_detections(dup, "d.csv"),
            Err(ScanError::Parse { line: 3, .. })
        ));
        let nan = "magnet,side,arm_mm,bed_deg\n0,near,NaN,2\n";
        assert!(matches!(
            parse_detections(nan, "d.csv"),
            Err(ScanError::Parse { column: 8, .. })
        ));
    }

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
