//! Pictures for jointspace: a small figure model (layers in data coordinates: heat maps, polylines,
//! coloured segments, circles, points, text, colour bar, legend) rendered to SVG by our own writer and to
//! PNG through plotters' bitmap backend with the bundled DejaVu Sans font (no system fontconfig).
//!
//! This crate knows nothing of machines: it takes plain data (grids of `Option<f64>`, points, labels).
//! [`workspace`] turns a workspace map given as plain data into the reach and resolution pictures.

pub mod canvas;
pub mod colour;
mod error;
pub mod figure;
mod png_out;
mod svg;
pub mod workspace;

pub use colour::{ColourScale, Rgb};
pub use error::PlotError;
pub use figure::{Figure, Grid, Layer, Legend};

/// A picture (8-bit RGB, `width × height`) with `draw`'s marks over it, as PNG bytes: a scan with what was found
/// on it.
pub fn overlay_png(
    rgb: Vec<u8>,
    width: u32,
    height: u32,
    draw: impl FnOnce(&mut dyn canvas::Canvas),
) -> Result<Vec<u8>, PlotError> {
    png_out::render_over(rgb, width, height, draw)
}
