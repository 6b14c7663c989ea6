//! `jointspace run` (plan + every motor step) and `jointspace check` (plan only, list every problem).

use crate::{diag, input};
use motion::machine::{CheckReport, MachineSetup, Severity, check_gcode, plan_gcode};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;
use stepgen::{
    ExpectedTravel, ExtruderSpec, MotorStats, StepFileWriter, StepGenConfig, StepSink, StepStats,
};

use super::audit::{AuditedMotor, StepStreamError, first_problem, line_at_time, period_of};

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

/// `--host`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum HostArg {
    #[default]
    Klipper,
    KalicoFekt,
}

impl From<HostArg> for motion::Host {
    fn from(h: HostArg) -> Self {
        match h {
            HostArg::Klipper => motion::Host::Klipper,
            HostArg::KalicoFekt => motion::Host::KalicoFekt,
        }
    }
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

/// Load `printer.cfg` and build the machine, with diagnostics pointing into the file.
pub fn load_machine(path: &Path) -> miette::Result<(config::MachineConfig, MachineSetup)> {
    crate::output::register_input(path);
    let machine = config::MachineConfig::load(path)
        .map_err(|e| miette::Report::new(diag::config_error(&e)))?;
    for w in &machine.warnings {
        match &w.span {
            Some(span) => eprintln!("{span}: warning: {}", w.message),
            None => eprintln!("{}: warning: {}", path.display(), w.message),
        }
    }
    for unused in machine.unused_keys() {
        eprintln!(
            "{}: warning: option `{}` in [{}] is not one jointspace knows (a typo?); ignored",
            unused.span, unused.key, unused.section
        );
    }
    let setup = MachineSetup::from_config(&machine)
        .map_err(|e| miette::miette!("{}: {e}", path.display()))?;
    Ok((machine, setup))
}

/// One motor's sink: statistics, plus its step file when asked for.
#[derive(Debug)]
struct MotorSink {
    stats: StepStats,
    file: Option<StepFileWriter>,
}

impl StepSink for MotorSink {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        self.stats.step(clock, dir);
        if let Some(file) = &mut self.file {
            file.step(clock, dir);
        }
    }

    #[inline]
    fn steps(&mut self, clocks: &[u64], dir: bool) {
        self.stats.steps(clocks, dir);
        if let Some(file) = &mut self.file {
            file.steps(clocks, dir);
        }
    }
}

#[derive(Debug, Serialize)]
pub struct MotorSummary {
    pub name: String,
    pub steps: u64,
    pub net_steps: i64,
    pub min_interval_ticks: Option<u64>,
    pub peak_rate_min_interval: Option<f64>,
    pub peak_rate_1ms: f64,
    pub filtered_pairs: u64,
    /// The motor's configured step-rate limit, when set and exceeded.
    pub over_max_step_rate: Option<f64>,
}

#[derive(Debug, Serialize)]
pub struct WarningLine {
    pub line: u64,
    pub column: u32,
    pub message: String,
}

#[derive(Debug, Serialize)]
pub struct RunSummary {
    pub file: String,
    pub config: String,
    pub kinematics: String,
    pub print_time_s: f64,
    pub toolhead_moves: u64,
    pub extruder_moves: u64,
    pub total_steps: u64,
    pub motors: Vec<MotorSummary>,
    pub slowed_moves: u64,
    pub warnings: Vec<WarningLine>,
    pub wall_time_s: f64,
}

/// Counts planned moves on the way through.
#[derive(Debug, Default)]
struct MoveCounter {
    toolhead: u64,
    extruder: u64,
}

impl trapq::MoveSink for MoveCounter {
    fn append(&mut self, queue: trapq::Queue, _mv: &trapq::TrapezoidMove) {
        match queue {
            trapq::Queue::Toolhead => self.toolhead += 1,
            trapq::Queue::Extruder => self.extruder += 1,
        }
    }
}

/// What `run` needs besides the machine and the G-code.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    pub steps: Option<PathBuf>,
    pub moves: Option<PathBuf>,
    pub clock_hz: f64,
    pub skip_unreachable: bool,
    pub klipper_batch: bool,
    pub host: motion::Host,
}

pub fn run(args: RunArgs) -> miette::Result<ExitCode> {
    if !(args.clock_hz > 0.0 && args.clock_hz.is_finite()) {
        return Err(miette::miette!("--clock-hz must be a positive number"));
    }
    let (machine, setup) = load_machine(&args.config)?;
    let options = RunOptions {
        steps: args.steps.clone(),
        moves: args.moves.clone(),
        clock_hz: args.clock_hz,
        skip_unreachable: args.skip_unreachable,
        klipper_batch: args.klipper_batch,
        host: args.host.into(),
    };
    let (reader, name, bar) = input::open_gcode(&args.file).map_err(super::plain)?;
    let result = execute(
        &machine,
        setup,
        reader,
        &name,
        &args.config.display().to_string(),
        &options,
    );
    bar.finish_and_clear();
    let report = result.map_err(|e| {
        let (place, message, report) = match e {
            ExecuteError::Pipeline(e) => {
                let (place, message) = match &e {
                    motion::machine::PipelineError::Gcode(g) => {
                        ((g.span.line, g.span.column), g.kind.to_string())
                    }
                    motion::machine::PipelineError::Plan(p) => {
                        ((p.span.line, p.span.column), p.kind.to_string())
                    }
                };
                (Some(place), message, pipeline_error(&args.file, e))
            }
            ExecuteError::Steps(e) => {
                let line = locate_step_problem(&args.config, &args.file, &options, e.time);
                let place = line.map(|line| (line, 1));
                (
                    place,
                    e.to_string(),
                    step_stream_error(&args.file, line, &e),
                )
            }
            ExecuteError::Other(report) => (None, report.to_string(), report),
        };
        if args.json {
            super::print_json_error(&name, place, &message);
        }
        report
    })?;
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&report).map_err(|e| miette::miette!("{e}"))?
        );
    } else {
        crate::out!("{}", render(&report));
    }
    Ok(ExitCode::SUCCESS)
}

/// Why [`execute`] failed: a planning error (rendered against the G-code file), a step stream no MCU could run,
/// or anything else.
#[derive(Debug)]
pub enum ExecuteError {
    Pipeline(motion::machine::PipelineError),
    Steps(StepStreamError),
    Other(miette::Report),
}

/// One sink per motor: statistics with the step audit, and the step file when `--steps` asks for one.
fn motor_sinks(
    machine: &config::MachineConfig,
    motor_names: &[String],
    options: &RunOptions,
) -> miette::Result<Vec<MotorSink>> {
    let step_dir = options.steps.as_deref();
    if let Some(dir) = step_dir {
        crate::output::directory_output(dir).map_err(super::plain)?;
        std::fs::create_dir_all(dir)
            .map_err(|e| miette::miette!("cannot create {}: {e}", dir.display()))?;
    }
    let mut sinks = Vec::with_capacity(motor_names.len());
    for name in motor_names {
        let file = match step_dir {
            Some(dir) => {
                let path = dir.join(format!("{name}.txt"));
                crate::output::refuse_input(&path).map_err(super::plain)?;
                Some(StepFileWriter::create(path).map_err(|e| miette::miette!("{e}"))?)
            }
            None => None,
        };
        sinks.push(MotorSink {
            stats: StepStats::new(options.clock_hz).audited(max_step_rate(machine, name)),
            file,
        });
    }
    Ok(sinks)
}

/// A stepper's configured step-rate limit (its own, or `[printer]`'s).
fn max_step_rate(machine: &config::MachineConfig, stepper: &str) -> Option<f64> {
    machine
        .stepper(stepper)
        .and_then(|s| s.max_step_rate)
        .or(machine.limits.max_step_rate)
}

/// Every motor's stream through the audit: the first problem, or none.
fn audit_steps(
    sinks: &[MotorSink],
    names: &[String],
    kin: &dyn kinematics::Kinematics,
    extruder_step: Option<f64>,
    (travel, stretches): (Vec<Option<f64>>, u32),
    clock_hz: f64,
) -> Result<(), ExecuteError> {
    let step_distances = kin
        .motors()
        .iter()
        .map(|m| m.step_distance)
        .chain(extruder_step);
    let motors: Vec<AuditedMotor> = sinks
        .iter()
        .zip(names)
        .zip(step_distances)
        .zip(travel)
        .enumerate()
        .map(|(i, (((sink, name), step_distance), expected_travel))| {
            let stats = sink.stats.summary(clock_hz, 0);
            AuditedMotor {
                name,
                problem: sink.stats.problem(),
                net_steps: stats.net_steps,
                step_distance,
                period: period_of(kin, i),
                expected_travel,
                stretches,
                last_time: stats.last_clock.unwrap_or(0) as f64 / clock_hz,
            }
        })
        .collect();
    match first_problem(&motors, clock_hz) {
        Some(problem) => Err(ExecuteError::Steps(problem)),
        None => Ok(()),
    }
}

impl From<miette::Report> for ExecuteError {
    fn from(r: miette::Report) -> Self {
        ExecuteError::Other(r)
    }
}

/// Plan `input` on the machine and generate every motor's steps; the summary of the run.
pub fn execute(
    machine: &config::MachineConfig,
    mut setup: MachineSetup,
    input: impl std::io::BufRead,
    name: &str,
    config_name: &str,
    options: &RunOptions,
) -> Result<RunSummary, ExecuteError> {
    let started = Instant::now();
    setup.planner.skip_unreachable = options.skip_unreachable;
    setup.planner.klipper_batch_flush = options.klipper_batch;
    setup.planner.behave_as(options.host);
    let extruder = machine.extruder.as_ref().map(|e| ExtruderSpec {
        name: e.stepper.name.clone(),
        step_distance: e.stepper.step_distance,
        start_position: 0.0,
    });
    let motor_names: Vec<String> = setup
        .kinematics
        .motors()
        .iter()
        .map(|m| m.name.clone())
        .chain(extruder.iter().map(|e| e.name.clone()))
        .collect();
    let sinks = motor_sinks(machine, &motor_names, options)?;
    let config = StepGenConfig {
        clock_hz: options.clock_hz,
        ..StepGenConfig::default()
    };
    let csv = match &options.moves {
        Some(path) => Some(CsvFile::create(path)?),
        None => None,
    };
    // Planning on this thread, stepping on another: they overlap chunk by chunk.
    let kinematics = setup.kinematics.as_ref();
    let travel = ExpectedTravel::new(kinematics, extruder.is_some());
    let extruder_step = extruder.as_ref().map(|e| e.step_distance);
    let (planned, sinks, filtered) = stepgen::run_in_parallel(
        kinematics,
        extruder,
        config,
        sinks,
        crate::interrupt::requested,
        |sender| {
            // The sender is dropped here, which tells the stepping thread that planning is over.
            let sink = ((sender, (MoveCounter::default(), travel)), csv);
            plan_gcode(&setup, input, name, sink).map(
                |(((_sender, (counter, travel)), csv), summary)| (counter, travel, csv, summary),
            )
        },
    )
    .map_err(|e| miette::miette!("step generation failed: {e}"))?;
    let (counter, travel, csv, summary) = planned.map_err(ExecuteError::Pipeline)?;
    audit_steps(
        &sinks,
        &motor_names,
        kinematics,
        extruder_step,
        travel.finish(),
        options.clock_hz,
    )?;
    if let Some(csv) = csv {
        csv.finish()?;
    }
    let mut motors = Vec::with_capacity(sinks.len());
    for ((sink, name), filtered_pairs) in sinks.into_iter().zip(&motor_names).zip(filtered) {
        if let Some(file) = sink.file {
            file.finish().map_err(|e| miette::miette!("{e}"))?;
        }
        let stats: MotorStats = sink.stats.summary(options.clock_hz, filtered_pairs);
        let limit = max_step_rate(machine, name);
        motors.push(MotorSummary {
            name: name.clone(),
            steps: stats.steps,
            net_steps: stats.net_steps,
            min_interval_ticks: stats.min_interval_ticks,
            peak_rate_min_interval: stats
                .peak_rate_min_interval
                .is_finite()
                .then_some(stats.peak_rate_min_interval),
            peak_rate_1ms: stats.peak_rate_1ms,
            filtered_pairs,
            over_max_step_rate: limit.filter(|l| stats.peak_rate_1ms > *l),
        });
    }
    let mut warnings: Vec<WarningLine> = summary
        .warnings
        .iter()
        .map(|w| WarningLine {
            line: w.span.line,
            column: w.span.column,
            message: w.message.clone(),
        })
        .chain(summary.gcode_warnings.iter().map(|w| WarningLine {
            line: w.span.line,
            column: w.span.column,
            message: w.message.clone(),
        }))
        .collect();
    warnings.sort_by_key(|w| (w.line, w.column));
    Ok(RunSummary {
        file: name.to_string(),
        config: config_name.to_string(),
        kinematics: machine.kinematics.name().to_string(),
        print_time_s: summary.end_time,
        toolhead_moves: counter.toolhead,
        extruder_moves: counter.extruder,
        total_steps: motors.iter().map(|m| m.steps).sum(),
        motors,
        slowed_moves: summary.slow_moves.total,
        warnings,
        wall_time_s: started.elapsed().as_secs_f64(),
    })
}

pub fn render(r: &RunSummary) -> String {
    let mut out = format!("{} on {} ({})\n", r.file, r.config, r.kinematics);
    let total = r.print_time_s.max(0.0);
    out += &format!(
        "  print time   {:.1} s ({}h{:02}m{:02}s)\n",
        total,
        (total / 3600.0) as u64,
        ((total % 3600.0) / 60.0) as u64,
        (total % 60.0) as u64
    );
    out += &format!(
        "  moves        {} toolhead, {} extruder\n",
        r.toolhead_moves, r.extruder_moves
    );
    out += &format!(
        "  steps        {} in all, computed in {:.3} s\n",
        r.total_steps, r.wall_time_s
    );
    out += "  motor             steps        net   peak rate (1 ms)   min interval\n";
    for m in &r.motors {
        let interval = m
            .min_interval_ticks
            .map_or("-".to_string(), |t| format!("{t} ticks"));
        out += &format!(
            "  {:<14} {:>9} {:>10} {:>12.0} steps/s   {:>12}\n",
            m.name, m.steps, m.net_steps, m.peak_rate_1ms, interval
        );
        if let Some(limit) = m.over_max_step_rate {
            out += &format!(
                "    warning: {} exceeds its max_step_rate of {limit:.0} steps/s\n",
                m.name
            );
        }
        if m.filtered_pairs > 0 {
            out += &format!(
                "    {} step pairs removed by the step+dir+step filter\n",
                m.filtered_pairs
            );
        }
    }
    if r.slowed_moves > 0 {
        out += &format!(
            "  {} moves slowed below 25% of their requested speed by machine limits\n",
            r.slowed_moves
        );
    }
    for w in r.warnings.iter().take(20) {
        out += &format!(
            "  {}:{}:{}: warning: {}\n",
            r.file, w.line, w.column, w.message
        );
    }
    if r.warnings.len() > 20 {
        out += &format!(
            "  … and {} more warnings (see --json)\n",
            r.warnings.len() - 20
        );
    }
    out
}

/// The moves CSV: written to a temporary file and renamed into place when complete (never over an input),
/// or to standard output for `-`.
struct CsvFile {
    sink: trapq::csv::CsvSink<std::io::BufWriter<Box<dyn std::io::Write + Send>>>,
    /// The temporary file and where it goes; `None` for standard output.
    temp: Option<(tempfile::NamedTempFile, PathBuf)>,
}

impl std::fmt::Debug for CsvFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CsvFile").finish_non_exhaustive()
    }
}

impl CsvFile {
    fn create(path: &Path) -> miette::Result<Self> {
        let fail =
            |e: &dyn std::fmt::Display| miette::miette!("cannot write {}: {e}", path.display());
        if crate::output::is_stdio(path) {
            let out: Box<dyn std::io::Write + Send> = Box::new(std::io::stdout());
            return Ok(CsvFile {
                sink: trapq::csv::CsvSink::new(std::io::BufWriter::new(out)),
                temp: None,
            });
        }
        let temp = crate::output::temp_file_for(path).map_err(super::plain)?;
        let file = temp.reopen().map_err(|e| fail(&e))?;
        let out: Box<dyn std::io::Write + Send> = Box::new(file);
        Ok(CsvFile {
            sink: trapq::csv::CsvSink::new(std::io::BufWriter::new(out)),
            temp: Some((temp, path.to_path_buf())),
        })
    }

    fn finish(self) -> miette::Result<()> {
        let fail = |e: &dyn std::fmt::Display| miette::miette!("cannot write the moves: {e}");
        let writer = self.sink.finish().map_err(|e| fail(&e))?;
        let mut out = writer.into_inner().map_err(|e| fail(&e))?;
        out.flush().map_err(|e| fail(&e))?;
        if let Some((temp, path)) = self.temp {
            temp.persist(&path)
                .map_err(|e| miette::miette!("cannot write {}: {e}", path.display()))?;
        }
        Ok(())
    }
}

impl trapq::MoveSink for CsvFile {
    fn append(&mut self, queue: trapq::Queue, mv: &trapq::TrapezoidMove) {
        self.sink.append(queue, mv);
    }
}

/// The G-code line a step problem at print time `time` comes from, planning the file again as `run` did.
fn locate_step_problem(config: &Path, file: &Path, options: &RunOptions, time: f64) -> Option<u64> {
    let machine = config::MachineConfig::load(config).ok()?;
    let mut setup = MachineSetup::from_config(&machine).ok()?;
    setup.planner.skip_unreachable = options.skip_unreachable;
    setup.planner.klipper_batch_flush = options.klipper_batch;
    setup.planner.behave_as(options.host);
    line_at_time(&setup, file, time)
}

/// A step stream no MCU could run, as a diagnostic on the G-code line it comes from (when it could be found).
fn step_stream_error(file: &Path, line: Option<u64>, e: &StepStreamError) -> miette::Report {
    match line {
        Some(line) => {
            let span = gcode::Span {
                line,
                column: 1,
                len: 0,
            };
            miette::Report::new(diag::at_gcode_line(
                file,
                span,
                e.to_string(),
                "the steps of this move".into(),
            ))
        }
        None => miette::miette!("{}: {e}", file.display()),
    }
}

/// For `check`: the file's steps generated (not written) and audited as `run` does, so that `check` flags what
/// `run` would refuse. Standard input cannot be read twice: it is not audited.
fn audit_file(
    machine: &config::MachineConfig,
    args: &CheckArgs,
    name: &str,
) -> miette::Result<Option<motion::machine::Problem>> {
    if args.file == Path::new("-") {
        return Ok(None);
    }
    let options = RunOptions {
        clock_hz: 16e6,
        ..RunOptions::default()
    };
    let setup = MachineSetup::from_config(machine).map_err(|e| miette::miette!("{e}"))?;
    let input = std::io::BufReader::new(
        std::fs::File::open(&args.file)
            .map_err(|e| miette::miette!("cannot read {}: {e}", args.file.display()))?,
    );
    let config_name = args.config.display().to_string();
    match execute(machine, setup, input, name, &config_name, &options) {
        Err(ExecuteError::Steps(e)) => {
            let line = locate_step_problem(&args.config, &args.file, &options, e.time);
            Ok(Some(motion::machine::Problem {
                span: gcode::Span {
                    line: line.unwrap_or(0),
                    column: 1,
                    len: 0,
                },
                severity: Severity::Error,
                message: e.to_string(),
                line_text: None,
            }))
        }
        // Planning problems were reported by the check itself; anything else is not the file's.
        _ => Ok(None),
    }
}

/// A planning error as a diagnostic on the G-code line.
pub fn pipeline_error(file: &Path, e: motion::machine::PipelineError) -> miette::Report {
    match e {
        motion::machine::PipelineError::Gcode(e) => miette::Report::new(diag::gcode_error(&e)),
        motion::machine::PipelineError::Plan(e) => miette::Report::new(diag::at_gcode_line(
            file,
            e.span,
            e.kind.to_string(),
            "this move".into(),
        )),
    }
}

pub fn check(args: CheckArgs) -> miette::Result<ExitCode> {
    let (machine, setup) = load_machine(&args.config)?;
    let (reader, name, bar) = input::open_gcode(&args.file).map_err(super::plain)?;
    let mut report: CheckReport = check_gcode(&setup, reader, &name, args.max_problems);
    bar.finish_and_clear();
    if report.errors() == 0
        && let Some(problem) = audit_file(&machine, &args, &name)?
    {
        report.error_count += 1;
        if report.problems.len() < args.max_problems {
            report.problems.push(problem);
        }
    }
    let label = |p: &motion::machine::Problem| match p.severity {
        Severity::Error => "error",
        Severity::Warning => "warning",
    };
    let errors = report.errors();
    if args.json {
        let problems: Vec<serde_json::Value> = report
            .problems
            .iter()
            .map(|p| {
                serde_json::json!({
                    "line": p.span.line,
                    "column": p.span.column,
                    "severity": label(p),
                    "message": p.message,
                })
            })
            .collect();
        let value = serde_json::json!({
            "file": name,
            "errors": errors,
            "warnings": report.warning_count,
            "print_time_s": report.end_time,
            "slowed_moves": report.slow_moves,
            "problems": problems,
        });
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&value).unwrap_or_default()
        );
    } else {
        for p in &report.problems {
            crate::outln!(
                "{name}:{}:{}: {}: {}",
                p.span.line,
                p.span.column,
                label(p),
                p.message
            );
        }
        crate::outln!(
            "{name}: {errors} errors, {} warnings; {:.1} s of printing planned; {} moves slowed hard",
            report.warning_count,
            report.end_time,
            report.slow_moves
        );
    }
    Ok(if errors > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}
