//! The machine's workspace map under the part: where it reaches (or why not) and its resolution, from the map
//! `jointspace workspace` draws (`kinematics::workspace`), on a grid fine enough for the page.

use kinematics::workspace::{self, Outline, ResolutionKind};
use serde_json::json;

use crate::encode::Array;

/// Cells across the map's wider side.
const CELLS_ACROSS: f64 = 200.0;
/// An unreachable cell in a resolution layer (reachable ones are 0 … 65534 of the layer's largest value).
const UNREACHABLE: u16 = u16::MAX;

/// The map's description (JSON) and its layers (`reach`, one resolution per planar motor, the worst direction).
#[derive(Debug, Clone)]
pub struct MapData {
    pub meta: serde_json::Value,
    pub arrays: Vec<(String, Array)>,
}

/// The map of `params`; `None` (with the reason) when the machine has none.
pub fn map(params: &kinematics::MachineParams) -> Result<MapData, String> {
    let (bounds, _) = workspace::area_for(params).map_err(|e| e.to_string())?;
    let across = (bounds.x_max - bounds.x_min).max(bounds.y_max - bounds.y_min);
    let cell = (across / CELLS_ACROSS).max(0.1);
    let map = workspace::map_machine(params, cell, 0.0).map_err(|e| e.to_string())?;
    let (labels, reach) = map.reach_categories();
    let outline = match map.outline {
        Outline::Circle { centre, radius } => {
            json!({"circle": {"centre": centre, "radius": radius}})
        }
        Outline::Rectangle { min, max } => json!({"rectangle": {"min": min, "max": max}}),
    };
    // Each resolution layer as 16-bit fractions of its largest value (its `max`).
    let values = |kind| {
        let values = map.resolution_values(kind);
        let max = values.iter().flatten().fold(0.0, |m: f64, v| m.max(*v));
        let cells = values
            .iter()
            .map(|v| v.map_or(UNREACHABLE, |v| (v / max * 65534.0).round() as u16))
            .collect();
        (Array::U16(cells), max)
    };
    let mut arrays = vec![(
        "map-reach".to_string(),
        Array::U8(reach.iter().map(|&i| i.min(255) as u8).collect()),
    )];
    let mut layers = Vec::new();
    for (i, name) in map.motor_names.iter().enumerate() {
        let (cells, max) = values(ResolutionKind::Motor(i));
        arrays.push((format!("map-motor{i}"), cells));
        layers.push(json!({
            "id": format!("motor{i}"),
            "max": max,
            "title": format!("nozzle travel that steps {name} once, along its steepest direction (mm)"),
            "note": format!(
                "small: {name} steps for little nozzle travel here (it turns fast and its steps come often); \
                 it is not by itself where the nozzle is placed finely"
            ),
        }));
    }
    let (cells, max) = values(ResolutionKind::Machine);
    arrays.push(("map-machine".into(), cells));
    layers.push(json!({
        "id": "machine",
        "max": max,
        "title": "positioning resolution: nozzle travel per motor step in the worst direction (mm; small is fine)",
        "note": "small: fine positioning in every direction; large: coarse",
    }));
    let meta = json!({
        "machine": map.machine,
        "x_min": map.bounds.x_min,
        "y_min": map.bounds.y_min,
        "cell": map.cell_mm,
        "nx": map.nx,
        "ny": map.ny,
        "outline": outline,
        "reach_labels": labels,
        "layers": layers,
    });
    Ok(MapData { meta, arrays })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scara_map_has_reach_and_three_resolutions_on_its_grid() {
        let params = kinematics::MachineParams::Scara(kinematics::ScaraParams::fekt_example());
        let data = map(&params).expect("a map");
        let cells = data.meta["nx"].as_u64().expect("nx") * data.meta["ny"].as_u64().expect("ny");
        assert_eq!(data.arrays.len(), 4);
        for (name, array) in &data.arrays {
            assert_eq!(array.len() as u64, cells, "{name}");
        }
        assert_eq!(data.meta["reach_labels"][0], "reachable");
    }
}
