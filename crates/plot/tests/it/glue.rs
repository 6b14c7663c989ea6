//! Turns a `kinematics::workspace::WorkspaceMap` into the plain data the plot crate draws (the same few
//! lines a caller such as the CLI writes; shared with `examples/workspace_maps.rs`).

use kinematics::workspace::{self, ResolutionKind, WorkspaceMap};
use plot::workspace::{Outline, ResolutionLayer, WorkspaceData};

pub fn workspace_data(map: &WorkspaceMap) -> WorkspaceData {
    let (labels, reach) = map.reach_categories();
    let mut resolutions: Vec<ResolutionLayer> = map
        .motor_names
        .iter()
        .enumerate()
        .map(|(i, name)| ResolutionLayer {
            name: name.clone(),
            title: format!(
                "{}: {name} resolution (mm of nozzle travel per step)",
                map.machine
            ),
            values: map.resolution_values(ResolutionKind::Motor(i)),
        })
        .collect();
    resolutions.push(ResolutionLayer {
        name: "machine".into(),
        title: format!("{}: worst-direction resolution (mm per step)", map.machine),
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
            "worst-direction resolution {:.4} mm/step at ({:.0}, {:.0}) … {:.4} at ({:.0}, {:.0})",
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
    }
}
