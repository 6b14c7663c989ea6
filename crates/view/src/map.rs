//! The machine's workspace map under the part: where it reaches (or why not) and its resolution, from the map
//! `jointspace workspace` draws (`kinematics::workspace`), on a grid fine enough for the page.

use kinematics::workspace::{self, Outline, ResolutionKind};
use serde_json::json;

use crate::encode::Array;

/// Cells across the map's wider side.
const CELLS_ACROSS: f64 = 240.0;

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
    let values = |kind| {
        Array::F32(
            map.resolution_values(kind)
                .iter()
                .map(|v| v.map_or(f32::NAN, |v| v as f32))
                .collect(),
        )
    };
    let mut arrays = vec![(
        "map-reach".to_string(),
        Array::U8(reach.iter().map(|&i| i.min(255) as u8).collect()),
    )];
    let mut layers = Vec::new();
    for (i, name) in map.motor_names.iter().enumerate() {
        arrays.push((format!("map-motor{i}"), values(ResolutionKind::Motor(i))));
        layers.push(json!({
            "id": format!("motor{i}"),
            "title": format!("nozzle travel that steps {name} once (mm, along its steepest direction)"),
            "note": format!(
                "small: {name} steps for little nozzle travel here (it turns fast and its steps come often); \
                 it is not by itself where the nozzle is placed finely"
            ),
        }));
    }
    arrays.push(("map-machine".into(), values(ResolutionKind::Machine)));
    layers.push(json!({
        "id": "machine",
        "title": "positioning resolution in the worst direction (mm of nozzle travel per step of both motors)",
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
