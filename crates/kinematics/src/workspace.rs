//! Workspace maps: over a grid covering the machine's area, whether each point is reachable (or why not)
//! and the positioning resolution there (mm of nozzle travel per motor step).
//!
//! Resolution per planar motor `i` (motors 0 and 1 of every machine here move XY): a one-step change of
//! that motor alone moves the nozzle at least `step_i / |∇_xy motor_i|` along `∇motor_i` — this is that
//! motor's mm per step in its own worst (steepest) direction. The machine's worst case is the largest nozzle
//! travel for a unit change in step space over all directions: `1 / σ_min(S)`, where `S` is the 2×2 XY
//! Jacobian with each row divided by its motor's step distance (rows in steps per mm).

use crate::{Kinematics, MachineParams, ParamError, ReachError};

/// Rectangular area of the map, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub x_min: f64,
    pub x_max: f64,
    pub y_min: f64,
    pub y_max: f64,
}

/// The bed (polar, Cartesian) or the arm's full reach (SCARA), for drawing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outline {
    Circle { centre: [f64; 2], radius: f64 },
    Rectangle { min: [f64; 2], max: [f64; 2] },
}

/// Resolution at one reachable cell, mm per step.
#[derive(Debug, Clone, PartialEq)]
pub struct CellResolution {
    /// Per planar motor (motors 0 and 1).
    pub per_motor: [f64; 2],
    /// Worst direction over both motors together.
    pub machine: f64,
}

/// A value and the cell centre where it occurs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extreme {
    pub value: f64,
    pub at: [f64; 2],
}

/// Minimum and maximum of a resolution over the reachable cells (`None` when nothing is reachable).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    pub min: Extreme,
    pub max: Extreme,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    pub reachable_cells: usize,
    pub reachable_area_mm2: f64,
    /// Per planar motor.
    pub per_motor: [Option<Range>; 2],
    pub machine: Option<Range>,
}

/// One kind of special pose and where it lies (several pieces where it leaves the area or the reach).
#[derive(Debug, Clone, PartialEq)]
pub struct SingularCurve {
    /// What the machine does there, e.g. `left arm straight`, `distal links in line`.
    pub label: &'static str,
    /// Polylines, bed coordinates (mm).
    pub pieces: Vec<Vec<[f64; 2]>>,
}

impl SingularCurve {
    /// Total length of the pieces (mm).
    pub fn length(&self) -> f64 {
        self.pieces
            .iter()
            .flat_map(|piece| piece.windows(2))
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum()
    }
}

/// The map: `cells[iy * nx + ix]` is the cell whose centre is `cell_centre(ix, iy)`.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceMap {
    pub machine: &'static str,
    pub bounds: Bounds,
    pub outline: Outline,
    pub cell_mm: f64,
    pub nx: usize,
    pub ny: usize,
    /// Names of the two planar motors, e.g. `stepper_bed`, `stepper_arm`.
    pub motor_names: [String; 2],
    pub cells: Vec<Result<CellResolution, ReachError>>,
    pub summary: Summary,
    /// Where the machine's special poses lie in the area, traced at half a cell (drawn over the cells).
    pub curves: Vec<SingularCurve>,
}

/// Which resolution of a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResolutionKind {
    /// Planar motor 0 or 1.
    Motor(usize),
    /// The machine's worst direction.
    Machine,
}

impl WorkspaceMap {
    pub fn cell_centre(&self, ix: usize, iy: usize) -> [f64; 2] {
        cell_centre(&self.bounds, self.cell_mm, ix, iy)
    }

    /// Reach as categories for pictures: the labels (index 0 is `reachable`) and every cell's index.
    pub fn reach_categories(&self) -> (Vec<&'static str>, Vec<usize>) {
        let mut labels = vec!["reachable"];
        let indices = self
            .cells
            .iter()
            .map(|c| {
                let label = match c {
                    Ok(_) => "reachable",
                    Err(e) => reason_label(e),
                };
                labels.iter().position(|l| *l == label).unwrap_or_else(|| {
                    labels.push(label);
                    labels.len() - 1
                })
            })
            .collect();
        (labels, indices)
    }

    /// One resolution per cell, mm per step (`None` where unreachable).
    pub fn resolution_values(&self, kind: ResolutionKind) -> Vec<Option<f64>> {
        self.cells
            .iter()
            .map(|c| {
                c.as_ref().ok().and_then(|r| match kind {
                    ResolutionKind::Motor(i) => r.per_motor.get(i).copied(),
                    ResolutionKind::Machine => Some(r.machine),
                })
            })
            .collect()
    }
}

/// A short legend label for why a point is unreachable.
pub fn reason_label(e: &ReachError) -> &'static str {
    match e {
        ReachError::OutOfReach { .. } => "out of reach",
        ReachError::InsideMinimumRadius { .. } => "inside minimum radius",
        ReachError::JointLimit { .. } => "joint / arm limit",
        ReachError::BranchImpossible { .. } => "wrong elbow branch",
        ReachError::Singular { .. } | ReachError::ArmSingular { .. } => "near singular pose",
        ReachError::ArmReach { .. } => "out of an arm's reach",
        ReachError::ParallelSingular { .. } => "near the parallel singularity",
        ReachError::ElbowsApart { .. } => "distal links cannot join",
        ReachError::AtCentre { .. } => "at the rotation centre",
        ReachError::AxisLimit { .. } => "axis limit",
        ReachError::NotFinite => "not finite",
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorkspaceError {
    #[error(transparent)]
    Params(#[from] ParamError),
    #[error("cell size must be positive and finite, got {0}")]
    BadCellSize(f64),
    #[error("the machine has {0} motors; a workspace map needs two planar motors")]
    TooFewMotors(usize),
    #[error("a {nx}×{ny} grid is too large (at most {max} cells)")]
    TooManyCells { nx: usize, ny: usize, max: usize },
}

/// Largest grid accepted (keeps memory and time bounded).
pub const MAX_CELLS: usize = 4_000_000;

/// Map area and outline from the machine parameters: polar bed radius = arm `position_max`; SCARA reach
/// `L1 + L2` around the shoulder; five-bar: the box around both arms' full reach; Cartesian X/Y limits.
pub fn area_for(params: &MachineParams) -> Result<(Bounds, Outline), ParamError> {
    match params {
        MachineParams::Polar(p) => {
            let radius = p.arm.position_max.ok_or_else(|| ParamError::Invalid {
                name: format!("{} position_max", p.arm.name),
                reason: "needed as the bed radius of the workspace map".into(),
            })?;
            crate::common::ensure_positive("stepper_arm position_max", radius)?;
            Ok(circle_area([0.0, 0.0], radius))
        }
        MachineParams::Scara(p) => {
            let reach = p.link1_length + p.link2_length;
            crate::common::ensure_positive("link1_length + link2_length", reach)?;
            Ok(circle_area([p.offset_x, p.offset_y], reach))
        }
        MachineParams::Fivebar(p) => {
            // Both arms reach the nozzle: the box of the two discs' overlap.
            let disc = |arm: &crate::FivebarArm| {
                let r = arm.proximal + arm.distal;
                [
                    arm.base[0] - r,
                    arm.base[0] + r,
                    arm.base[1] - r,
                    arm.base[1] + r,
                ]
            };
            let (l, r) = (disc(&p.left), disc(&p.right));
            let bounds = Bounds {
                x_min: l[0].max(r[0]),
                x_max: l[1].min(r[1]),
                y_min: l[2].max(r[2]),
                y_max: l[3].min(r[3]),
            };
            if !(bounds.x_min < bounds.x_max && bounds.y_min < bounds.y_max) {
                return Err(ParamError::Invalid {
                    name: "left_base_x".into(),
                    reason: "the two arms' reaches do not overlap".into(),
                });
            }
            let outline = Outline::Rectangle {
                min: [bounds.x_min, bounds.y_min],
                max: [bounds.x_max, bounds.y_max],
            };
            Ok((bounds, outline))
        }
        MachineParams::Cartesian(p) => {
            let limit = |i: usize| -> Result<(f64, f64), ParamError> {
                let s = &p.steppers[i];
                match (s.position_min, s.position_max) {
                    (Some(min), Some(max)) if min < max => Ok((min, max)),
                    _ => Err(ParamError::Invalid {
                        name: s.name.clone(),
                        reason: "position_min < position_max needed for the workspace map".into(),
                    }),
                }
            };
            let ((x0, x1), (y0, y1)) = (limit(0)?, limit(1)?);
            let bounds = Bounds {
                x_min: x0,
                x_max: x1,
                y_min: y0,
                y_max: y1,
            };
            Ok((
                bounds,
                Outline::Rectangle {
                    min: [x0, y0],
                    max: [x1, y1],
                },
            ))
        }
    }
}

fn circle_area(centre: [f64; 2], radius: f64) -> (Bounds, Outline) {
    let bounds = Bounds {
        x_min: centre[0] - radius,
        x_max: centre[0] + radius,
        y_min: centre[1] - radius,
        y_max: centre[1] + radius,
    };
    (bounds, Outline::Circle { centre, radius })
}

fn cell_centre(b: &Bounds, cell: f64, ix: usize, iy: usize) -> [f64; 2] {
    [
        b.x_min + (ix as f64 + 0.5) * cell,
        b.y_min + (iy as f64 + 0.5) * cell,
    ]
}

/// Maps the machine over `bounds` with square cells of `cell_mm`, at height `z`.
pub fn map(
    kin: &dyn Kinematics,
    bounds: Bounds,
    outline: Outline,
    cell_mm: f64,
    z: f64,
) -> Result<WorkspaceMap, WorkspaceError> {
    if !(cell_mm.is_finite() && cell_mm > 0.0) {
        return Err(WorkspaceError::BadCellSize(cell_mm));
    }
    let motors = kin.motors();
    if motors.len() < 2 {
        return Err(WorkspaceError::TooFewMotors(motors.len()));
    }
    let nx = ((bounds.x_max - bounds.x_min) / cell_mm).ceil().max(1.0) as usize;
    let ny = ((bounds.y_max - bounds.y_min) / cell_mm).ceil().max(1.0) as usize;
    if nx.saturating_mul(ny) > MAX_CELLS {
        return Err(WorkspaceError::TooManyCells {
            nx,
            ny,
            max: MAX_CELLS,
        });
    }
    let steps = [motors[0].step_distance, motors[1].step_distance];
    let mut rows = vec![[0.0; 3]; motors.len()];
    let mut cells = Vec::with_capacity(nx * ny);
    for iy in 0..ny {
        for ix in 0..nx {
            let [x, y] = cell_centre(&bounds, cell_mm, ix, iy);
            cells.push(resolution_at(kin, [x, y, z], steps, &mut rows));
        }
    }
    let summary = summarise(&cells, &bounds, cell_mm, nx);
    let curves = kin.singular_curves(&bounds, 0.5 * cell_mm);
    Ok(WorkspaceMap {
        machine: kin.name(),
        bounds,
        outline,
        cell_mm,
        nx,
        ny,
        motor_names: [motors[0].name.clone(), motors[1].name.clone()],
        cells,
        summary,
        curves,
    })
}

/// Builds the machine from `params` and maps its default area.
pub fn map_machine(
    params: &MachineParams,
    cell_mm: f64,
    z: f64,
) -> Result<WorkspaceMap, WorkspaceError> {
    let kin = crate::build(params)?;
    let (bounds, outline) = area_for(params)?;
    map(kin.as_ref(), bounds, outline, cell_mm, z)
}

fn resolution_at(
    kin: &dyn Kinematics,
    p: [f64; 3],
    steps: [f64; 2],
    rows: &mut [[f64; 3]],
) -> Result<CellResolution, ReachError> {
    kin.check_point(p)?;
    kin.jacobian(p, rows)?;
    let grad = |i: usize| [rows[i][0], rows[i][1]];
    let (g0, g1) = (grad(0), grad(1));
    let norm = |g: [f64; 2]| (g[0] * g[0] + g[1] * g[1]).sqrt();
    let (n0, n1) = (norm(g0), norm(g1));
    // Steps per mm: rows scaled by 1/step.
    let s = [
        [g0[0] / steps[0], g0[1] / steps[0]],
        [g1[0] / steps[1], g1[1] / steps[1]],
    ];
    let sigma_min = smallest_singular_value(s);
    if n0 == 0.0 || n1 == 0.0 || sigma_min <= 0.0 || !sigma_min.is_finite() {
        return Err(ReachError::Singular {
            x: p[0],
            y: p[1],
            sin_q2: 0.0,
            margin: 0.0,
        });
    }
    Ok(CellResolution {
        per_motor: [steps[0] / n0, steps[1] / n1],
        machine: 1.0 / sigma_min,
    })
}

/// σ_min of a 2×2 matrix, computed as |det| / σ_max (stable when the matrix is nearly singular).
pub fn smallest_singular_value(m: [[f64; 2]; 2]) -> f64 {
    let [[a, b], [c, d]] = m;
    let frob2 = a * a + b * b + c * c + d * d;
    let det = (a * d - b * c).abs();
    let disc = (frob2 * frob2 - 4.0 * det * det).max(0.0).sqrt();
    let sigma_max = ((frob2 + disc) / 2.0).sqrt();
    if sigma_max == 0.0 {
        0.0
    } else {
        det / sigma_max
    }
}

fn summarise(
    cells: &[Result<CellResolution, ReachError>],
    b: &Bounds,
    cell: f64,
    nx: usize,
) -> Summary {
    let mut per_motor: [Option<Range>; 2] = [None, None];
    let mut machine: Option<Range> = None;
    let mut reachable = 0;
    for (i, c) in cells.iter().enumerate() {
        let Ok(res) = c else { continue };
        reachable += 1;
        let at = cell_centre(b, cell, i % nx, i / nx);
        for (range, value) in per_motor.iter_mut().zip(res.per_motor) {
            widen(range, value, at);
        }
        widen(&mut machine, res.machine, at);
    }
    Summary {
        reachable_cells: reachable,
        reachable_area_mm2: reachable as f64 * cell * cell,
        per_motor,
        machine,
    }
}

fn widen(range: &mut Option<Range>, value: f64, at: [f64; 2]) {
    let e = Extreme { value, at };
    match range {
        None => *range = Some(Range { min: e, max: e }),
        Some(r) => {
            if value < r.min.value {
                r.min = e;
            }
            if value > r.max.value {
                r.max = e;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn categories_number_reasons_in_order_of_appearance() {
        let params = crate::MachineParams::Polar(crate::PolarParams {
            bed: crate::StepperParams {
                name: "stepper_bed".into(),
                step_distance: 0.001,
                position_min: None,
                position_max: None,
            },
            arm: crate::StepperParams {
                name: "stepper_arm".into(),
                step_distance: 0.01,
                position_min: None,
                position_max: Some(10.0),
            },
            z: crate::StepperParams {
                name: "stepper_z".into(),
                step_distance: 0.01,
                position_min: None,
                position_max: None,
            },
            arm_zero_offset: 0.0,
            arm_lateral_offset: 0.0,
        });
        let map = map_machine(&params, 1.0, 0.0).expect("map");
        let (labels, cells) = map.reach_categories();
        assert_eq!(labels, vec!["reachable", "joint / arm limit"]);
        assert_eq!(cells.len(), 400);
        assert_eq!(cells[0], 1, "corner of the square is beyond the 10 mm arm");
        let bed = map.resolution_values(ResolutionKind::Motor(0));
        assert!(bed[0].is_none() && bed[210].is_some());
    }

    #[test]
    fn singular_value_of_a_diagonal_matrix() {
        assert_eq!(smallest_singular_value([[3.0, 0.0], [0.0, 2.0]]), 2.0);
        assert_eq!(smallest_singular_value([[1.0, 1.0], [1.0, 1.0]]), 0.0);
        // Rotation scaled by 5: both singular values 5.
        let (s, c) = 0.3f64.sin_cos();
        assert!(
            (smallest_singular_value([[5.0 * c, -5.0 * s], [5.0 * s, 5.0 * c]]) - 5.0).abs()
                < 1e-12
        );
    }
}
