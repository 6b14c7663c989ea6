//! The figure model (layers in data coordinates, mm) and its layout: plot area with equal aspect, axes with
//! tick labels, title, colour bar, legend. Rendering goes through [`Canvas`], so SVG and PNG look the same.

use std::path::Path;

use crate::canvas::{Anchor, Canvas};
use crate::colour::{ColourScale, Rgb};
use crate::error::PlotError;

/// A regular grid of values; `values[iy * nx + ix]` covers
/// `[x_min + ix·cell, x_min + (ix+1)·cell] × [y_min + iy·cell, …]`. `None` cells are drawn grey.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid<T = f64> {
    pub x_min: f64,
    pub y_min: f64,
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    pub values: Vec<Option<T>>,
}

impl<T> Grid<T> {
    /// Checks that the value count matches the size.
    pub fn new(
        x_min: f64,
        y_min: f64,
        cell: f64,
        nx: usize,
        ny: usize,
        values: Vec<Option<T>>,
    ) -> Result<Self, PlotError> {
        if values.len() != nx * ny || nx == 0 || ny == 0 {
            return Err(PlotError::GridSize {
                nx,
                ny,
                len: values.len(),
            });
        }
        Ok(Grid {
            x_min,
            y_min,
            cell,
            nx,
            ny,
            values,
        })
    }

    fn extent(&self) -> [f64; 4] {
        [
            self.x_min,
            self.x_min + self.nx as f64 * self.cell,
            self.y_min,
            self.y_min + self.ny as f64 * self.cell,
        ]
    }
}

/// One thing drawn in data coordinates.
#[derive(Debug, Clone, PartialEq)]
pub enum Layer {
    /// Values coloured by `scale`; empty cells grey.
    Heatmap { grid: Grid<f64>, scale: ColourScale },
    /// Category indices into `palette`; empty cells grey.
    Categories {
        grid: Grid<usize>,
        palette: Vec<Rgb>,
    },
    Polyline {
        points: Vec<[f64; 2]>,
        colour: Rgb,
        width: f64,
    },
    /// Separate segments, each coloured by its value on `scale` (paths, errors along a print).
    Segments {
        segments: Vec<[[f64; 2]; 2]>,
        values: Vec<f64>,
        scale: ColourScale,
        width: f64,
    },
    Circle {
        centre: [f64; 2],
        radius: f64,
        colour: Rgb,
        width: f64,
    },
    Rectangle {
        min: [f64; 2],
        max: [f64; 2],
        colour: Rgb,
        width: f64,
    },
    /// Dots of a fixed pixel radius.
    Points {
        points: Vec<[f64; 2]>,
        colour: Rgb,
        radius_px: f64,
    },
    Text {
        at: [f64; 2],
        text: String,
        colour: Rgb,
        size: f64,
    },
}

/// Coloured squares with labels, in the right margin.
#[derive(Debug, Clone, PartialEq)]
pub struct Legend {
    pub entries: Vec<(String, Rgb)>,
}

/// A picture: title, axes, layers, optional colour bar and legend.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    pub title: String,
    /// Smaller lines under the title (summary numbers).
    pub notes: Vec<String>,
    pub x_label: String,
    pub y_label: String,
    pub width: u32,
    pub height: u32,
    pub layers: Vec<Layer>,
    pub colour_bar: Option<ColourScale>,
    pub legend: Option<Legend>,
    /// `[x_min, x_max, y_min, y_max]` shown; `None`: the extent of the layers.
    pub view: Option<[f64; 4]>,
    /// Same scale on both axes (geometry); otherwise the plot area is filled.
    pub equal_aspect: bool,
}

impl Figure {
    /// An empty 900×800 figure with mm axes and equal aspect.
    pub fn new(title: impl Into<String>) -> Self {
        Figure {
            title: title.into(),
            notes: Vec::new(),
            x_label: "x (mm)".into(),
            y_label: "y (mm)".into(),
            width: 900,
            height: 800,
            layers: Vec::new(),
            colour_bar: None,
            legend: None,
            view: None,
            equal_aspect: true,
        }
    }

    pub fn with_layer(mut self, layer: Layer) -> Self {
        self.layers.push(layer);
        self
    }

    /// The figure as an SVG document.
    pub fn to_svg(&self) -> Result<String, PlotError> {
        self.check_size()?;
        let mut svg = crate::svg::SvgCanvas::new(self.width, self.height);
        self.draw(&mut svg);
        Ok(svg.finish())
    }

    pub fn write_svg(&self, path: &Path) -> Result<(), PlotError> {
        Ok(outfile::write_bytes(path, self.to_svg()?.as_bytes())?)
    }

    /// The figure as PNG bytes.
    pub fn to_png(&self) -> Result<Vec<u8>, PlotError> {
        self.check_size()?;
        crate::png_out::render(self.width, self.height, |canvas| self.draw(canvas))
    }

    pub fn write_png(&self, path: &Path) -> Result<(), PlotError> {
        Ok(outfile::write_bytes(path, &self.to_png()?)?)
    }

    fn check_size(&self) -> Result<(), PlotError> {
        let ok = (200..=8000).contains(&self.width) && (150..=8000).contains(&self.height);
        if ok {
            Ok(())
        } else {
            Err(PlotError::BadSize {
                width: self.width,
                height: self.height,
            })
        }
    }

    /// Draws everything onto `c`.
    pub fn draw(&self, c: &mut dyn Canvas) {
        let (w, h) = (self.width as f64, self.height as f64);
        c.fill_rect(0.0, 0.0, w, h, Rgb::WHITE);
        let frame = self.plot_frame();
        let view = self.view.unwrap_or_else(|| padded(self.layer_extent()));
        let t = Transform::fit(frame, view, self.equal_aspect);
        self.draw_grid_lines(c, &t);
        for layer in &self.layers {
            draw_layer(c, &t, layer);
        }
        self.draw_axes(c, &t);
        self.draw_titles(c, &t);
        let side_x = t.px1 + 28.0;
        let mut side_y = t.py0;
        if let Some(legend) = &self.legend {
            side_y = draw_legend(c, legend, side_x, side_y) + 24.0;
        }
        if let Some(scale) = &self.colour_bar {
            draw_colour_bar(c, scale, side_x, side_y.max(t.py0) + 22.0, t.py1);
        }
    }

    /// Pixel box available for the plot: `[left, top, right, bottom]`.
    fn plot_frame(&self) -> [f64; 4] {
        let top = 58.0 + 18.0 * self.notes.len() as f64;
        let right = if self.colour_bar.is_some() || self.legend.is_some() {
            190.0
        } else {
            30.0
        };
        [
            84.0,
            top,
            self.width as f64 - right,
            self.height as f64 - 62.0,
        ]
    }

    fn layer_extent(&self) -> [f64; 4] {
        let mut e = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut add = |x: f64, y: f64| {
            if x.is_finite() && y.is_finite() {
                e = [e[0].min(x), e[1].max(x), e[2].min(y), e[3].max(y)];
            }
        };
        for layer in &self.layers {
            match layer {
                Layer::Heatmap { grid, .. } => {
                    let g = grid.extent();
                    add(g[0], g[2]);
                    add(g[1], g[3]);
                }
                Layer::Categories { grid, .. } => {
                    let g = grid.extent();
                    add(g[0], g[2]);
                    add(g[1], g[3]);
                }
                Layer::Polyline { points, .. } | Layer::Points { points, .. } => {
                    points.iter().for_each(|p| add(p[0], p[1]));
                }
                Layer::Segments { segments, .. } => {
                    segments.iter().flatten().for_each(|p| add(p[0], p[1]))
                }
                Layer::Circle { centre, radius, .. } => {
                    add(centre[0] - radius, centre[1] - radius);
                    add(centre[0] + radius, centre[1] + radius);
                }
                Layer::Rectangle { min, max, .. } => {
                    add(min[0], min[1]);
                    add(max[0], max[1]);
                }
                Layer::Text { at, .. } => add(at[0], at[1]),
            }
        }
        if e[0] > e[1] { [0.0, 1.0, 0.0, 1.0] } else { e }
    }

    fn draw_grid_lines(&self, c: &mut dyn Canvas, t: &Transform) {
        c.fill_rect(t.px0, t.py0, t.px1, t.py1, Rgb(250, 250, 250));
        for x in nice_ticks(t.view[0], t.view[1], 8) {
            c.polyline(&[(t.x(x), t.py0), (t.x(x), t.py1)], Rgb::GRID, 1.0);
        }
        for y in nice_ticks(t.view[2], t.view[3], 8) {
            c.polyline(&[(t.px0, t.y(y)), (t.px1, t.y(y))], Rgb::GRID, 1.0);
        }
    }

    fn draw_axes(&self, c: &mut dyn Canvas, t: &Transform) {
        let frame = [
            (t.px0, t.py0),
            (t.px1, t.py0),
            (t.px1, t.py1),
            (t.px0, t.py1),
            (t.px0, t.py0),
        ];
        c.polyline(&frame, Rgb::AXIS, 1.2);
        let xs = nice_ticks(t.view[0], t.view[1], 8);
        let step = tick_step(&xs);
        for x in &xs {
            let px = t.x(*x);
            c.polyline(&[(px, t.py1), (px, t.py1 + 5.0)], Rgb::AXIS, 1.0);
            c.text(
                px,
                t.py1 + 16.0,
                &format_number(*x, step),
                12.0,
                Rgb::AXIS,
                Anchor::Middle,
            );
        }
        let ys = nice_ticks(t.view[2], t.view[3], 8);
        let step = tick_step(&ys);
        for y in &ys {
            let py = t.y(*y);
            c.polyline(&[(t.px0 - 5.0, py), (t.px0, py)], Rgb::AXIS, 1.0);
            c.text(
                t.px0 - 8.0,
                py,
                &format_number(*y, step),
                12.0,
                Rgb::AXIS,
                Anchor::End,
            );
        }
        c.text(
            (t.px0 + t.px1) / 2.0,
            t.py1 + 38.0,
            &self.x_label,
            14.0,
            Rgb::AXIS,
            Anchor::Middle,
        );
        c.text(
            t.px0 - 8.0,
            t.py0 - 14.0,
            &self.y_label,
            14.0,
            Rgb::AXIS,
            Anchor::Middle,
        );
    }

    fn draw_titles(&self, c: &mut dyn Canvas, _t: &Transform) {
        let mid = self.width as f64 / 2.0;
        c.text(mid, 24.0, &self.title, 20.0, Rgb::BLACK, Anchor::Middle);
        for (i, note) in self.notes.iter().enumerate() {
            c.text(
                mid,
                48.0 + 18.0 * i as f64,
                note,
                13.0,
                Rgb(80, 80, 80),
                Anchor::Middle,
            );
        }
    }
}

/// Data → pixel mapping.
struct Transform {
    view: [f64; 4],
    px0: f64,
    py0: f64,
    px1: f64,
    py1: f64,
    sx: f64,
    sy: f64,
}

impl Transform {
    fn fit(frame: [f64; 4], view: [f64; 4], equal: bool) -> Self {
        let [l, top, r, b] = frame;
        let (dw, dh) = (
            (view[1] - view[0]).max(1e-12),
            (view[3] - view[2]).max(1e-12),
        );
        let (aw, ah) = ((r - l).max(10.0), (b - top).max(10.0));
        let (mut sx, mut sy) = (aw / dw, ah / dh);
        if equal {
            sx = sx.min(sy);
            sy = sx;
        }
        let (w, h) = (dw * sx, dh * sy);
        let px0 = l + (aw - w) / 2.0;
        let py0 = top + (ah - h) / 2.0;
        Transform {
            view,
            px0,
            py0,
            px1: px0 + w,
            py1: py0 + h,
            sx,
            sy,
        }
    }

    fn x(&self, x: f64) -> f64 {
        self.px0 + (x - self.view[0]) * self.sx
    }

    fn y(&self, y: f64) -> f64 {
        self.py1 - (y - self.view[2]) * self.sy
    }
}

fn padded(e: [f64; 4]) -> [f64; 4] {
    let pad = 0.02 * (e[1] - e[0]).max(e[3] - e[2]).max(1e-9);
    [e[0] - pad, e[1] + pad, e[2] - pad, e[3] + pad]
}

fn draw_layer(c: &mut dyn Canvas, t: &Transform, layer: &Layer) {
    match layer {
        Layer::Heatmap { grid, scale } => draw_cells(c, t, grid, |v| scale.banded_colour(*v)),
        Layer::Categories { grid, palette } => draw_cells(c, t, grid, |i| {
            palette.get(*i).copied().unwrap_or(Rgb::NO_DATA)
        }),
        Layer::Polyline {
            points,
            colour,
            width,
        } => {
            let px: Vec<(f64, f64)> = points.iter().map(|p| (t.x(p[0]), t.y(p[1]))).collect();
            c.polyline(&px, *colour, *width);
        }
        Layer::Segments {
            segments,
            values,
            scale,
            width,
        } => {
            for (s, v) in segments.iter().zip(values) {
                c.polyline(
                    &[(t.x(s[0][0]), t.y(s[0][1])), (t.x(s[1][0]), t.y(s[1][1]))],
                    scale.colour(*v),
                    *width,
                );
            }
        }
        Layer::Circle {
            centre,
            radius,
            colour,
            width,
        } => {
            c.circle(
                t.x(centre[0]),
                t.y(centre[1]),
                radius * t.sx,
                Some((*colour, *width)),
                None,
            );
        }
        Layer::Rectangle {
            min,
            max,
            colour,
            width,
        } => {
            let (x0, y0, x1, y1) = (t.x(min[0]), t.y(min[1]), t.x(max[0]), t.y(max[1]));
            c.polyline(
                &[(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)],
                *colour,
                *width,
            );
        }
        Layer::Points {
            points,
            colour,
            radius_px,
        } => {
            for p in points {
                c.circle(t.x(p[0]), t.y(p[1]), *radius_px, None, Some(*colour));
            }
        }
        Layer::Text {
            at,
            text,
            colour,
            size,
        } => c.text(t.x(at[0]), t.y(at[1]), text, *size, *colour, Anchor::Start),
    }
}

/// Fills the cells row by row, merging runs of equal colour into one rectangle (small SVGs).
fn draw_cells<T>(c: &mut dyn Canvas, t: &Transform, grid: &Grid<T>, colour: impl Fn(&T) -> Rgb) {
    for iy in 0..grid.ny {
        let row = &grid.values[iy * grid.nx..(iy + 1) * grid.nx];
        let y0 = grid.y_min + iy as f64 * grid.cell;
        let mut ix = 0;
        while ix < grid.nx {
            let fill = row[ix].as_ref().map_or(Rgb::NO_DATA, &colour);
            let mut end = ix + 1;
            while end < grid.nx && row[end].as_ref().map_or(Rgb::NO_DATA, &colour) == fill {
                end += 1;
            }
            let x0 = grid.x_min + ix as f64 * grid.cell;
            let x1 = grid.x_min + end as f64 * grid.cell;
            c.fill_rect(t.x(x0), t.y(y0 + grid.cell), t.x(x1), t.y(y0), fill);
            ix = end;
        }
    }
}

fn draw_legend(c: &mut dyn Canvas, legend: &Legend, x: f64, mut y: f64) -> f64 {
    for (label, colour) in &legend.entries {
        c.fill_rect(x, y, x + 14.0, y + 14.0, *colour);
        c.polyline(
            &[
                (x, y),
                (x + 14.0, y),
                (x + 14.0, y + 14.0),
                (x, y + 14.0),
                (x, y),
            ],
            Rgb::AXIS,
            0.8,
        );
        c.text(x + 20.0, y + 7.0, label, 12.0, Rgb::AXIS, Anchor::Start);
        y += 22.0;
    }
    y
}

fn draw_colour_bar(c: &mut dyn Canvas, scale: &ColourScale, x: f64, top: f64, bottom: f64) {
    let bottom = bottom.max(top + 60.0);
    let width = 18.0;
    c.text(
        x - 6.0,
        top - 16.0,
        &scale.label,
        13.0,
        Rgb::AXIS,
        Anchor::Start,
    );
    let strips = 120;
    let h = (bottom - top) / strips as f64;
    for i in 0..strips {
        let f = (i as f64 + 0.5) / strips as f64;
        let y1 = bottom - i as f64 * h;
        c.fill_rect(x, y1 - h - 0.5, x + width, y1, crate::colour::colour_map(f));
    }
    c.polyline(
        &[
            (x, top),
            (x + width, top),
            (x + width, bottom),
            (x, bottom),
            (x, top),
        ],
        Rgb::AXIS,
        1.0,
    );
    let ticks = if scale.log {
        log_ticks(scale.min, scale.max)
    } else {
        nice_ticks(scale.min, scale.max, 6)
    };
    let step = tick_step(&ticks);
    for v in ticks {
        let y = bottom - scale.fraction(v) * (bottom - top);
        c.polyline(&[(x + width, y), (x + width + 5.0, y)], Rgb::AXIS, 1.0);
        let label = if scale.log {
            format_log(v)
        } else {
            format_number(v, step)
        };
        c.text(x + width + 8.0, y, &label, 12.0, Rgb::AXIS, Anchor::Start);
    }
}

/// Round tick values (1, 2, 5 × 10ᵏ steps) inside `[lo, hi]`, about `target` of them.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return if lo.is_finite() { vec![lo] } else { Vec::new() };
    }
    let raw = (hi - lo) / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last)
        .map(|k| k as f64 * step)
        .map(|v| if v.abs() < step * 1e-9 { 0.0 } else { v })
        .collect()
}

/// Decades (and 2, 5 multiples when the range is short) inside `[lo, hi]`, for log scales.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if lo <= 0.0 || hi <= lo {
        return nice_ticks(lo, hi, 6);
    }
    let (k0, k1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let multiples: &[f64] = if hi / lo <= 1e3 {
        &[1.0, 2.0, 5.0]
    } else {
        &[1.0]
    };
    let mut ticks = Vec::new();
    for k in k0..=k1 {
        for m in multiples {
            let v = m * 10f64.powi(k);
            if v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9) {
                ticks.push(v);
            }
        }
    }
    ticks
}

fn tick_step(ticks: &[f64]) -> f64 {
    match ticks {
        [a, b, ..] => (b - a).abs(),
        [a] => a.abs().max(1.0),
        [] => 1.0,
    }
}

/// A tick label with as many decimals as the tick step needs.
pub fn format_number(v: f64, step: f64) -> String {
    let decimals = if step > 0.0 {
        (-step.log10().floor()).max(0.0) as usize
    } else {
        0
    };
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|ch| ch == '0' || ch == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

fn format_log(v: f64) -> String {
    if (1e-3..1e4).contains(&v) {
        let decimals = (-v.log10().floor()).max(0.0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.0e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_numbers() {
        assert_eq!(
            nice_ticks(-300.0, 300.0, 6),
            vec![-300.0, -200.0, -100.0, 0.0, 100.0, 200.0, 300.0]
        );
        assert_eq!(
            nice_ticks(0.0, 1.0, 5),
            vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        assert_eq!(
            log_ticks(0.002, 0.2),
            vec![0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2]
        );
    }

    #[test]
    fn labels_use_the_decimals_of_the_step() {
        assert_eq!(format_number(0.6000000000000001, 0.2), "0.6");
        assert_eq!(format_number(-0.0, 1.0), "0");
        assert_eq!(format_number(150.0, 50.0), "150");
        assert_eq!(format_log(0.005), "0.005");
        assert_eq!(format_log(1e-5), "1e-5");
    }

    #[test]
    fn grid_size_is_checked() {
        assert!(Grid::<f64>::new(0.0, 0.0, 1.0, 2, 2, vec![None; 3]).is_err());
        assert!(Grid::<f64>::new(0.0, 0.0, 1.0, 2, 2, vec![Some(1.0); 4]).is_ok());
    }
}
