//! One module per subcommand.

pub mod calibrate;
pub mod convert;
pub mod demo;
pub mod run;
pub mod simulate;
pub mod stats;
pub mod workspace;

/// Convert an `anyhow` error into a report (plain message, with its causes).
pub fn plain(e: anyhow::Error) -> miette::Report {
    miette::miette!("{e:#}")
}
