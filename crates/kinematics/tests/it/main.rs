//! Integration tests of the kinematics crate: property tests over random machines, closed-form cases,
//! whole-segment checks, consistency with Klipper's golden data, and workspace maps.

mod closed_form;
mod fivebar;
mod fivebar_curves;
mod golden;
mod machines;
mod roundtrip;
mod segment;
mod workspace;
