//! `jointspace run` (plan + every motor step) and `jointspace check` (plan only, list every problem).

use crate::machine::{HostArg, load_machine};
use crate::{diag, input, report};
use printjob::{PlanOptions, RunError, RunOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Printer configuration (Klipper's printer.cfg format).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// G-code file (`-` for standard input).
    pub file: PathBuf,
    /// Write one step file per motor into DIR: a line `clock dir` per step (dir 1 = position increases).
    #[arg(long, value_name = "DIR")]
    pub steps: Option<PathBuf>,
    /// Write the planned moves as CSV (the columns of Klipper's trapq_append).
    #[arg(long, value_name = "FILE")]
    pub moves: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// MCU clock frequency used for step clocks.
    #[arg(long, default_value_t = 16_000_000.0, value_name = "HZ")]
    pub clock_hz: f64,
    /// Skip unreachable moves (reported as warnings) instead of stopping at the first.
    #[arg(long)]
    pub skip_unreachable: bool,
    /// Reproduce Klipper's batch-mode flushing (`klippy.py -i`), for comparisons with Klipper's output.
    #[arg(long)]
    pub klipper_batch: bool,
    /// The host whose planning to reproduce: `klipper`, or `kalico-fekt` (the FEKT-SCARA fork: no Z speed limits,
    /// first move at 0.251 s).
    #[arg(long, value_enum, default_value_t = HostArg::Klipper)]
    pub host: HostArg,
}

#[derive(Debug, clap::Args)]
pub struct CheckArgs {
    /// Printer configuration (Klipper's printer.cfg format).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// G-code file (`-` for standard input).
    pub file: PathBuf,
    /// Most problems to list.
    #[arg(long, default_value_t = 200)]
    pub max_problems: usize,
    /// Print the problems and totals as JSON.
    #[arg(long)]
    pub json: bool,
}

impl RunArgs {
    fn options(&self) -> RunOptions {
        RunOptions {
            steps: self.steps.clone(),
            moves: self.moves.clone(),
            clock_hz: self.clock_hz,
            plan: PlanOptions {
                skip_unreachable: self.skip_unreachable,
                klipper_batch: self.klipper_batch,
                host: self.host.into(),
            },
        }
    }
}

pub fn run(args: RunArgs) -> miette::Result<ExitCode> {
    if !(args.clock_hz > 0.0 && args.clock_hz.is_finite()) {
        return Err(miette::miette!("--clock-hz must be a positive number"));
    }
    let machine = load_machine(&args.config)?;
    let options = args.options();
    if let Some(dir) = &options.steps {
        crate::output::directory_output(dir).map_err(super::plain)?;
    }
    let (reader, name, bar) = input::open_gcode(&args.file).map_err(super::plain)?;
    let result = printjob::run(
        &machine,
        reader,
        &name,
        &options,
        crate::interrupt::requested,
    );
    bar.finish_and_clear();
    let summary = result.map_err(|e| {
        let (place, message, report) = run_error(&machine, &args.file, &options, e);
        if args.json {
            super::print_json_error(&name, place, &message);
        }
        report
    })?;
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&summary).map_err(|e| miette::miette!("{e}"))?
        );
    } else {
        crate::out!("{}", report::run_summary(&summary));
    }
    Ok(ExitCode::SUCCESS)
}

/// A failed run as a diagnostic, with the G-code line and column it comes from when it has one, and its message.
fn run_error(
    machine: &printjob::Machine,
    file: &Path,
    options: &RunOptions,
    e: RunError,
) -> (Option<(u64, u32)>, String, miette::Report) {
    match e {
        RunError::Plan(e) => (Some(e.place()), e.message(), diag::pipeline_error(file, e)),
        RunError::Steps(e) => {
            let line = printjob::audit::locate(machine, options.plan, file, e.time);
            let report = diag::step_stream_error(file, line, &e);
            (line.map(|line| (line, 1)), e.to_string(), report)
        }
        other => (None, other.to_string(), miette::miette!("{other}")),
    }
}

pub fn check(args: CheckArgs) -> miette::Result<ExitCode> {
    let machine = load_machine(&args.config)?;
    let (reader, name, bar) = input::open_gcode(&args.file).map_err(super::plain)?;
    let mut report = printjob::check_gcode(&machine.setup, reader, &name, args.max_problems);
    bar.finish_and_clear();
    if report.errors() == 0
        && let Some(problem) = printjob::audit_file(&machine, &args.file, &name)
    {
        report.push(problem);
    }
    if args.json {
        print_check_json(&name, &report);
    } else {
        print_check_text(&name, &report);
    }
    Ok(if report.errors() > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

fn print_check_json(name: &str, report: &printjob::CheckReport) {
    let problems: Vec<serde_json::Value> = report
        .problems
        .iter()
        .map(|p| {
            serde_json::json!({
                "line": p.span.line,
                "column": p.span.column,
                "severity": p.severity.label(),
                "message": p.message,
            })
        })
        .collect();
    let value = serde_json::json!({
        "file": name,
        "errors": report.errors(),
        "warnings": report.warning_count,
        "print_time_s": report.end_time,
        "slowed_moves": report.slow_moves,
        "problems": problems,
        "motor_travel": report::motor_travel_json(&report.envelope),
        "closest_to_special_poses": report::closest_json(&report.envelope),
    });
    crate::outln!(
        "{}",
        serde_json::to_string_pretty(&value).unwrap_or_default()
    );
}

fn print_check_text(name: &str, report: &printjob::CheckReport) {
    for p in &report.problems {
        crate::outln!(
            "{name}:{}:{}: {}: {}",
            p.span.line,
            p.span.column,
            p.severity.label(),
            p.message
        );
    }
    crate::outln!(
        "{name}: {} errors, {} warnings; {:.1} s of printing planned; {} moves slowed hard",
        report.errors(),
        report.warning_count,
        report.end_time,
        report.slow_moves
    );
    crate::out!("{}", report::envelope(&report.envelope));
}
