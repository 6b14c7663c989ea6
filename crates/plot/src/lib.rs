//! Pictures for jointspace: a small figure model (layers in data coordinates: heat maps, polylines,
//! coloured segments, circles, points, text, colour bar, legend) rendered to SVG by our own writer and to
//! PNG through plotters' bitmap backend with the bundled DejaVu Sans font (no system fontconfig).
//!
//! This crate knows nothing of machines: it takes plain data (grids of `Option<f64>`, points, labels).
//! [`workspace`] turns a workspace map given as plain data into the reach and resolution pictures.

pub mod canvas;
pub mod colour;
pub mod figure;
mod png_out;
mod svg;
pub mod workspace;

use std::path::PathBuf;

pub use colour::{ColourScale, Rgb};
pub use figure::{Figure, Grid, Layer, Legend};

/// Why a picture could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error(transparent)]
    Output(#[from] outfile::OutputError),
    #[error("drawing failed: {0}")]
    Render(String),
    #[error("PNG encoding of {path} failed: {message}")]
    Encode { path: PathBuf, message: String },
    #[error("grid of {nx}×{ny} cells has {len} values")]
    GridSize { nx: usize, ny: usize, len: usize },
    #[error("figure size {width}×{height} px is unusable")]
    BadSize { width: u32, height: u32 },
}
