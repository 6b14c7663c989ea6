//! SCARA geometry identification: a parametric forward model with its analytic Jacobian, a Levenberg–Marquardt
//! fit of `L1, L2, offset_x, offset_y, shoulder_zero, elbow_zero, coupling` to measured nozzle XY at commanded
//! motor angles, identifiability analysis (scaled-Jacobian singular values), greedy D-optimal pose selection,
//! the measurement CSV reader and the G-code of a printable calibration pattern.
//!
//! Model (standard frame, angles from +X counter-clockwise, as `kinematics::ScaraParams`):
//! `q1 = a − shoulder_zero`, `q2 = b − elbow_zero − c·q1`,
//! `x = L1·cos q1 + L2·cos(q1+q2) + offset_x`, `y = L1·sin q1 + L2·sin(q1+q2) + offset_y`
//! (a, b: motor angles; c: elbow coupling, `1/ECR` on FEKT-SCARA).
//!
//! Gauge: the measurement frame is the bed frame. Its origin fixes the offsets and its orientation fixes the
//! base rotation, which is therefore not a separate parameter: a rotated base shows up as `shoulder_zero`
//! (the two are not separable, REFERENCE §4). Measurements must be taken in the standard frame; data in
//! the X-SCARA frame (`kinematics::ScaraFrame::XScara`, the standard frame with x and y swapped) is used by
//! swapping the `x_mm` and `y_mm` columns (and swapping the fitted offsets back).
//!
//! Identifiability in practice: a fixed shoulder leaves `L1`, the offsets, `shoulder_zero` and the coupling
//! mixed (3 null combinations); a fixed elbow joint makes the arm rigid (2 null combinations); a fixed elbow
//! *motor* is identifiable but poorly conditioned.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

/// Parameter names in vector order.
pub const PARAM_NAMES: [&str; 7] = [
    "link1_length",
    "link2_length",
    "offset_x",
    "offset_y",
    "shoulder_zero",
    "elbow_zero",
    "elbow_coupling",
];

/// The identified quantities (mm, rad, dimensionless coupling).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScaraGeometry {
    pub link1_length: f64,
    pub link2_length: f64,
    pub offset_x: f64,
    pub offset_y: f64,
    pub shoulder_zero: f64,
    pub elbow_zero: f64,
    pub elbow_coupling: f64,
}

impl From<&kinematics::ScaraParams> for ScaraGeometry {
    /// A configured machine's nominal geometry, in the identification's terms.
    fn from(p: &kinematics::ScaraParams) -> Self {
        ScaraGeometry {
            link1_length: p.link1_length,
            link2_length: p.link2_length,
            offset_x: p.offset_x,
            offset_y: p.offset_y,
            shoulder_zero: p.shoulder_zero,
            elbow_zero: p.elbow_zero,
            elbow_coupling: p.elbow_coupling,
        }
    }
}

impl ScaraGeometry {
    /// FEKT-SCARA nominal: 100/100 mm arms, ECR 3, no offsets.
    pub fn fekt() -> Self {
        Self {
            link1_length: 100.0,
            link2_length: 100.0,
            offset_x: 0.0,
            offset_y: 0.0,
            shoulder_zero: 0.0,
            elbow_zero: 0.0,
            elbow_coupling: 1.0 / 3.0,
        }
    }

    pub fn to_array(&self) -> [f64; 7] {
        [
            self.link1_length,
            self.link2_length,
            self.offset_x,
            self.offset_y,
            self.shoulder_zero,
            self.elbow_zero,
            self.elbow_coupling,
        ]
    }

    pub fn from_array(v: [f64; 7]) -> Self {
        Self {
            link1_length: v[0],
            link2_length: v[1],
            offset_x: v[2],
            offset_y: v[3],
            shoulder_zero: v[4],
            elbow_zero: v[5],
            elbow_coupling: v[6],
        }
    }

    /// Joint angles (q1, q2) from motor angles (a, b).
    pub fn joints(&self, a: f64, b: f64) -> (f64, f64) {
        let q1 = a - self.shoulder_zero;
        (q1, b - self.elbow_zero - self.elbow_coupling * q1)
    }

    /// Nozzle XY (mm) at motor angles (a, b) in rad.
    pub fn forward(&self, a: f64, b: f64) -> [f64; 2] {
        let (q1, q2) = self.joints(a, b);
        let phi = q1 + q2;
        [
            self.link1_length * q1.cos() + self.link2_length * phi.cos() + self.offset_x,
            self.link1_length * q1.sin() + self.link2_length * phi.sin() + self.offset_y,
        ]
    }

    /// ∂(x, y)/∂(parameters) at motor angles (a, b): rows x and y, columns in [`PARAM_NAMES`] order.
    pub fn parameter_jacobian(&self, a: f64, b: f64) -> [[f64; 7]; 2] {
        let (q1, q2) = self.joints(a, b);
        let phi = q1 + q2;
        let (l1, l2, c) = (self.link1_length, self.link2_length, self.elbow_coupling);
        let (s1, c1, sp, cp) = (q1.sin(), q1.cos(), phi.sin(), phi.cos());
        // dq1/dz1 = −1, dφ/dz1 = c − 1, dφ/dz2 = −1, dφ/dc = −q1.
        [
            [
                c1,
                cp,
                1.0,
                0.0,
                l1 * s1 + l2 * sp * (1.0 - c),
                l2 * sp,
                l2 * sp * q1,
            ],
            [
                s1,
                sp,
                0.0,
                1.0,
                -l1 * c1 - l2 * cp * (1.0 - c),
                -l2 * cp,
                -l2 * cp * q1,
            ],
        ]
    }
}

/// One measured pose: commanded motor angles (rad) and the nozzle position measured on the bed (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    pub motor_a: f64,
    pub motor_b: f64,
    pub x: f64,
    pub y: f64,
    /// Source line (1-based), 0 when not from a file.
    pub line: usize,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScaraError {
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("{got} measurements give {rows} equations for 7 parameters; need at least 4 poses")]
    TooFewMeasurements { got: usize, rows: usize },
    #[error("the poses cannot identify: {0}")]
    Unidentifiable(String),
    #[error("the fit did not converge: {0}")]
    NoConvergence(String),
    #[error("non-finite value in measurement {index}")]
    NonFinite { index: usize },
}

/// The CSV header this reader expects (angles in degrees, positions in mm).
pub const CSV_HEADER: [&str; 4] = ["motor_a_deg", "motor_b_deg", "x_mm", "y_mm"];

/// Parse measurements: `#` starts a comment (whole line or trailing), blank lines are skipped, the first
/// remaining line is the header `motor_a_deg,motor_b_deg,x_mm,y_mm`, then one pose per line.
/// Errors carry `file:line:column` of the offending field.
pub fn parse_measurements(text: &str, file: &str) -> Result<Vec<Measurement>, ScaraError> {
    let located = |e: crate::csv::CsvError| ScaraError::Parse {
        file: file.to_string(),
        line: e.line,
        column: e.column,
        message: e.message,
    };
    let mut out = Vec::new();
    for row in crate::csv::data_rows(text, &CSV_HEADER).map_err(located)? {
        out.push(Measurement {
            motor_a: row.number(0).map_err(located)?.to_radians(),
            motor_b: row.number(1).map_err(located)?.to_radians(),
            x: row.number(2).map_err(located)?,
            y: row.number(3).map_err(located)?,
            line: row.line,
        });
    }
    Ok(out)
}

/// How well a pose set determines the parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identifiability {
    /// Singular values of the column-normalised Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// Largest over smallest singular value (infinite when a combination is not identified at all).
    pub condition_number: f64,
    /// Parameter combinations the poses cannot determine: right singular vectors with negligible singular
    /// value, as (parameter name, weight) pairs with |weight| ≥ 0.1.
    pub unidentifiable: Vec<Vec<(String, f64)>>,
}

impl Identifiability {
    pub fn is_identifiable(&self) -> bool {
        self.unidentifiable.is_empty()
    }

    /// A readable list of the unidentifiable combinations.
    pub fn describe(&self) -> String {
        self.unidentifiable
            .iter()
            .map(|combo| {
                combo
                    .iter()
                    .map(|(n, w)| format!("{w:+.2}·{n}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// Relative singular value below which a combination counts as not identified.
const NULL_RELATIVE: f64 = 1e-7;

fn stacked_jacobian(g: &ScaraGeometry, poses: &[(f64, f64)]) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(2 * poses.len(), 7);
    for (i, &(a, b)) in poses.iter().enumerate() {
        let rows = g.parameter_jacobian(a, b);
        for (k, row) in rows.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                j[(2 * i + k, c)] = *v;
            }
        }
    }
    j
}

/// Singular values and null combinations of the identification Jacobian at `g` for motor poses (rad).
/// Columns are normalised to unit length first so mm and rad parameters compare fairly.
pub fn analyse_poses(g: &ScaraGeometry, poses: &[(f64, f64)]) -> Identifiability {
    let mut j = stacked_jacobian(g, poses);
    let mut zero_columns = Vec::new();
    for c in 0..7 {
        let norm = j.column(c).norm();
        if norm > 0.0 {
            j.column_mut(c).unscale_mut(norm);
        } else {
            zero_columns.push(c);
        }
    }
    // Pad to at least 7 rows so the SVD yields all 7 right singular vectors.
    if j.nrows() < 7 {
        j = j.resize_vertically(7, 0.0);
    }
    let svd = j.svd(false, true);
    let mut pairs: Vec<(f64, Vec<f64>)> = match &svd.v_t {
        Some(vt) => (0..7)
            .map(|k| (svd.singular_values[k], vt.row(k).iter().copied().collect()))
            .collect(),
        None => Vec::new(),
    };
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
    let smax = pairs.first().map_or(0.0, |p| p.0);
    let unidentifiable: Vec<Vec<(String, f64)>> = pairs
        .iter()
        .filter(|(s, _)| smax <= 0.0 || *s <= NULL_RELATIVE * smax)
        .map(|(_, v)| {
            let sign = if v
                .iter()
                .copied()
                .fold(0.0f64, |m, x| if x.abs() > m.abs() { x } else { m })
                < 0.0
            {
                -1.0
            } else {
                1.0
            };
            v.iter()
                .enumerate()
                .filter(|(_, w)| w.abs() >= 0.1)
                .map(|(k, w)| (PARAM_NAMES[k].to_string(), sign * w))
                .collect()
        })
        .collect();
    let smin = pairs.last().map_or(0.0, |p| p.0);
    let condition_number = if unidentifiable.is_empty() && smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    Identifiability {
        singular_values: pairs.iter().map(|p| p.0).collect(),
        condition_number,
        unidentifiable,
    }
}

/// A fitted geometry with its uncertainty and diagnostics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identification {
    pub geometry: ScaraGeometry,
    /// 1σ per parameter, [`PARAM_NAMES`] order (mm, rad, 1).
    pub sigma: [f64; 7],
    /// Parameter covariance `σ²(JᵀJ)⁻¹`.
    pub covariance: Vec<[f64; 7]>,
    /// RMS of the XY residual components (mm).
    pub rms: f64,
    /// Residual (model − measured) per measurement (mm).
    pub residuals: Vec<[f64; 2]>,
    pub identifiability: Identifiability,
}

struct FitProblem<'a> {
    data: &'a [Measurement],
    params: DVector<f64>,
}

impl FitProblem<'_> {
    fn geometry(&self) -> ScaraGeometry {
        let mut v = [0.0; 7];
        v.copy_from_slice(self.params.as_slice());
        ScaraGeometry::from_array(v)
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for FitProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.params.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.params.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let g = self.geometry();
        let mut r = DVector::zeros(2 * self.data.len());
        for (i, m) in self.data.iter().enumerate() {
            let p = g.forward(m.motor_a, m.motor_b);
            r[2 * i] = p[0] - m.x;
            r[2 * i + 1] = p[1] - m.y;
        }
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let poses: Vec<(f64, f64)> = self.data.iter().map(|m| (m.motor_a, m.motor_b)).collect();
        Some(stacked_jacobian(&self.geometry(), &poses))
    }
}

/// Fit the geometry to `data`, starting from `start` (the nominal machine). Refuses pose sets that cannot
/// identify every parameter, naming the combinations.
pub fn identify(data: &[Measurement], start: &ScaraGeometry) -> Result<Identification, ScaraError> {
    if data.len() < 4 {
        return Err(ScaraError::TooFewMeasurements {
            got: data.len(),
            rows: 2 * data.len(),
        });
    }
    if let Some(index) = data.iter().position(|m| {
        ![m.motor_a, m.motor_b, m.x, m.y]
            .iter()
            .all(|v| v.is_finite())
    }) {
        return Err(ScaraError::NonFinite { index });
    }
    let poses: Vec<(f64, f64)> = data.iter().map(|m| (m.motor_a, m.motor_b)).collect();
    let before = analyse_poses(start, &poses);
    if !before.is_identifiable() {
        return Err(ScaraError::Unidentifiable(before.describe()));
    }
    let problem = FitProblem {
        data,
        params: DVector::from_row_slice(&start.to_array()),
    };
    let (solved, report) = LevenbergMarquardt::new()
        .with_patience(200)
        .minimize(problem);
    if !report.termination.was_successful() {
        return Err(ScaraError::NoConvergence(format!(
            "{:?}",
            report.termination
        )));
    }
    let g = solved.geometry();
    let residual = solved
        .residuals()
        .ok_or_else(|| ScaraError::NoConvergence("non-finite residuals".into()))?;
    let j = stacked_jacobian(&g, &poses);
    let identifiability = analyse_poses(&g, &poses);
    let dof = (residual.len() as f64 - 7.0).max(1.0);
    let sigma2 = residual.norm_squared() / dof;
    let inv = (j.transpose() * &j)
        .try_inverse()
        .ok_or_else(|| ScaraError::Unidentifiable(identifiability.describe()))?;
    let covariance: Vec<[f64; 7]> = (0..7)
        .map(|a| std::array::from_fn(|b| sigma2 * inv[(a, b)]))
        .collect();
    let sigma = std::array::from_fn(|k| covariance[k][k].max(0.0).sqrt());
    let residuals = (0..data.len())
        .map(|i| [residual[2 * i], residual[2 * i + 1]])
        .collect();
    let rms = (residual.norm_squared() / residual.len() as f64).sqrt();
    Ok(Identification {
        geometry: g,
        sigma,
        covariance,
        rms,
        residuals,
        identifiability,
    })
}

/// Candidate poses on a grid of motor angles (rad), `n_a × n_b` points including the ends.
pub fn pose_grid(
    a_range: (f64, f64),
    b_range: (f64, f64),
    n_a: usize,
    n_b: usize,
) -> Vec<(f64, f64)> {
    let lerp = |(lo, hi): (f64, f64), k: usize, n: usize| {
        if n <= 1 {
            lo
        } else {
            lo + (hi - lo) * k as f64 / (n - 1) as f64
        }
    };
    (0..n_a)
        .flat_map(|i| (0..n_b).map(move |k| (lerp(a_range, i, n_a), lerp(b_range, k, n_b))))
        .collect()
}

/// Greedy D-optimal design: add `count` poses from `candidates` to `current`, each time the one that most
/// increases `det(JᵀJ)` (a small ridge lets the first picks proceed before the matrix has full rank).
pub fn suggest_poses(
    g: &ScaraGeometry,
    current: &[(f64, f64)],
    candidates: &[(f64, f64)],
    count: usize,
) -> Vec<(f64, f64)> {
    let info = |poses: &[(f64, f64)]| {
        let j = stacked_jacobian(g, poses);
        j.transpose() * j
    };
    let cand_info: Vec<DMatrix<f64>> = candidates
        .iter()
        .map(|p| info(std::slice::from_ref(p)))
        .collect();
    let scale =
        cand_info.iter().map(|m| m.trace()).sum::<f64>() / (7.0 * candidates.len().max(1) as f64);
    let mut m = info(current) + DMatrix::identity(7, 7) * (1e-6 * scale.max(1e-12));
    let mut chosen = Vec::new();
    let mut used = vec![false; candidates.len()];
    for _ in 0..count {
        let best = (0..candidates.len())
            .filter(|&i| !used[i])
            .map(|i| (i, (&m + &cand_info[i]).determinant()))
            .filter(|(_, d)| d.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _)) = best else { break };
        used[i] = true;
        m += &cand_info[i];
        chosen.push(candidates[i]);
    }
    chosen
}

/// Options for the printed calibration pattern.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PatternOptions {
    /// Length of each cross arm, tip to tip (mm).
    pub cross_size: f64,
    pub layer_height: f64,
    /// Filament length per mm of line (mm).
    pub extrusion_per_mm: f64,
    pub print_speed: f64,
    pub travel_speed: f64,
    /// Motor angles `(a, b)` (rad) where `G28` leaves the arm, if known: the first travel then also turns the
    /// joints instead of going straight.
    #[serde(default)]
    pub home_pose: Option<(f64, f64)>,
}

impl Default for PatternOptions {
    fn default() -> Self {
        Self {
            cross_size: 6.0,
            layer_height: 0.3,
            extrusion_per_mm: 0.04,
            print_speed: 20.0,
            travel_speed: 100.0,
            home_pose: None,
        }
    }
}

/// Fixed-decimal number without `-0.000`.
fn num(v: f64) -> String {
    let s = format!("{v:.3}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0.000".to_string()
    } else {
        s
    }
}

/// G-code of one small cross per pose, centred at the pose's nominal XY. With the nominal configuration the
/// firmware puts the motors at exactly the listed angles at each cross centre; measure the centres and
/// fill in `x_mm,y_mm` in the CSV the comments give.
pub fn calibration_pattern_gcode(
    g: &ScaraGeometry,
    poses: &[(f64, f64)],
    o: &PatternOptions,
) -> String {
    let mut s = String::new();
    let h = 0.5 * o.cross_size;
    let e = num(o.cross_size * o.extrusion_per_mm);
    let (fp, ft) = (num(o.print_speed * 60.0), num(o.travel_speed * 60.0));
    let _ = writeln!(
        s,
        "; jointspace SCARA calibration pattern: {} crosses of {} mm",
        poses.len(),
        num(o.cross_size)
    );
    let _ = writeln!(
        s,
        "; measure each cross centre on the bed and record: {}",
        CSV_HEADER.join(",")
    );
    let _ = writeln!(s, "G21\nG90\nM83\nG28\nG1 Z{} F600", num(o.layer_height));
    // The pose before the first cross is G28's: when it is not known, the first travel goes straight.
    let mut last = o.home_pose;
    for (i, &(a, b)) in poses.iter().enumerate() {
        let [x, y] = g.forward(a, b);
        let _ = writeln!(
            s,
            "; pose {} motor_a_deg={} motor_b_deg={} nominal_x={} nominal_y={}",
            i + 1,
            num(a.to_degrees()),
            num(b.to_degrees()),
            num(x),
            num(y)
        );
        for [vx, vy] in travel_via(g, last, (a, b)) {
            let _ = writeln!(s, "G0 X{} Y{} F{ft}", num(vx), num(vy));
        }
        let _ = writeln!(s, "G0 X{} Y{} F{ft}", num(x - h), num(y));
        let _ = writeln!(s, "G1 X{} Y{} E{e} F{fp}", num(x + h), num(y));
        let _ = writeln!(s, "G0 X{} Y{} F{ft}", num(x), num(y - h));
        let _ = writeln!(s, "G1 X{} Y{} E{e} F{fp}", num(x), num(y + h));
        last = Some((a, b));
    }
    let _ = writeln!(s, "G1 Z{} F600\nM84", num(o.layer_height + 5.0));
    s
}

/// Via points of the travel between two poses, in joint space: the arm turns its motors linearly from one
/// pose's angles to the other's (at most 5° per step), as a joint move would. Every point is a pose of the same
/// elbow branch whose distance from the shoulder lies between the two poses' (it depends on q2 alone, which
/// changes monotonically), so a travel never sweeps through the base or the unreachable centre, nor turns a
/// joint through angles the grid of poses avoids.
fn travel_via(g: &ScaraGeometry, from: Option<(f64, f64)>, to: (f64, f64)) -> Vec<[f64; 2]> {
    let Some(from) = from else {
        return Vec::new();
    };
    let (da, db) = (to.0 - from.0, to.1 - from.1);
    let steps = (da.abs().max(db.abs()) / 5f64.to_radians()).ceil() as usize;
    (1..steps)
        .map(|i| {
            let f = i as f64 / steps as f64;
            g.forward(from.0 + da * f, from.1 + db * f)
        })
        .collect()
}

/// A calibration pattern for one machine: the poses, its G-code, and how well the poses determine the geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// Motor angles `(a, b)` (rad) of each cross centre.
    pub poses: Vec<(f64, f64)>,
    pub gcode: String,
    pub condition_number: f64,
}

/// Chooses `count` well-conditioned poses (greedy D-optimal) among a grid of motor angles, keeping only those
/// `admissible` accepts (motor angles, nominal cross centre: the caller knows the machine's reach and branch), and
/// writes the pattern of crosses at them.
pub fn pattern(
    g: &ScaraGeometry,
    count: usize,
    admissible: &dyn Fn((f64, f64), [f64; 2]) -> bool,
    options: &PatternOptions,
) -> Pattern {
    let span = (-150f64.to_radians(), 150f64.to_radians());
    let candidates: Vec<(f64, f64)> = pose_grid(span, span, 25, 25)
        .into_iter()
        .filter(|&pose| admissible(pose, g.forward(pose.0, pose.1)))
        .collect();
    let mut poses = suggest_poses(g, &[], &candidates, count);
    // One sweep of the shoulder: short joint-space travels.
    poses.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
    Pattern {
        gcode: calibration_pattern_gcode(g, &poses, options),
        condition_number: analyse_poses(g, &poses).condition_number,
        poses,
    }
}

/// The measurements file to fill in: one row per pose with its motor angles, `x_mm` and `y_mm` left to the
/// person measuring the printed crosses.
pub fn measurement_template(poses: &[(f64, f64)]) -> String {
    let mut s = String::from(
        "# jointspace SCARA calibration: measure each printed cross's centre on the bed (mm, the printer's X/Y\n\
         # frame) and fill in x_mm and y_mm; then run: jointspace calibrate scara --measurements THIS_FILE\n",
    );
    s += &CSV_HEADER.join(",");
    s.push('\n');
    for &(a, b) in poses {
        let _ = writeln!(s, "{},{},,", num(a.to_degrees()), num(b.to_degrees()));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_closed_forms() {
        let g = ScaraGeometry::fekt();
        let p = g.forward(0.0, 0.0);
        assert!((p[0] - 200.0).abs() < 1e-12 && p[1].abs() < 1e-12);
        // Shoulder 90°, elbow motor 90°·c + 90°: q2 = 90° → nozzle at (−100, 100).
        let a = 90f64.to_radians();
        let p = g.forward(a, a + a / 3.0);
        assert!((p[0] + 100.0).abs() < 1e-9 && (p[1] - 100.0).abs() < 1e-9);
    }

    #[test]
    fn csv_parse_and_errors() {
        let text =
            "# poses\nmotor_a_deg, motor_b_deg, x_mm, y_mm\n10,20,1.5,2.5 # ok\n\n30,40,3,4\n";
        let m = parse_measurements(text, "p.csv").expect("parse");
        assert_eq!(m.len(), 2);
        assert!((m[0].motor_a - 10f64.to_radians()).abs() < 1e-15 && m[1].line == 5);
        let bad = "motor_a_deg,motor_b_deg,x_mm,y_mm\n1,2,abc,4\n";
        assert_eq!(
            parse_measurements(bad, "p.csv"),
            Err(ScaraError::Parse {
                file: "p.csv".into(),
                line: 2,
                column: 5,
                message: "`abc` is not a finite number".into()
            })
        );
        assert!(matches!(
            parse_measurements("a,b,c,d\n", "p.csv"),
            Err(ScaraError::Parse {
                line: 1,
                column: 1,
                ..
            })
        ));
        assert!(matches!(
            parse_measurements("motor_a_deg,motor_b_deg,x_mm\n", "p.csv"),
            Err(ScaraError::Parse { .. })
        ));
        assert!(matches!(
            parse_measurements("# nothing\n", "p.csv"),
            Err(ScaraError::Parse { .. })
        ));
    }

    #[test]
    fn lm_problem_jacobian_matches_numerical_differentiation() {
        let g = ScaraGeometry {
            link1_length: 101.0,
            link2_length: 99.0,
            offset_x: 0.5,
            offset_y: -1.0,
            shoulder_zero: 0.01,
            elbow_zero: -0.02,
            elbow_coupling: 0.34,
        };
        let data: Vec<Measurement> = (0..6)
            .map(|k| {
                let (a, b) = (0.3 * k as f64 - 0.5, 1.1 - 0.2 * k as f64);
                let p = ScaraGeometry::fekt().forward(a, b);
                Measurement {
                    motor_a: a,
                    motor_b: b,
                    x: p[0],
                    y: p[1],
                    line: 0,
                }
            })
            .collect();
        let mut problem = FitProblem {
            data: &data,
            params: DVector::from_row_slice(&g.to_array()),
        };
        let numeric =
            levenberg_marquardt::differentiate_numerically(&mut problem).expect("numeric");
        let analytic = problem.jacobian().expect("analytic");
        assert!((numeric - analytic).amax() < 1e-5);
    }

    #[test]
    fn number_format_has_no_negative_zero() {
        assert_eq!(num(-0.0001), "0.000");
        assert_eq!(num(-1.25), "-1.250");
    }
}
