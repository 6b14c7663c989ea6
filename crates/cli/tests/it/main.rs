//! Integration tests of the `jointspace` binary: the bad-input catalogue, limits that must hold (memory,
//! time, determinism, interruption) and fuzz regressions. Every test runs the built binary as a user would.

mod catalogue;
mod check;
mod common;
mod determinism;
mod fuzz_regressions;
mod host;
mod interrupt;
mod json;
mod limits;
mod output;
