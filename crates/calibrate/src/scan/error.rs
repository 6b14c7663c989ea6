//! What can go wrong in a scan, from the hardware to the fit.

/// Failure reported by scan hardware (real or simulated).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct HardwareError(pub String);

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScanError {
    #[error("hardware: {0}")]
    Hardware(#[from] HardwareError),
    #[error("invalid scan parameter: {0}")]
    InvalidParams(String),
    #[error("no magnet found between arm {from:.2} mm and {to:.2} mm")]
    NoMagnetFound { from: f64, to: f64 },
    #[error("only {found} magnets were seen on both sides of the centre; at least 3 are needed")]
    TooFewPairs { found: usize },
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    #[error(
        "the scan recorded no sensor readings (no ADC data: batch mode, or the sensor is not reporting)"
    )]
    NoSamples,
    #[error("the Hall sensor saturates: {0}")]
    Saturated(String),
    #[error("the {side} side of the scan shows {found} magnets, the ring has {expected}")]
    WrongMagnetCount {
        side: String,
        found: usize,
        expected: usize,
    },
    #[error("the magnet at {angle_deg:.1}° on the {side} side cannot be peaked: {why}")]
    BadPeak {
        side: String,
        angle_deg: f64,
        why: String,
    },
    #[error("the fit is poor: {0}")]
    BadFit(String),
    #[error("cannot read or write the result file {path}: {message}")]
    File { path: String, message: String },
}
