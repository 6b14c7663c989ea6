//! Workspace pictures from plain data: a reach map (reachable, or why not, per cell) and one resolution
//! heat map per layer (per motor, machine worst case), each written as `<stem>-<name>.png` and `.svg`.
//!
//! The glue from `kinematics::workspace::WorkspaceMap` to [`WorkspaceData`] lives with the caller (the CLI):
//! this crate stays independent of the machine crates.

use std::path::{Path, PathBuf};

use crate::{ColourScale, Figure, Grid, Layer, Legend, PlotError, Rgb};

/// Drawn on top of every map: the bed (polar, Cartesian) or the arm's full reach (SCARA).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outline {
    Circle { centre: [f64; 2], radius: f64 },
    Rectangle { min: [f64; 2], max: [f64; 2] },
}

/// One heat map: `values` per cell (`None` = unreachable, drawn grey), in mm per step.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolutionLayer {
    /// File name part, e.g. `stepper_bed` or `machine`.
    pub name: String,
    pub title: String,
    pub values: Vec<Option<f64>>,
}

/// A workspace map as plain data; cell `iy * nx + ix` has its lower left corner at
/// `(x_min + ix·cell_mm, y_min + iy·cell_mm)`.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceData {
    /// Machine name for titles (`polar`, `scara`…).
    pub machine: String,
    pub x_min: f64,
    pub y_min: f64,
    pub cell_mm: f64,
    pub nx: usize,
    pub ny: usize,
    pub outline: Outline,
    /// Category names; `reach` holds indices into it. Index 0 should be "reachable".
    pub reach_labels: Vec<String>,
    pub reach: Vec<usize>,
    pub resolutions: Vec<ResolutionLayer>,
    /// Summary lines printed under the titles (area, extremes).
    pub notes: Vec<String>,
    /// The machine's singular curves, drawn over every map and named in the reach map's legend.
    pub curves: Vec<CurveData>,
}

/// One kind of special pose: its name and polylines (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct CurveData {
    pub label: String,
    pub pieces: Vec<Vec<[f64; 2]>>,
}

/// Dark, saturated: they stay visible over the reach categories and the heat maps alike.
/// In order: an arm straight, an arm folded, links in line, anything else.
const CURVE_PALETTE: [Rgb; 4] = [
    Rgb(20, 20, 140),
    Rgb(0, 110, 150),
    Rgb(190, 0, 110),
    Rgb(0, 90, 40),
];

/// The curves' colour: by kind (left and right of a kind share one).
fn curve_colour(label: &str) -> Rgb {
    let kind = ["straight", "folded", "in line"]
        .iter()
        .position(|k| label.contains(k))
        .unwrap_or(3);
    CURVE_PALETTE[kind]
}

fn curve_layers(data: &WorkspaceData) -> impl Iterator<Item = Layer> + '_ {
    data.curves.iter().flat_map(|c| {
        let colour = curve_colour(&c.label);
        c.pieces.iter().map(move |piece| Layer::Polyline {
            points: piece.clone(),
            colour,
            width: 2.0,
        })
    })
}

/// Legend entries of the curves, one per colour (`left/right arm straight` read as `arm straight`).
fn curve_entries(data: &WorkspaceData) -> Vec<(String, Rgb)> {
    let mut entries: Vec<(String, Rgb)> = Vec::new();
    for c in &data.curves {
        let colour = curve_colour(&c.label);
        let name = c
            .label
            .trim_start_matches("left ")
            .trim_start_matches("right ");
        if !entries.iter().any(|(_, rgb)| *rgb == colour) {
            entries.push((format!("singular: {name}"), colour));
        }
    }
    entries
}

const REACH_PALETTE: [Rgb; 8] = [
    Rgb(96, 178, 118),
    Rgb(205, 205, 205),
    Rgb(236, 150, 92),
    Rgb(206, 84, 96),
    Rgb(146, 124, 196),
    Rgb(110, 164, 214),
    Rgb(236, 204, 92),
    Rgb(150, 150, 150),
];

fn outline_layer(outline: Outline) -> Layer {
    let colour = Rgb(30, 30, 30);
    match outline {
        Outline::Circle { centre, radius } => Layer::Circle {
            centre,
            radius,
            colour,
            width: 2.0,
        },
        Outline::Rectangle { min, max } => Layer::Rectangle {
            min,
            max,
            colour,
            width: 2.0,
        },
    }
}

/// `cells` on the map's grid.
fn map_grid<T>(data: &WorkspaceData, cells: Vec<Option<T>>) -> Result<Grid<T>, PlotError> {
    Grid::new(
        data.x_min,
        data.y_min,
        data.cell_mm,
        data.nx,
        data.ny,
        cells,
    )
}

/// The reach map figure.
pub fn reach_figure(data: &WorkspaceData) -> Result<Figure, PlotError> {
    let grid = map_grid(data, data.reach.iter().map(|&i| Some(i)).collect())?;
    let palette: Vec<Rgb> = (0..data.reach_labels.len())
        .map(|i| REACH_PALETTE[i % REACH_PALETTE.len()])
        .collect();
    let present = |i: usize| data.reach.contains(&i);
    let mut entries: Vec<(String, Rgb)> = data
        .reach_labels
        .iter()
        .zip(&palette)
        .enumerate()
        .filter(|(i, _)| present(*i))
        .map(|(_, (label, colour))| (label.clone(), *colour))
        .collect();
    entries.extend(curve_entries(data));
    let mut fig = Figure::new(format!("{} workspace: reachable area", data.machine));
    fig.notes = data.notes.clone();
    fig.legend = Some(Legend { entries });
    fig.layers.push(Layer::Categories { grid, palette });
    fig.layers.extend(curve_layers(data));
    fig.layers.push(outline_layer(data.outline));
    Ok(fig)
}

/// The heat map figure of one resolution layer.
pub fn resolution_figure(
    data: &WorkspaceData,
    layer: &ResolutionLayer,
) -> Result<Figure, PlotError> {
    let grid = map_grid(data, layer.values.clone())?;
    let values = || layer.values.iter().flatten().copied();
    let scale = ColourScale::fit(values(), "mm per step");
    let (lo, hi) = values().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    let mut fig = Figure::new(layer.title.clone());
    fig.notes = vec![if lo <= hi {
        format!(
            "{} … {} mm per step; grey: unreachable",
            significant(lo),
            significant(hi)
        )
    } else {
        "nothing reachable".to_string()
    }];
    fig.colour_bar = Some(scale.clone());
    fig.layers.push(Layer::Heatmap { grid, scale });
    fig.layers.extend(curve_layers(data));
    fig.layers.push(outline_layer(data.outline));
    Ok(fig)
}

/// Four significant digits.
fn significant(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let decimals = (3 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}

/// Writes `<stem>-reach.{png,svg}` and `<stem>-<layer>.{png,svg}` into `dir`; returns the paths written.
pub fn write_workspace_maps(
    data: &WorkspaceData,
    dir: &Path,
    stem: &str,
) -> Result<Vec<PathBuf>, PlotError> {
    let mut figures = vec![("reach".to_string(), reach_figure(data)?)];
    for layer in &data.resolutions {
        figures.push((layer.name.clone(), resolution_figure(data, layer)?));
    }
    let mut written = Vec::new();
    for (name, fig) in figures {
        for ext in ["png", "svg"] {
            let path = dir.join(format!("{stem}-{name}.{ext}"));
            if ext == "png" {
                fig.write_png(&path)?
            } else {
                fig.write_svg(&path)?
            }
            written.push(path);
        }
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits() {
        assert_eq!(significant(0.0123456), "0.01235");
        assert_eq!(significant(123.456), "123.5");
    }
}
