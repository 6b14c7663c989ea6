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
