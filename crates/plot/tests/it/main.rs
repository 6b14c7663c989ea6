//! Integration tests of the plot crate: figures render to PNG that decodes and SVG that is well-formed.
//! (Real workspace maps are drawn and checked by the CLI's `workspace` tests.)

mod figures;
mod wellformed;
