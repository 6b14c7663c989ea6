//! Running a job: plan the stream on this thread while every motor steps on a thread of its own, audit every
//! motor's stream as an MCU would execute it, and write the step files and the moves CSV when asked for.

use std::io::BufRead;
use std::path::PathBuf;
use std::time::Instant;

use config::StepRateLimit;
use kinematics::Kinematics;
use serde::Serialize;
use stepgen::{
    ExpectedTravel, ExtruderSpec, FileAndStats, MotorStats, StepFileError, StepFileWriter,
    StepGenConfig, StepStats, Tee,
};

use crate::audit::{AuditedMotor, StepStreamError, first_problem, period_of};
use crate::moves_file::MovesFile;
use crate::plan::{PipelineError, PlanSummary, plan_gcode};
use machine::{Machine, PlanOptions};

/// What a run needs besides the machine and the G-code.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    /// Write one step file per motor into this folder.
    pub steps: Option<PathBuf>,
    /// Write the planned moves as CSV here (`-`: standard output).
    pub moves: Option<PathBuf>,
    /// MCU clock frequency of the step clocks (Hz).
    pub clock_hz: f64,
    pub plan: PlanOptions,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            steps: None,
            moves: None,
            clock_hz: 16e6,
            plan: PlanOptions::default(),
        }
    }
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The G-code could not be planned (its line and column: [`PipelineError::place`]).
    #[error(transparent)]
    Plan(#[from] PipelineError),
    /// A step stream no MCU could run.
    #[error(transparent)]
    Steps(#[from] StepStreamError),
    #[error(transparent)]
    Output(#[from] outfile::OutputError),
    #[error(transparent)]
    StepFile(#[from] StepFileError),
    #[error("step generation failed: {0}")]
    StepGen(stepgen::StepError),
    /// `cancelled` turned true: the run stopped and wrote nothing.
    #[error("cancelled")]
    Cancelled,
}

impl From<stepgen::StepError> for RunError {
    fn from(e: stepgen::StepError) -> Self {
        match e {
            stepgen::StepError::Cancelled => RunError::Cancelled,
            other => RunError::StepGen(other),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
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

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarningLine {
    pub line: u64,
    pub column: u32,
    pub message: String,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
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

/// Plan `input` on the machine (as `options.plan` says) and generate every motor's steps, audited; the summary
/// of the run. `cancelled` is polled as the motors step (e.g. Ctrl-C): when it turns true the run fails and
/// writes nothing. A run that fails leaves nothing behind, not even the step files' folder it made.
pub fn run(
    machine: &Machine,
    input: impl BufRead,
    name: &str,
    options: &RunOptions,
    cancelled: fn() -> bool,
) -> Result<RunSummary, RunError> {
    let made_here = options.steps.as_ref().filter(|dir| !dir.exists());
    let result = run_to_files(machine, input, name, options, cancelled);
    if let (Err(_), Some(dir)) = (&result, made_here) {
        // Its files were never committed; only an empty folder is removed.
        let _ = std::fs::remove_dir(dir);
    }
    result
}

fn run_to_files(
    machine: &Machine,
    input: impl BufRead,
    name: &str,
    options: &RunOptions,
    cancelled: fn() -> bool,
) -> Result<RunSummary, RunError> {
    let started = Instant::now();
    let setup = machine.setup_with(options.plan);
    let kinematics = setup.kinematics.as_ref();
    let motors = Motors::of(machine, kinematics);
    let sinks = motors.sinks(options)?;
    let moves_file = options
        .moves
        .as_deref()
        .map(MovesFile::create)
        .transpose()?;
    let travel = ExpectedTravel::new(kinematics, motors.extruder.is_some());
    let config = StepGenConfig {
        clock_hz: options.clock_hz,
        ..StepGenConfig::default()
    };
    // Planning on this thread, stepping on the motors' own: they overlap chunk by chunk.
    let (planned, sinks, filtered) = stepgen::run_in_parallel(
        kinematics,
        motors.extruder.clone(),
        config,
        sinks,
        cancelled,
        |sender| {
            // The sender is dropped here, which tells the stepping threads that planning is over.
            let sink = ((sender, (MoveCounter::default(), travel)), moves_file);
            plan_gcode(&setup, input, name, sink)
                .map(|(((_, (counter, travel)), moves), summary)| (counter, travel, moves, summary))
        },
    )?;
    let (counter, travel, moves_file, summary) = planned?;
    motors.audit(&sinks, kinematics, travel.finish(), options.clock_hz)?;
    if let Some(moves_file) = moves_file {
        moves_file.finish()?;
    }
    let motor_summaries = motors.finish(sinks, filtered, options.clock_hz)?;
    Ok(RunSummary {
        file: name.to_string(),
        config: machine.source.clone(),
        kinematics: machine.config.kinematics.name().to_string(),
        print_time_s: summary.end_time,
        toolhead_moves: counter.toolhead,
        extruder_moves: counter.extruder,
        total_steps: motor_summaries.iter().map(|m| m.steps).sum(),
        motors: motor_summaries,
        slowed_moves: summary.slow_moves.total,
        warnings: warning_lines(&summary),
        wall_time_s: started.elapsed().as_secs_f64(),
    })
}

/// The machine's motors as a run steps them: the kinematics' motors, then the extruder's.
struct Motors {
    names: Vec<String>,
    /// Each motor's configured step-rate limit (`max_step_rate`), which the run warns about over 1 ms.
    max_rates: Vec<Option<f64>>,
    /// Each motor's limit for the step audit: `max_step_rate`, or one step per step pulse.
    audit_limits: Vec<Option<StepRateLimit>>,
    extruder: Option<ExtruderSpec>,
}

impl Motors {
    fn of(machine: &Machine, kinematics: &dyn Kinematics) -> Motors {
        let extruder = machine.config.extruder.as_ref().map(|e| ExtruderSpec {
            name: e.stepper.name.clone(),
            step_distance: e.stepper.step_distance,
            start_position: 0.0,
        });
        let names: Vec<String> = kinematics
            .motors()
            .iter()
            .map(|m| m.name.clone())
            .chain(extruder.iter().map(|e| e.name.clone()))
            .collect();
        let max_rates = names
            .iter()
            .map(|name| machine.config.max_step_rate(name))
            .collect();
        let audit_limits = names
            .iter()
            .map(|name| machine.config.step_rate_limit(name))
            .collect();
        Motors {
            names,
            max_rates,
            audit_limits,
            extruder,
        }
    }

    /// One sink per motor: statistics with the step audit, and the step file when asked for one (its folder
    /// is made by `outfile` as the file is).
    fn sinks(&self, options: &RunOptions) -> Result<Vec<FileAndStats>, RunError> {
        let mut sinks = Vec::with_capacity(self.names.len());
        for (name, limit) in self.names.iter().zip(&self.audit_limits) {
            let file = match &options.steps {
                Some(dir) => Some(StepFileWriter::create(dir.join(format!("{name}.txt")))?),
                None => None,
            };
            sinks.push(Tee(
                StepStats::new(options.clock_hz).audited(limit.map(|l| l.steps_per_second)),
                file,
            ));
        }
        Ok(sinks)
    }

    /// Every motor's stream through the audit: the first problem is the run's error.
    fn audit(
        &self,
        sinks: &[FileAndStats],
        kin: &dyn Kinematics,
        (travel, stretches): (Vec<Option<f64>>, u32),
        clock_hz: f64,
    ) -> Result<(), StepStreamError> {
        let step_distances = kin
            .motors()
            .iter()
            .map(|m| m.step_distance)
            .chain(self.extruder.as_ref().map(|e| e.step_distance));
        let motors: Vec<AuditedMotor> = sinks
            .iter()
            .zip(&self.names)
            .zip(step_distances)
            .zip(travel)
            .enumerate()
            .map(|(i, (((sink, name), step_distance), expected_travel))| {
                let stats = sink.0.summary(clock_hz, 0);
                AuditedMotor {
                    name,
                    problem: sink.0.problem(),
                    net_steps: stats.net_steps,
                    step_distance,
                    period: period_of(kin, i),
                    expected_travel,
                    stretches,
                    last_time: stats.last_clock.unwrap_or(0) as f64 / clock_hz,
                    limit: self.audit_limits[i],
                }
            })
            .collect();
        first_problem(&motors, clock_hz).map_or(Ok(()), Err)
    }

    /// Each motor's step file finished, and its summary.
    fn finish(
        &self,
        sinks: Vec<FileAndStats>,
        filtered: Vec<u64>,
        clock_hz: f64,
    ) -> Result<Vec<MotorSummary>, RunError> {
        let mut motors = Vec::with_capacity(sinks.len());
        let motors_of_run = sinks.into_iter().zip(&self.names).zip(&self.max_rates);
        for (((sink, name), &limit), filtered_pairs) in motors_of_run.zip(filtered) {
            let Tee(stats, file) = sink;
            if let Some(file) = file {
                file.finish()?;
            }
            let stats: MotorStats = stats.summary(clock_hz, filtered_pairs);
            motors.push(MotorSummary {
                name: name.clone(),
                steps: stats.steps,
                net_steps: stats.net_steps,
                min_interval_ticks: stats.min_interval_ticks,
                peak_rate_min_interval: Some(stats.peak_rate_min_interval)
                    .filter(|rate| rate.is_finite()),
                peak_rate_1ms: stats.peak_rate_1ms,
                filtered_pairs,
                over_max_step_rate: limit.filter(|l| stats.peak_rate_1ms > *l),
            });
        }
        Ok(motors)
    }
}

/// The planner's and the reader's warnings, in file order.
pub(crate) fn warning_lines(summary: &PlanSummary) -> Vec<WarningLine> {
    let line = |span: gcode::Span, message: &str| WarningLine {
        line: span.line,
        column: span.column,
        message: message.to_string(),
    };
    let mut warnings: Vec<WarningLine> = summary
        .warnings
        .iter()
        .map(|w| line(w.span, &w.message))
        .chain(
            summary
                .gcode_warnings
                .iter()
                .map(|w| line(w.span, &w.message)),
        )
        .collect();
    warnings.sort_by_key(|w| (w.line, w.column));
    warnings
}

/// Counts planned moves on the way through.
#[derive(Debug, Default)]
struct MoveCounter {
    toolhead: u64,
    extruder: u64,
}

impl trapq::MoveSink for MoveCounter {
    fn append(
        &mut self,
        queue: trapq::Queue,
        _mv: &trapq::TrapezoidMove,
    ) -> Result<(), trapq::SinkError> {
        match queue {
            trapq::Queue::Toolhead => self.toolhead += 1,
            trapq::Queue::Extruder => self.extruder += 1,
        }
        Ok(())
    }
}
