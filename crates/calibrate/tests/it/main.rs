//! Integration tests of the calibrate crate: circle fits against closed forms, the centre scan on the
//! simulated Hall-sensor printer, and SCARA and five-bar identification on
//! simulated measurements.

mod centre_scan;
mod circle_fits;
mod fivebar_pattern;
mod scan_render;
mod scara_ident;
mod scara_pattern;
mod scara_scan;
mod sweep_scan;
mod tilt_scan;
