//! Checking a stream: plan it without steps and collect every problem instead of stopping at the first; then,
//! when planning found no error, generate and audit the steps as a run would (not written).

use std::io::BufRead;
use std::path::Path;

use gcode::Span;
use machine::MachineSetup;

use crate::envelope::{Envelope, EnvelopeSink};
use crate::plan::{line_start, start};
use crate::run::{RunError, RunOptions, run};
use machine::{Machine, PlanOptions};

/// One problem found by [`check_gcode`].
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub span: Span,
    pub severity: Severity,
    pub message: String,
    /// The offending line's text, when the reader kept it (G-code syntax errors).
    pub line_text: Option<(String, usize)>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    Warning,
    Error,
}

impl Severity {
    pub fn label(self) -> &'static str {
        match self {
            Severity::Error => "error",
            Severity::Warning => "warning",
        }
    }
}

impl Problem {
    fn at(span: Span, severity: Severity, message: String) -> Problem {
        Problem {
            span,
            severity,
            message,
            line_text: None,
        }
    }
}

/// Everything [`check_gcode`] found, and the print time of what could be planned.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// The first `max_problems` problems found, in file order.
    pub problems: Vec<Problem>,
    pub end_time: f64,
    pub slow_moves: u64,
    /// How far the motors travel and how close the nozzle comes to the special poses.
    pub envelope: Envelope,
    /// Every error and warning found, kept or not.
    pub error_count: usize,
    pub warning_count: usize,
    max_problems: usize,
}

impl CheckReport {
    fn new(max_problems: usize) -> CheckReport {
        CheckReport {
            problems: Vec::new(),
            end_time: 0.0,
            slow_moves: 0,
            envelope: Envelope::default(),
            error_count: 0,
            warning_count: 0,
            max_problems,
        }
    }

    /// Errors found (all of them, also beyond `max_problems`).
    pub fn errors(&self) -> usize {
        self.error_count
    }

    /// Counts `problem` and keeps it while fewer than `max_problems` are kept.
    pub fn push(&mut self, problem: Problem) {
        match problem.severity {
            Severity::Error => self.error_count += 1,
            Severity::Warning => self.warning_count += 1,
        }
        if self.problems.len() < self.max_problems {
            self.problems.push(problem);
        }
    }
}

/// Plan a stream without generating steps and collect every problem instead of stopping at the first:
/// syntax errors, unreachable segments, commands the planner refused (after each refusal the check goes on
/// from the refused move's target when the machine can be there, else from where it is, with the target's E:
/// [`motion::Planner::resync_after_refusal`]),
/// ignored commands, and moves that a machine limit slows below a quarter of their requested speed.
/// At most `max_problems` are kept (all are counted in the error total).
pub fn check_gcode(
    setup: &MachineSetup,
    input: impl BufRead,
    source_name: &str,
    max_problems: usize,
) -> CheckReport {
    let mut report = CheckReport::new(max_problems);
    let sink = EnvelopeSink::new(setup.kinematics.as_ref());
    let (mut commands, mut planner) = start(setup, input, source_name, sink);
    while let Some(command) = commands.next_command() {
        match command {
            Err(e) => report.push(Problem {
                line_text: Some((e.line_text.clone(), e.line_text_offset)),
                ..Problem::at(e.span, Severity::Error, e.kind.to_string())
            }),
            Ok(command) => match planner.command(&command) {
                Ok(Some(position)) => commands.interpreter_mut().set_position(position),
                Ok(None) => {}
                Err(e) => {
                    report.push(Problem::at(e.span, Severity::Error, e.kind.to_string()));
                    // Go on from where the file meant to be, so no follow-on errors are invented.
                    let position = planner.resync_after_refusal(&command);
                    commands.interpreter_mut().set_position(position);
                }
            },
        }
    }
    for w in commands.take_warnings() {
        report.push(Problem::at(w.span, Severity::Warning, w.message.clone()));
    }
    let (sink, end_time, warnings, slow) = match planner.finish() {
        Ok(finished) => finished,
        Err(_) => unreachable!("the check's sink takes every move"),
    };
    for w in warnings {
        report.push(Problem::at(w.span, Severity::Warning, w.message));
    }
    for s in &slow.first {
        let message = format!(
            "move slowed to {:.1} mm/s by a machine limit (requested {:.1} mm/s)",
            s.allowed, s.requested
        );
        report.push(Problem::at(
            line_start(s.origin),
            Severity::Warning,
            message,
        ));
    }
    report
        .problems
        .sort_by_key(|p| (p.span.line, p.span.column));
    report.end_time = end_time;
    report.slow_moves = slow.total;
    report.envelope = sink.into_envelope();
    report
}

/// For a check: the file's steps generated (not written) and audited as a run does, so that a check flags what a
/// run would refuse; the problem found, at the G-code line it comes from. Standard input (`-`) cannot be read
/// twice: it is not audited. Planning problems are the plan check's to report, so they are not repeated here.
pub fn audit_file(machine: &Machine, file: &Path, name: &str) -> Option<Problem> {
    if outfile::is_stdio(file) {
        return None;
    }
    let plan = PlanOptions::default();
    let input = std::io::BufReader::new(std::fs::File::open(file).ok()?);
    let options = RunOptions {
        plan,
        ..RunOptions::default()
    };
    match run(machine, input, name, &options, || false) {
        Err(RunError::Steps(e)) => {
            let line = crate::audit::locate(machine, plan, file, e.time);
            Some(Problem::at(
                line_start(line.unwrap_or(0)),
                Severity::Error,
                e.to_string(),
            ))
        }
        _ => None,
    }
}
