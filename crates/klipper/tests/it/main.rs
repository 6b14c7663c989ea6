//! The plug-in inside the real hosts: Klipper, Kalico and the FEKT-SCARA fork from `../shared/klipper`, run in
//! batch mode, compared with their own kinematics, with the FEKT golden steps and with jointspace's own engine.
//! Plus the library's own contract (struct layout against each host's header, solvers against closed forms).

// The tests call the library's C interface as the hosts do.
#![allow(unsafe_code)]

mod calibration;
pub mod centre_grid;
mod centre_scan;
mod config_errors;
mod differential;
mod engine;
mod estimate;
mod examples;
mod fivebar;
mod fivebar_grid;
pub mod fivebar_reference;
mod header;
mod homing;
mod hosts;
pub mod install;
mod layout;
mod polar;
mod regressions;
mod routes;
mod scara;
mod scara_grid;
pub mod solvers;
mod splitting;
pub mod wheel;
mod wheel_hosts;
