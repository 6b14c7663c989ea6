//! Integration tests of the `jointspace` binary: the bad-input catalogue, limits that must hold (memory,
//! time, determinism, interruption) and fuzz regressions, each running the built binary as a user would; and the
//! tree's structural invariants (`structure.rs`).

mod calibration;
mod catalogue;
mod check;
mod common;
mod determinism;
mod estimate;
mod fivebar;
mod fivebar_calibration;
mod fuzz_regressions;
mod host;
mod includes;
mod interrupt;
mod invariants;
mod json;
mod limits;
mod output;
mod simulate;
mod structure;
mod view;
