//! `jointspace workspace`: where the machine reaches, and how fine its motion is across the bed.

use crate::machine::load_machine;
use crate::maps::map_and_draw;
use crate::report;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Printer configuration (Klipper's printer.cfg format).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// Folder for the pictures (PNG and SVG).
    #[arg(short = 'o', long = "out", default_value = "workspace")]
    pub out: PathBuf,
    /// Grid cell size (mm).
    #[arg(long, default_value_t = 2.0)]
    pub cell: f64,
    /// Print the numbers as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let machine = load_machine(&args.config)?;
    if !(args.cell > 0.05 && args.cell.is_finite()) {
        return Err(miette::miette!("--cell must be at least 0.05 mm"));
    }
    crate::output::directory_output(&args.out).map_err(super::plain)?;
    let figures = map_and_draw(&machine.config.params, args.cell, &args.out, "workspace")?;
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&figures).map_err(|e| miette::miette!("{e}"))?
        );
    } else {
        crate::out!("{}", report::workspace(&figures));
    }
    Ok(ExitCode::SUCCESS)
}
