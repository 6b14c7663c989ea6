//! The polar centre scan: an algorithm over a small hardware trait that finds every bed magnet with the Hall
//! sensor, peaks each one with sub-step interpolation, and turns the magnet detections into the arm's zero
//! offset `dx` and lateral offset `dy` relative to the bed's rotation centre.
//!
//! # Conventions: the machine's own (`kinematics::polar`, Klipper's polar, what `convert` writes)
//! Machine frame: origin on the bed's rotation axis, +x along the arm. With the arm reading `r` the sensor
//! (aligned with the nozzle) sits at `N(r) = (r + dx, dy)`: `dx` = `arm_zero_offset` (where the arm's zero
//! really is, along the arm), `dy` = `arm_lateral_offset` (sideways offset of the arm's line). The bed angle
//! `θ` is the bed motor's reading with the kinematics' sign: the bed point under the sensor is
//! `p = Rot(θ)·N(r)` (an ideal machine puts bed point `(r cos θ, r sin θ)` under the nozzle, as
//! `kinematics::polar` and Klipper's polar do; `convert` writes this `θ`). So a magnet `m` (bed frame) is
//! under the sensor when `m = Rot(θ)·(r + dx, dy)`: the polar inverse `θ = atan2(m) − atan2(dy, dx + r)`.
//! Physically the bed has turned by `−θ`; logs that record the physical rotation must negate it.
//!
//! # What a scan can observe
//! Seen from one side of the centre only, every magnet gives `(r + dx)² + dy² = ρ²` and an angle that is
//! confounded with the (declared) bed zero: `dx` and `dy` cannot be separated from the unknown magnet
//! radii. The scan therefore peaks every magnet twice, on the near side (`r⁺ ≈ ρ`) and on the far side of
//! the centre (`r⁻ ≈ −ρ`, bed turned by ≈ π). For one magnet, exactly and independently of where it was
//! placed: `dx = −(r⁺ + r⁻)/2`, `h = (r⁺ − r⁻)/2`, `θ⁺ − θ⁻ = π − 2·atan(dy/h)`. The per-magnet pairs are
//! combined robustly (median screen, then mean and covariance). The magnet map (each magnet in the bed frame
//! with the fitted offsets) gets a robust geometric circle fit, which gives the ring's own eccentricity and
//! per-magnet residuals for the plot. The arm must reach `−ρ` (`arm_min`); a machine whose arm passes the
//! centre only a little can use a small inner ring (e.g. 4 magnets at 10 mm, tested), and one whose arm
//! cannot pass the centre at all cannot separate `dx` from the ring radius nor measure `dy` with this
//! sensor: the scan refuses such parameters instead of guessing.
//!
//! # Layout
//! - `hardware`: what the scan needs from a machine ([`ScanHardware`]) and the scan's clock over it.
//! - `params`: the settings ([`ScanParams`], [`PeakMethod`]) and their checks.
//! - `search`: the stop-and-read plan ([`scan_centre`]): first magnet, the near ring, the far side.
//! - `peaks`: one magnet's centre from sensor profiles or the thesis' comparator grid.
//! - `fit`: detections → pair offsets, robust combination, magnet map, flags ([`centre_from_detections`]).
//! - `result`: the result ([`CentreResult`]) and its JSON file; `detections`: the detections CSV file.
//! - `tilt`: the sensor's tilt measured by a second scan at another height and removed ([`remove_tilt`]).
//! - `error`: [`ScanError`].

mod detections;
mod error;
mod fit;
mod hardware;
mod params;
mod peaks;
mod result;
mod search;
mod tilt;

pub use detections::{
    DETECTIONS_HEADER, DETECTIONS_PREAMBLE, DetectionSlots, parse_detections, write_detections,
};
pub use error::{HardwareError, ScanError};
pub(crate) use fit::median;
pub use fit::{centre_from_detections, centre_from_ring, pair_offsets};
pub use hardware::{ScanHardware, trapezoid_time};
pub use params::{PeakMethod, ScanParams};
pub(crate) use peaks::parabola_vertex;
pub use result::{CentreResult, Detection, MagnetMapPlot, MagnetRecord, TiltCorrection};
pub use search::scan_centre;
pub use tilt::{remove_tilt, with_tilt_removed};
