//! Five-bar (parallel SCARA) geometry identification from a printed pattern measured by hand: the model and its
//! analytic Jacobian (`model`), the fit, identifiability and verdict (`fit`, over the shared `crate::lsq` and
//! `crate::verdict`), the measurements file (`measurements`) and the pattern made through the machine's own
//! kinematics (`pattern`).
//!
//! Parameters (the printer.cfg keys): each side's base joint (x, y), proximal and distal length and zero. The
//! working mode (arm turns, distal turn) is an assembly choice, not fitted.
//!
//! Gauge: the crosses are measured in the bed frame (the G-code's X and Y, from the bed's origin and edges). That
//! frame fixes the machine's place and turn on the bed, so all ten parameters are identified from a good pattern:
//! a turn of the whole machine moves the printed points and is seen. What the measurements fix is stated by the
//! identifiability analysis, which the fit reports twice: in the bed frame (the fit's terms: any combination the
//! poses leave undetermined is refused, never silently fitted), and for measurements that would fix no frame
//! (relative positions only), where the frame's shift is not separable from the base positions and its turn from
//! the bases and zeros together: three combinations not identified.

mod fit;
mod measurements;
mod model;
mod pattern;

pub use fit::{
    FRAME_NAMES, Identification, PARAMETERS, analyse_free_frame, analyse_poses, identify, judge,
    suggest_poses,
};
pub use measurements::{CSV_HEADER, measurement_template, parse_measurements, parse_poses};
pub use model::{ArmGeometry, FivebarGeometry, PARAM_NAMES};
pub use pattern::{DEFAULT_POSES, MIN_POSES, Pattern, machine_pattern};

pub use crate::measured::Measurement;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FivebarError {
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("{got} measurements give {} equations for 10 parameters; need at least 5 poses", 2 * got)]
    TooFewMeasurements { got: usize },
    #[error("the poses cannot identify: {0}")]
    Unidentifiable(String),
    #[error("the fit did not converge: {0}")]
    NoConvergence(String),
    #[error("non-finite value in measurement {}", index + 1)]
    NonFinite { index: usize },
    #[error(
        "pose {} has no nozzle in the configured geometry, or its distal links are in line there: not a pose this \
         machine prints (a pattern of another configuration?)", index + 1
    )]
    Degenerate { index: usize },
    #[error("{0}")]
    Pattern(String),
}
