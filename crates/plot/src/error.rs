//! Why a picture could not be made or written.

use std::path::PathBuf;

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
