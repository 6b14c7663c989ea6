//! `jointspace`: the command-line front end. It only wires the library crates together: each subcommand
//! turns its flags into a validated configuration, runs the pipeline, and renders errors as diagnostics.

mod cmd;
mod diag;
mod input;
mod interrupt;
mod machine;
mod magnets;
mod maps;
mod output;
mod report;
mod scan_picture;
mod timing;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// `jointspace --version`: the release and the commit it was built from (build.rs; "unknown" without git).
const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (",
    env!("JOINTSPACE_COMMIT"),
    ")"
);

#[derive(Debug, Parser)]
#[command(
    name = "jointspace",
    version = VERSION,
    about = "Motion host and toolkit for SCARA and polar 3D printers"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the whole pipeline on the bundled example machines and prints; report and pictures in --out.
    Demo(cmd::demo::Args),
    /// Summarise a G-code file: lines, commands, moves, extrusion, bounding box, layers.
    Stats(cmd::stats::Args),
    /// Plan a print and compute every motor step: print time, steps and peak step rates per motor.
    Run(cmd::run::RunArgs),
    /// Check a print against a machine without generating steps: reach, limits, slow moves.
    Check(cmd::run::CheckArgs),
    /// The time the printer will take (plan only): by layer, feature type and machine limit, beside the slicer's.
    Estimate(cmd::estimate::Args),
    /// The planned print as one self-contained HTML page: toolpath, limits, motors against time, the estimate.
    View(cmd::view::Args),
    /// Rewrite a G-code file's M73 progress lines and time comments with the planned times (slicer post-processing).
    PostProcess(cmd::post_process::Args),
    /// Draw where the machine reaches and its resolution (mm per motor step) across the bed.
    Workspace(cmd::workspace::Args),
    /// Rewrite G-code for firmware without these kinematics (radius/angle or joint angles), with a bounded path error.
    Convert(cmd::convert::Args),
    /// Calibrate: the polar bed's rotation centre, SCARA arm geometry, or a five-bar's geometry.
    #[command(subcommand)]
    Calibrate(cmd::calibrate::Command),
    /// Simulate the printer as built (with assembly errors): the deformation of a print, and its correction.
    Simulate(cmd::simulate::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Diagnostics stay on one line each, so they can be searched and compared.
    let _ = miette::set_hook(Box::new(|_| {
        // Without colours: the whole diagnostic passes `output::printable` (escape sequences in a G-code file must
        // not reach the terminal), which would escape miette's own colour codes too.
        Box::new(
            miette::MietteHandlerOpts::new()
                .wrap_lines(false)
                .color(false)
                .build(),
        )
    }));
    if let Err(e) = interrupt::install() {
        eprintln!("warning: {e}");
    }
    let result = match cli.command {
        Command::Demo(args) => cmd::demo::run(args),
        Command::Stats(args) => cmd::stats::run(args),
        Command::Run(args) => cmd::run::run(args),
        Command::Check(args) => cmd::run::check(args),
        Command::Estimate(args) => cmd::estimate::run(args),
        Command::View(args) => cmd::view::run(args),
        Command::PostProcess(args) => cmd::post_process::run(args),
        Command::Workspace(args) => cmd::workspace::run(args),
        Command::Convert(args) => cmd::convert::run(args),
        Command::Calibrate(command) => cmd::calibrate::run(command),
        Command::Simulate(args) => cmd::simulate::run(args),
    };
    match result {
        Ok(code) => code,
        Err(_) if interrupt::requested() => {
            eprintln!("{}", interrupt::INTERRUPTED_MESSAGE);
            ExitCode::from(interrupt::INTERRUPTED_EXIT_CODE as u8)
        }
        Err(report) => {
            eprintln!("{}", output::printable(&format!("{report:?}")));
            ExitCode::FAILURE
        }
    }
}
