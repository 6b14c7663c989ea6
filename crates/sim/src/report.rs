//! The simulation report: numbers (text + JSON) and pictures (overlay of intended vs actual path coloured by
//! deviation, heat map of deviation over the bed), for one run or a before/after correction pair.

use crate::correction::CorrectionSummary;
use crate::error::SimulationError;
use crate::features::{CircleFeature, QuadFeature};
use crate::metrics::{PathPoint, StatsSummary};
use crate::simulation::Simulation;
use plot::{ColourScale, Figure, Grid, Layer, Rgb};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Segments drawn at most in an overlay (the kept path is thinned evenly beyond this).
const MAX_DRAWN_SEGMENTS: usize = 30_000;
/// Heat-map cells across the larger side of the printed area.
const HEAT_CELLS: f64 = 120.0;

/// Rows of a report's per-layer table at most: beyond, consecutive layers are merged into one row.
pub const MAX_REPORTED_LAYERS: usize = 200;
/// Rows of the circle and four-sided-loop tables at most (the worst are kept).
pub const MAX_REPORTED_FEATURES: usize = 200;

/// Statistics of one layer, or of a run of consecutive layers when the print has more than
/// [`MAX_REPORTED_LAYERS`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LayerReport {
    /// First layer of the row (0-based) and how many layers it holds.
    pub index: usize,
    pub layers: usize,
    /// Intended Z at the row's start, and the highest in it.
    pub z: f64,
    pub z_max: f64,
    pub stats: StatsSummary,
}

/// The numbers of one simulation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunReport {
    pub deposited: StatsSummary,
    pub all_motion: StatsSummary,
    /// Layers found in the print (one per turn of a spiral vase).
    pub layer_count: usize,
    pub layers: Vec<LayerReport>,
    /// Circles and four-sided loops found (the tables hold at most [`MAX_REPORTED_FEATURES`] each, the
    /// worst first kept in print order).
    pub circle_count: usize,
    pub circles: Vec<CircleFeature>,
    pub square_count: usize,
    pub squares: Vec<QuadFeature>,
    pub steps: Vec<(String, u64)>,
    pub print_time: f64,
    /// Largest time error / local step resolution (when tracked; ≤ 1 means within step resolution).
    pub worst_resolution_ratio: Option<f64>,
    pub warnings: usize,
}

impl RunReport {
    pub fn new(sim: &Simulation) -> Self {
        let r = &sim.replay;
        RunReport {
            deposited: r.deposited.summary(),
            all_motion: r.all.summary(),
            layer_count: r.layer_count,
            layers: crate::metrics::summarise_layers(&r.layers, MAX_REPORTED_LAYERS)
                .iter()
                .map(|l| LayerReport {
                    index: l.first,
                    layers: l.count,
                    z: l.z,
                    z_max: l.z_max,
                    stats: l.stats.summary(),
                })
                .collect(),
            circle_count: sim.circles.len(),
            circles: worst_kept(&sim.circles, |c| {
                (c.actual_diameter - c.intended_diameter).abs() + c.roundness + c.centre_shift()
            }),
            square_count: sim.quads.len(),
            squares: worst_kept(&sim.quads, |q| q.worst_side_error()),
            steps: r.steps.clone(),
            print_time: r.end_time,
            worst_resolution_ratio: r.worst_resolution_ratio,
            warnings: r.warnings.len(),
        }
    }
}

/// At most [`MAX_REPORTED_FEATURES`] of `all`: the worst by `badness`, in their original order.
fn worst_kept<T: Clone>(all: &[T], badness: impl Fn(&T) -> f64) -> Vec<T> {
    if all.len() <= MAX_REPORTED_FEATURES {
        return all.to_vec();
    }
    let mut order: Vec<usize> = (0..all.len()).collect();
    order.sort_by(|&a, &b| badness(&all[b]).total_cmp(&badness(&all[a])));
    order.truncate(MAX_REPORTED_FEATURES);
    order.sort_unstable();
    order.into_iter().map(|i| all[i].clone()).collect()
}

/// Everything written to `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    pub believed_config: String,
    pub actual_config: String,
    pub gcode: String,
    pub before: RunReport,
    pub correction: Option<CorrectionSummary>,
    pub after: Option<RunReport>,
    /// Why a correction was asked for and no "after" simulation could be made (the calibration failed, its fit
    /// was not trustworthy, or the corrected machine could not plan the print); `None` otherwise.
    pub after_missing: Option<String>,
}

impl Report {
    /// The human-readable report.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "jointspace simulate: {}", self.gcode);
        let _ = writeln!(
            s,
            "believed machine: {}\nactual machine:   {}",
            self.believed_config, self.actual_config
        );
        run_text(&mut s, "as configured", &self.before);
        if let Some(c) = &self.correction {
            let _ = writeln!(s, "\ncalibration: {}", c.method);
            let _ = writeln!(
                s,
                "  {:<20} {:>12} {:>12} {:>12}",
                "parameter", "believed", "measured", "actual"
            );
            for v in &c.values {
                let _ = writeln!(
                    s,
                    "  {:<20} {:>12.6} {:>12.6} {:>12.6}",
                    v.name, v.believed, v.measured, v.actual
                );
            }
            let _ = writeln!(s, "  fit rms {:.4} mm", c.rms);
            for note in &c.notes {
                let _ = writeln!(s, "  {note}");
            }
        }
        if let Some(after) = &self.after {
            run_text(&mut s, "after correction", after);
        }
        if let Some(why) = &self.after_missing {
            let _ = writeln!(s, "\n== after correction ==\nnot simulated: {why}");
        }
        s
    }
}

fn run_text(s: &mut String, title: &str, r: &RunReport) {
    run_stats_text(s, title, r);
    circles_text(s, &r.circles);
    more_than_listed(
        s,
        "               ",
        r.circle_count,
        r.circles.len(),
        "circles",
    );
    quads_text(s, &r.squares);
    more_than_listed(
        s,
        "                  ",
        r.square_count,
        r.squares.len(),
        "four-sided loops",
    );
}

/// Under a table cut to its worst rows: how many there were in all.
fn more_than_listed(s: &mut String, indent: &str, count: usize, listed: usize, what: &str) {
    if count > listed {
        let _ = writeln!(
            s,
            "{indent}({count} {what} in all; the {listed} worst are listed)"
        );
    }
}

fn run_stats_text(s: &mut String, title: &str, r: &RunReport) {
    let d = &r.deposited;
    let _ = writeln!(s, "\n== {title} ==");
    let _ = writeln!(
        s,
        "deposited path: max deviation {:.4} mm (at {:.2}, {:.2}), rms {:.4} mm; same-instant error max {:.4}, rms {:.4} mm",
        d.max_path_deviation,
        d.worst_at[0],
        d.worst_at[1],
        d.rms_path_deviation,
        d.max_time_error,
        d.rms_time_error
    );
    let _ = writeln!(
        s,
        "assembly error alone (true vs believed machine, same motor state): max {:.4} mm, rms {:.4} mm; max Z error {:.4} mm",
        d.max_model_error, d.rms_model_error, d.max_z_error
    );
    if let Some(ratio) = r.worst_resolution_ratio {
        let _ = writeln!(s, "worst error / local step resolution: {ratio:.3}");
    }
    let _ = writeln!(
        s,
        "print time {:.1} s, {} samples; steps: {}",
        r.print_time,
        d.samples,
        steps_text(&r.steps)
    );
    let merged = r.layers.len() < r.layer_count;
    let _ = writeln!(
        s,
        "per layer ({} layers{}):  layer      z   max dev   rms dev   max model",
        r.layer_count,
        if merged {
            format!(", {} rows of consecutive layers", r.layers.len())
        } else {
            String::new()
        }
    );
    for l in &r.layers {
        let index = if l.layers > 1 {
            format!("{}–{}", l.index, l.index + l.layers - 1)
        } else {
            l.index.to_string()
        };
        let z = if l.z_max - l.z > 0.005 {
            format!("{:.2}–{:.2}", l.z, l.z_max)
        } else {
            format!("{:.2}", l.z)
        };
        let _ = writeln!(
            s,
            "           {index:>5} {z:>6} {:>9.4} {:>9.4} {:>11.4}",
            l.stats.max_path_deviation, l.stats.rms_path_deviation, l.stats.max_model_error
        );
    }
}

fn circles_text(s: &mut String, circles: &[CircleFeature]) {
    if !circles.is_empty() {
        let _ = writeln!(
            s,
            "circles (mm):  layer  centre           Ø intended  Ø actual  roundness  ellipse axes (major × minor @ angle)  centre shift"
        );
        for c in circles {
            let axes = c.ellipse.map_or("-".to_string(), |e| {
                format!(
                    "{:.4} × {:.4} @ {:.1}°",
                    2.0 * e.semi_major,
                    2.0 * e.semi_minor,
                    e.angle_deg
                )
            });
            let _ = writeln!(
                s,
                "               {:>5}  ({:>7.2}, {:>7.2}) {:>10.4} {:>9.4} {:>10.4}  {axes:<36} {:.4}",
                c.layer,
                c.intended_centre[0],
                c.intended_centre[1],
                c.intended_diameter,
                c.actual_diameter,
                c.roundness,
                c.centre_shift()
            );
        }
    }
}

fn quads_text(s: &mut String, quads: &[QuadFeature]) {
    if quads.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "four-sided loops: layer  sides intended → actual (mm)            corner angles actual (°)"
    );
    for q in quads {
        let sides: Vec<String> = (0..4)
            .map(|k| format!("{:.3}→{:.3}", q.intended_sides[k], q.actual_sides[k]))
            .collect();
        let angles: Vec<String> = q
            .actual_angles_deg
            .iter()
            .map(|a| format!("{a:.3}"))
            .collect();
        let _ = writeln!(
            s,
            "                  {:>5}  {}   {}   (worst side error {:.4} mm, angle error {:.4}°)",
            q.layer,
            sides.join(" "),
            angles.join(" "),
            q.worst_side_error(),
            q.worst_angle_error()
        );
    }
}

fn steps_text(steps: &[(String, u64)]) -> String {
    steps
        .iter()
        .map(|(n, c)| format!("{n} {c}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Every file [`write_report`] may write into its folder (the `-after` ones only with a correction).
pub const REPORT_FILES: [&str; 8] = [
    "report.txt",
    "report.json",
    "overlay.png",
    "overlay.svg",
    "deviation-map.png",
    "overlay-after.png",
    "overlay-after.svg",
    "deviation-map-after.png",
];

/// Write `report.txt`, `report.json`, `overlay.png/.svg`, `deviation-map.png` (and `-after` pictures).
pub fn write_report(
    dir: &Path,
    report: &Report,
    before: &Simulation,
    after: Option<&Simulation>,
) -> Result<(), SimulationError> {
    write_pictures(dir, Stage::Before, before)?;
    if let Some(after) = after {
        write_pictures(dir, Stage::After, after)?;
    }
    write_numbers(dir, report)
}

/// Write `report.txt` and `report.json` (the pictures are [`write_pictures`]'s: a caller that streams drops each
/// simulation's path once its pictures are drawn).
pub fn write_numbers(dir: &Path, report: &Report) -> Result<(), SimulationError> {
    std::fs::create_dir_all(dir).map_err(|e| output_error(dir, &e))?;
    write_file(&dir.join("report.txt"), report.text().as_bytes())?;
    let json = serde_json::to_string_pretty(report).map_err(|e| output_error(dir, &e))?;
    write_file(&dir.join("report.json"), json.as_bytes())
}

/// Which simulation a picture shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// As configured: `overlay.png`, `overlay.svg`, `deviation-map.png`.
    Before,
    /// After correction: the same names with `-after`.
    After,
}

/// The overlay and deviation map of one simulation, into `dir`.
pub fn write_pictures(dir: &Path, stage: Stage, sim: &Simulation) -> Result<(), SimulationError> {
    let (suffix, title) = match stage {
        Stage::Before => ("", "as configured"),
        Stage::After => ("-after", "after correction"),
    };
    std::fs::create_dir_all(dir).map_err(|e| output_error(dir, &e))?;
    let overlay = overlay_figure(&sim.replay.path, title);
    overlay.write_png(&dir.join(format!("overlay{suffix}.png")))?;
    overlay.write_svg(&dir.join(format!("overlay{suffix}.svg")))?;
    if let Some(map) = deviation_map(&sim.replay.path, title)? {
        map.write_png(&dir.join(format!("deviation-map{suffix}.png")))?;
    }
    Ok(())
}

fn output_error(path: &Path, e: &dyn std::fmt::Display) -> SimulationError {
    SimulationError::Output {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Write through a temporary file renamed into place.
fn write_file(path: &Path, bytes: &[u8]) -> Result<(), SimulationError> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes).map_err(|e| output_error(path, &e))?;
    std::fs::rename(&tmp, path).map_err(|e| output_error(path, &e))
}

/// Intended path (grey) and actual deposited path coloured by its deviation.
pub fn overlay_figure(path: &[PathPoint], title: &str) -> Figure {
    let deposited_pairs: Vec<(&PathPoint, &PathPoint)> = path
        .windows(2)
        .filter(|w| w[0].deposited && w[1].deposited)
        .map(|w| (&w[0], &w[1]))
        .collect();
    let stride = deposited_pairs.len().div_ceil(MAX_DRAWN_SEGMENTS).max(1);
    let drawn: Vec<(&PathPoint, &PathPoint)> =
        deposited_pairs.iter().step_by(stride).copied().collect();
    let xy = |p: [f64; 3]| [p[0], p[1]];
    let scale = ColourScale::fit(
        drawn.iter().map(|(_, b)| b.deviation),
        "path deviation (mm)",
    );
    let max = drawn.iter().map(|(_, b)| b.deviation).fold(0.0, f64::max);
    let extent = path_extent(&drawn);
    let factor = exaggeration(extent, max);
    let shown = |p: &PathPoint| {
        [
            p.intended[0] + factor * (p.actual[0] - p.intended[0]),
            p.intended[1] + factor * (p.actual[1] - p.intended[1]),
        ]
    };
    let mut fig = Figure::new(format!("Intended (grey) vs actual path, {title}"));
    if factor > 1.0 {
        fig.notes.push(format!("deviation drawn ×{factor}"));
    }
    let drawn_note = if stride == 1 {
        "every kept segment drawn".to_string()
    } else {
        format!("one kept segment in {stride} drawn")
    };
    fig.notes
        .push(format!("max deviation {max:.4} mm; {drawn_note}"));
    // Grey underlay: the intended path, one polyline per connected run.
    let mut run: Vec<[f64; 2]> = Vec::new();
    for (a, b) in &drawn {
        if run
            .last()
            .is_some_and(|l| (l[0] - a.intended[0]).hypot(l[1] - a.intended[1]) > 1e-5)
        {
            fig.layers.push(grey_line(std::mem::take(&mut run)));
        }
        if run.is_empty() {
            run.push(xy(a.intended));
        }
        // Repeated points give the line joins no direction (spikes in the PNG).
        if run
            .last()
            .is_some_and(|l| (l[0] - b.intended[0]).hypot(l[1] - b.intended[1]) > 1e-6)
        {
            run.push(xy(b.intended));
        }
    }
    if run.len() > 1 {
        fig.layers.push(grey_line(run));
    }
    fig.layers.push(Layer::Segments {
        segments: drawn.iter().map(|(a, b)| [shown(a), shown(b)]).collect(),
        values: drawn.iter().map(|(_, b)| b.deviation).collect(),
        scale: scale.clone(),
        width: 1.5,
    });
    fig.colour_bar = Some(scale);
    fig
}

/// Largest side of the box around the drawn intended path (mm).
fn path_extent(drawn: &[(&PathPoint, &PathPoint)]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (_, p) in drawn {
        for k in 0..2 {
            lo[k] = lo[k].min(p.intended[k]);
            hi[k] = hi[k].max(p.intended[k]);
        }
    }
    (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.0)
}

/// A round factor (1, 2, 5, 10, …) that makes the largest deviation about 2 % of the drawing: deviations
/// of a few hundredths of a millimetre are invisible on a 150 mm print otherwise.
fn exaggeration(extent: f64, max_deviation: f64) -> f64 {
    if !(max_deviation > 0.0 && extent > 0.0) {
        return 1.0;
    }
    let wanted = 0.02 * extent / max_deviation;
    let mut factor = 1.0;
    for step in [2.0, 2.5, 2.0].iter().cycle().take(30) {
        if factor * step > wanted {
            break;
        }
        factor *= step;
    }
    factor
}

fn grey_line(points: Vec<[f64; 2]>) -> Layer {
    Layer::Polyline {
        points,
        colour: Rgb(170, 170, 170),
        width: 4.0,
    }
}

/// Largest deviation per cell over the bed, from the deposited path.
pub fn deviation_map(path: &[PathPoint], title: &str) -> Result<Option<Figure>, SimulationError> {
    let dep: Vec<&PathPoint> = path.iter().filter(|p| p.deposited).collect();
    if dep.is_empty() {
        return Ok(None);
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &dep {
        for k in 0..2 {
            lo[k] = lo[k].min(p.intended[k]);
            hi[k] = hi[k].max(p.intended[k]);
        }
    }
    let cell = ((hi[0] - lo[0]).max(hi[1] - lo[1]) / HEAT_CELLS).max(0.5);
    let nx = ((hi[0] - lo[0]) / cell).floor() as usize + 1;
    let ny = ((hi[1] - lo[1]) / cell).floor() as usize + 1;
    let mut values: Vec<Option<f64>> = vec![None; nx * ny];
    for p in &dep {
        let ix = (((p.intended[0] - lo[0]) / cell) as usize).min(nx - 1);
        let iy = (((p.intended[1] - lo[1]) / cell) as usize).min(ny - 1);
        let v = &mut values[iy * nx + ix];
        *v = Some(v.map_or(p.deviation, |old| old.max(p.deviation)));
    }
    let scale = ColourScale::fit(values.iter().flatten().copied(), "max path deviation (mm)");
    let grid = Grid::new(lo[0], lo[1], cell, nx, ny, values)?;
    let mut fig = Figure::new(format!("Deviation over the bed, {title}"));
    fig.notes.push(format!(
        "{cell:.2} mm cells; empty cells: nothing deposited"
    ));
    fig = fig.with_layer(Layer::Heatmap {
        grid,
        scale: scale.clone(),
    });
    fig.colour_bar = Some(scale);
    Ok(Some(fig))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exaggeration_is_a_round_factor() {
        assert_eq!(exaggeration(150.0, 1.0), 2.0);
        assert_eq!(exaggeration(150.0, 0.01), 200.0);
        assert_eq!(exaggeration(150.0, 5.0), 1.0);
        assert_eq!(exaggeration(0.0, 1.0), 1.0);
    }
}
