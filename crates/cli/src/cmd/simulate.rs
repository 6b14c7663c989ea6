//! `jointspace simulate`: run a G-code file planned for the believed printer (`-c`) on the printer as built
//! (`--actual`: same keys plus its assembly errors and a `[sim]` motor model), report how far the deposited
//! path strays from the intended one (text, JSON, overlay and heat-map pictures), and with `--correct`
//! calibrate the simulated machine, apply the result to the believed config and simulate again.

use crate::{diag, input};
use sim::report::Stage;
use sim::scenario::{CorrectionSummary, Rejected, Simulation, calibrate_and_correct};
use sim::{Machine, ReplayOptions, Report, RunReport, SimulationError};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The printer as configured (Klipper's printer.cfg format): what the G-code is planned for.
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// The printer as built: the same config with its real geometry (e.g. `arm_lateral_offset`, `ecr`,
    /// `link1_length`) and an optional `[sim]` section (microstep error, backlash, step scale errors).
    #[arg(long, value_name = "ACTUAL_CFG")]
    pub actual: PathBuf,
    /// G-code file.
    pub file: PathBuf,
    /// Report folder (report.txt, report.json, overlay.png/.svg, deviation-map.png).
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub out: PathBuf,
    /// Calibrate the simulated machine (polar: Hall centre scan; SCARA: measured pattern + identification),
    /// apply the result and simulate again: before/after in one report.
    #[arg(long)]
    pub correct: bool,
    /// Print the report as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Seed of the simulated calibration's random errors (magnet placement, sensor and measurement noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Exit status of a `--correct` run whose report holds the "before" simulation but no "after": the calibration
/// failed, its fit was not trustworthy, or the corrected machine cannot plan the print (the reason is in the
/// report and on standard error).
pub const NO_AFTER_EXIT: u8 = 3;

pub fn run(args: Args) -> miette::Result<ExitCode> {
    if args.correct && args.file == Path::new("-") {
        return Err(miette::miette!(
            "--correct reads the G-code twice: give a file, not standard input"
        ));
    }
    let believed = load_config(&args.config)?;
    let actual_cfg = load_config(&args.actual)?;
    let actual = Machine::from_config(&actual_cfg).map_err(|e| report_error(&e))?;
    // The G-code is an input too: no report file may replace it (checked before anything is written).
    crate::output::register_input(&args.file);
    crate::output::directory_output(&args.out).map_err(crate::cmd::plain)?;
    for name in sim::report::REPORT_FILES {
        crate::output::refuse_input(&args.out.join(name)).map_err(crate::cmd::plain)?;
    }
    let options = ReplayOptions::default();
    // Each simulation's pictures are drawn as soon as it ends and its path dropped: one path in memory at a time.
    let before = {
        let run = simulate_file(&believed, &actual, &args.file, &options)?;
        sim::report::write_pictures(&args.out, Stage::Before, &run)
            .map_err(|e| report_error(&e))?;
        RunReport::new(&run)
    };
    let (correction, after, after_missing) = if args.correct {
        corrected_run(&args, &believed, &actual, &options)?
    } else {
        (None, None, None)
    };
    let report = Report {
        believed_config: args.config.display().to_string(),
        actual_config: args.actual.display().to_string(),
        gcode: args.file.display().to_string(),
        before,
        correction,
        after,
        after_missing,
    };
    sim::report::write_numbers(&args.out, &report).map_err(|e| report_error(&e))?;
    let text = if args.json {
        let mut json = serde_json::to_string_pretty(&report).map_err(|e| miette::miette!("{e}"))?;
        json.push('\n');
        json
    } else {
        format!(
            "{}report written to {}\n",
            report.text(),
            args.out.display()
        )
    };
    print_stdout(&text)?;
    if let Some(why) = &report.after_missing {
        crate::errln!("warning: the correction was not simulated: {why}");
        return Ok(ExitCode::from(NO_AFTER_EXIT));
    }
    Ok(ExitCode::SUCCESS)
}

/// Calibrate the simulated machine, apply the result and simulate again, its pictures written: the calibration's
/// summary, the "after" numbers, or why there are none.
fn corrected_run(
    args: &Args,
    believed: &config::MachineConfig,
    actual: &Machine,
    options: &ReplayOptions,
) -> miette::Result<(Option<CorrectionSummary>, Option<RunReport>, Option<String>)> {
    let (corrected, summary) = match calibrate_and_correct(believed, actual, args.seed) {
        Ok(done) => done,
        Err(Rejected::Failed(e)) => return Ok((None, None, Some(e.to_string()))),
        Err(Rejected::Untrusted { summary, reason }) => {
            return Ok((Some(*summary), None, Some(reason)));
        }
    };
    let after = match simulate_gcode(&corrected, actual, &args.file, options)? {
        Ok(after) => after,
        Err(e) => {
            let why = format!(
                "the corrected machine cannot run the print: {}",
                error_at(&args.file, &e)
            );
            return Ok((Some(summary), None, Some(why)));
        }
    };
    sim::report::write_pictures(&args.out, Stage::After, &after).map_err(|e| report_error(&e))?;
    Ok((Some(summary), Some(RunReport::new(&after)), None))
}

/// A simulation error as one line, at the G-code file's line and column where it has one.
fn error_at(file: &Path, e: &SimulationError) -> String {
    match e {
        SimulationError::Plan(p) => {
            let (line, column) = p.place();
            format!("{}:{line}:{column}: {}", file.display(), p.message())
        }
        other => other.to_string(),
    }
}

/// Print to standard output; a closed pipe (`| head`) is not an error, the report files are written.
fn print_stdout(text: &str) -> miette::Result<()> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(miette::miette!("cannot write to standard output: {e}"))
        }
        _ => Ok(()),
    }
}

/// Both configs as every command reads them: their warnings shown, unknown keys refused.
fn load_config(path: &Path) -> miette::Result<config::MachineConfig> {
    crate::machine::read_config(path)
}

fn simulate_file(
    believed: &config::MachineConfig,
    actual: &Machine,
    path: &Path,
    options: &ReplayOptions,
) -> miette::Result<Simulation> {
    simulate_gcode(believed, actual, path, options)?.map_err(|e| match e {
        // A planning error names the G-code file, line and column.
        SimulationError::Plan(plan @ printjob::PipelineError::Plan(_)) => {
            diag::pipeline_error(path, plan)
        }
        other => report_error(&other),
    })
}

/// One simulation of the G-code file: the outer error when the file cannot be opened, the inner one when the
/// simulation fails.
fn simulate_gcode(
    believed: &config::MachineConfig,
    actual: &Machine,
    path: &Path,
    options: &ReplayOptions,
) -> miette::Result<Result<Simulation, SimulationError>> {
    let (reader, name, bar) = input::open_gcode(path).map_err(crate::cmd::plain)?;
    let result = sim::simulate(believed, actual, reader, &name, options);
    bar.finish_and_clear();
    Ok(result)
}

/// Diagnostics with the source line where the error has one.
fn report_error(e: &SimulationError) -> miette::Report {
    match e {
        SimulationError::Config(c) => miette::Report::new(diag::config_error(c)),
        SimulationError::Plan(printjob::PipelineError::Gcode(g)) => {
            miette::Report::new(diag::gcode_error(g))
        }
        other => miette::miette!("{other}"),
    }
}
