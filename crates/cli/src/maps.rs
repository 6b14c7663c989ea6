//! Workspace maps: where a machine reaches and how fine its motion is across the bed, as numbers and pictures.

use kinematics::workspace::{self, ResolutionKind, WorkspaceMap};
use plot::workspace::{CurveData, Outline, ResolutionLayer, WorkspaceData};
use serde::Serialize;
use std::path::Path;

/// The smallest and largest nozzle travel per motor step of one motor (along its steepest direction) or of the
/// machine's worst direction, with where they are. Small is fine positioning only for the worst direction: a
/// motor's own value is smallest where it steps for the least nozzle travel (where it turns fastest), which for a
/// SCARA's elbow is the rim, where the machine positions coarsest.
#[derive(Debug, Clone, Serialize)]
pub struct ResolutionRange {
    pub name: String,
    /// What the numbers are.
    pub quantity: String,
    /// mm of nozzle travel per step.
    pub smallest: f64,
    pub smallest_at: [f64; 2],
    pub largest: f64,
    pub largest_at: [f64; 2],
}

/// What a motor's map shows.
pub fn motor_quantity(motor: &str) -> String {
    format!("nozzle travel that steps {motor} once, along its steepest direction (mm)")
}

/// What the worst-direction map shows.
pub const MACHINE_QUANTITY: &str = "positioning resolution: nozzle travel per motor step in the worst direction (mm; small is fine)";

/// The numbers a builder compares machines by.
#[derive(Debug, Clone, Serialize)]
pub struct WorkspaceFigures {
    pub machine: String,
    pub reachable_area_mm2: f64,
    /// Per motor, then for the machine's worst direction.
    pub resolution: Vec<ResolutionRange>,
    /// The special poses drawn on the maps (a five-bar's arms straight or folded, its distal links in line).
    pub singular_curves: Vec<CurveLength>,
    pub pictures: Vec<String>,
}

/// How much of one kind of special pose lies in the mapped area.
#[derive(Debug, Clone, Serialize)]
pub struct CurveLength {
    pub label: String,
    pub length_mm: f64,
}

/// Map the workspace, write the pictures into `dir` as `<stem>-*.png/svg`, return the numbers.
pub fn map_and_draw(
    params: &kinematics::MachineParams,
    cell_mm: f64,
    dir: &Path,
    stem: &str,
) -> miette::Result<WorkspaceFigures> {
    let map = workspace::map_machine(params, cell_mm, 0.0).map_err(|e| miette::miette!("{e}"))?;
    let area = map.summary.reachable_area_mm2;
    if area.is_nan() || area <= 0.0 {
        return Err(miette::miette!(
            "the {} machine reaches no point of the bed on a {cell_mm} mm grid: check its lengths, limits and \
             base_protection_radius (nothing was written)",
            map.machine
        ));
    }
    // The maps are `<stem>-….png/svg`: none of them may be an input of this run.
    if let Ok(entries) = std::fs::read_dir(dir) {
        for entry in entries.flatten() {
            if entry.file_name().to_string_lossy().starts_with(stem) {
                crate::output::refuse_input(&entry.path()).map_err(crate::cmd::plain)?;
            }
        }
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| miette::miette!("cannot create {}: {e}", dir.display()))?;
    let written = plot::workspace::write_workspace_maps(&workspace_data(&map), dir, stem)
        .map_err(|e| miette::miette!("{e}"))?;
    let range = |name: &str, quantity: String, r: &workspace::Range| ResolutionRange {
        name: name.to_string(),
        quantity,
        smallest: r.min.value,
        smallest_at: r.min.at,
        largest: r.max.value,
        largest_at: r.max.at,
    };
    let mut resolution: Vec<ResolutionRange> = map
        .motor_names
        .iter()
        .zip(map.summary.per_motor.iter())
        .filter_map(|(name, r)| r.as_ref().map(|r| range(name, motor_quantity(name), r)))
        .collect();
    if let Some(r) = &map.summary.machine {
        resolution.push(range("worst direction", MACHINE_QUANTITY.into(), r));
    }
    Ok(WorkspaceFigures {
        machine: map.machine.to_string(),
        reachable_area_mm2: map.summary.reachable_area_mm2,
        resolution,
        singular_curves: map
            .curves
            .iter()
            .map(|c| CurveLength {
                label: c.label.to_string(),
                length_mm: c.length(),
            })
            .collect(),
        pictures: written.iter().map(|p| p.display().to_string()).collect(),
    })
}

/// The plain data the plot crate draws.
fn workspace_data(map: &WorkspaceMap) -> WorkspaceData {
    let (labels, reach) = map.reach_categories();
    let mut resolutions: Vec<ResolutionLayer> = map
        .motor_names
        .iter()
        .enumerate()
        .map(|(i, name)| ResolutionLayer {
            name: name.clone(),
            title: format!("{}: {}", map.machine, motor_quantity(name)),
            values: map.resolution_values(ResolutionKind::Motor(i)),
        })
        .collect();
    resolutions.push(ResolutionLayer {
        name: "machine".into(),
        title: format!("{}: {MACHINE_QUANTITY}", map.machine),
        values: map.resolution_values(ResolutionKind::Machine),
    });
    let outline = match map.outline {
        workspace::Outline::Circle { centre, radius } => Outline::Circle { centre, radius },
        workspace::Outline::Rectangle { min, max } => Outline::Rectangle { min, max },
    };
    let s = &map.summary;
    let mut notes = vec![format!(
        "reachable area {:.0} mm² ({} of {} cells of {} mm)",
        s.reachable_area_mm2,
        s.reachable_cells,
        map.cells.len(),
        map.cell_mm
    )];
    if let Some(m) = s.machine {
        notes.push(format!(
            "positioning resolution (worst direction) {:.4} mm/step at ({:.0}, {:.0}) … {:.4} at ({:.0}, {:.0})",
            m.min.value, m.min.at[0], m.min.at[1], m.max.value, m.max.at[0], m.max.at[1]
        ));
    }
    WorkspaceData {
        machine: map.machine.to_string(),
        x_min: map.bounds.x_min,
        y_min: map.bounds.y_min,
        cell_mm: map.cell_mm,
        nx: map.nx,
        ny: map.ny,
        outline,
        reach_labels: labels.into_iter().map(String::from).collect(),
        reach,
        resolutions,
        notes,
        curves: map
            .curves
            .iter()
            .map(|c| CurveData {
                label: c.label.to_string(),
                pieces: c.pieces.clone(),
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_of_the_example_machines_write_every_picture_with_sane_numbers() {
        let dir = tempfile::tempdir().expect("temp dir");
        // The polar map needs the bed radius: the arm's travel.
        let arm = kinematics::StepperParams {
            position_max: Some(150.0),
            ..kinematics::StepperParams::new("stepper_arm", 1.0 / 80.0)
        };
        let polar = kinematics::PolarParams {
            arm,
            ..kinematics::PolarParams::klipper_example()
        };
        let machines = [
            ("polar", kinematics::MachineParams::Polar(polar)),
            (
                "scara",
                kinematics::MachineParams::Scara(kinematics::ScaraParams::fekt_example()),
            ),
        ];
        for (stem, params) in machines {
            let figures = map_and_draw(&params, 10.0, dir.path(), stem).expect("maps");
            // Reach, two motors and the worst direction, each as PNG and SVG.
            assert_eq!(figures.pictures.len(), 8, "{stem}");
            for path in &figures.pictures {
                let bytes = std::fs::read(path).expect("picture");
                if path.ends_with(".png") {
                    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{path}");
                } else {
                    let text = String::from_utf8(bytes).expect("svg is text");
                    assert!(
                        text.contains("<svg") && text.trim_end().ends_with("</svg>"),
                        "{path}"
                    );
                }
            }
            assert!(figures.reachable_area_mm2 > 0.0);
            for r in &figures.resolution {
                assert!(
                    r.smallest > 0.0 && r.smallest <= r.largest,
                    "{stem} {}: {r:?}",
                    r.name
                );
            }
        }
    }
}
