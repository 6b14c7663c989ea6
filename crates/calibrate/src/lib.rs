//! Calibration for turning-axis printers: circle fits, the polar centre scan (over a hardware trait) and SCARA
//! geometry identification by Levenberg–Marquardt.

pub mod circle;
mod csv;
pub mod scan;
pub mod scara;
pub mod sweep;

pub use circle::{Circle, CircleError, CircleFit, Point};
pub use scan::{CentreResult, PeakMethod, ScanError, ScanHardware, ScanParams};
