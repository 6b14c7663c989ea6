//! Calibration for turning-axis printers: circle fits, the polar centre scan (over a hardware trait) and SCARA and
//! five-bar geometry identification by Levenberg–Marquardt (their shared pieces: `lsq`, `measured`, `verdict`).

pub mod circle;
mod csv;
pub mod fivebar;
pub mod lsq;
pub mod measured;
pub mod scan;
pub mod scara;
pub mod sweep;
pub mod verdict;

pub use circle::{Circle, CircleError, CircleFit, Point};
pub use scan::{CentreResult, PeakMethod, ScanError, ScanHardware, ScanParams};
