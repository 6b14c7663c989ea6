//! Integration tests of the plot crate: figures render to PNG that decodes and SVG that is well-formed,
//! and real workspace maps produce every expected file.

mod figures;
mod glue;
mod maps;
mod wellformed;
