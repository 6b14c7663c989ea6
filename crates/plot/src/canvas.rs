//! The drawing surface both outputs implement: pixel coordinates, y downwards.

use crate::colour::Rgb;

/// Horizontal text anchor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Anchor {
    Start,
    Middle,
    End,
}

/// Primitive drawing operations (pixels, origin top left).
pub trait Canvas {
    fn fill_rect(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, fill: Rgb);
    fn polyline(&mut self, points: &[(f64, f64)], colour: Rgb, width: f64);
    fn circle(&mut self, cx: f64, cy: f64, r: f64, stroke: Option<(Rgb, f64)>, fill: Option<Rgb>);
    /// Text with its baseline-centre at `y` (vertically centred on `y`).
    fn text(&mut self, x: f64, y: f64, text: &str, size: f64, colour: Rgb, anchor: Anchor);
}
