//! The step-stream audit of `run` and `check`: every motor's steps as an MCU would execute them (no two on one
//! clock tick, none closer than the motor's maximum step rate allows, a net position that agrees with where the
//! planned path takes the motor), and the G-code line a problem comes from.

use std::io::BufReader;
use std::path::Path;

use config::StepRateLimit;
use kinematics::{Kinematics, MotorUnit};
use machine::MachineSetup;
use stepgen::{StepProblem, net_agrees};

use crate::plan::plan_gcode;
use machine::{Machine, PlanOptions};

/// A step stream a real MCU could not execute.
#[derive(Debug, Clone, PartialEq)]
pub struct StepStreamError {
    pub motor: String,
    /// Print time (s) of the offending step, or of the end of the print for a position that does not agree.
    pub time: f64,
    pub message: String,
}

impl std::fmt::Display for StepStreamError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} at {:.6} s: a real MCU cannot execute this step stream",
            self.motor, self.message, self.time
        )
    }
}

/// One motor as the audit sees it.
#[derive(Debug)]
pub struct AuditedMotor<'a> {
    pub name: &'a str,
    /// The first step the audit found too close to the one before it.
    pub problem: Option<StepProblem>,
    pub net_steps: i64,
    pub step_distance: f64,
    /// A motor that turns without end (2π) compares its position modulo a turn.
    pub period: Option<f64>,
    /// How far the planned path moves it (motor units); `None` where the kinematics cannot say.
    pub expected_travel: Option<f64>,
    /// In how many stretches between declared positions.
    pub stretches: u32,
    /// Print time of the motor's last step (s), where a position problem is reported.
    pub last_time: f64,
    /// The step-rate limit its stream was audited against, which a message about a too-fast step names.
    pub limit: Option<StepRateLimit>,
}

/// The first problem over all motors (the earliest step problem, then position disagreements in motor order).
pub fn first_problem(motors: &[AuditedMotor], clock_hz: f64) -> Option<StepStreamError> {
    let step_problem = motors
        .iter()
        .filter_map(|m| m.problem.map(|p| (m, p)))
        .min_by_key(|(_, p)| p.clock())
        .map(|(m, p)| StepStreamError {
            motor: m.name.to_string(),
            time: p.clock() as f64 / clock_hz,
            message: step_message(m, p, clock_hz),
        });
    step_problem.or_else(|| motors.iter().find_map(position_problem))
}

/// A step problem in words; a too-fast step names the limit it broke and where that limit comes from.
fn step_message(m: &AuditedMotor, problem: StepProblem, clock_hz: f64) -> String {
    let what = problem.describe(clock_hz);
    match (problem, m.limit) {
        (StepProblem::TooFast { .. }, Some(limit)) => {
            format!("{what}; the limit is {}", limit.describe())
        }
        _ => what,
    }
}

fn position_problem(m: &AuditedMotor) -> Option<StepStreamError> {
    let expected = m.expected_travel?;
    let net = m.net_steps;
    (!net_agrees(net, m.step_distance, expected, m.period, m.stretches)).then(|| StepStreamError {
        motor: m.name.to_string(),
        time: m.last_time,
        message: format!(
            "its {net} net steps move it {:.6}, but the planned path moves it {expected:.6}",
            net as f64 * m.step_distance
        ),
    })
}

/// A rad motor turns without end as far as its position is concerned (a polar bed; joints compare the same).
pub fn period_of(kin: &dyn Kinematics, motor: usize) -> Option<f64> {
    kin.motors()
        .get(motor)
        .filter(|m| m.unit == MotorUnit::Rad)
        .map(|_| std::f64::consts::TAU)
}

/// The G-code line a step problem at print time `time` comes from, planning `file` again on `machine` as the run
/// did (`plan`). `None` when the file cannot be read again (standard input).
pub fn locate(machine: &Machine, plan: PlanOptions, file: &Path, time: f64) -> Option<u64> {
    line_at_time(&machine.setup_with(plan), file, time)
}

/// The G-code line whose move runs at print time `time`, found by planning `file` again on `setup` (the line of
/// the last move that starts by then). `None` when the file cannot be read again.
pub fn line_at_time(setup: &MachineSetup, file: &Path, time: f64) -> Option<u64> {
    if outfile::is_stdio(file) {
        return None;
    }
    let input = BufReader::new(std::fs::File::open(file).ok()?);
    let locator = Locator {
        time,
        origin: 0,
        found: None,
    };
    let name = file.display().to_string();
    let (locator, _) = plan_gcode(setup, input, &name, locator).ok()?;
    locator.found
}

/// Keeps the origin of the last move starting at or before `time`.
#[derive(Debug)]
struct Locator {
    time: f64,
    origin: u64,
    found: Option<u64>,
}

impl trapq::MoveSink for Locator {
    fn append(
        &mut self,
        _queue: trapq::Queue,
        mv: &trapq::TrapezoidMove,
    ) -> Result<(), trapq::SinkError> {
        if mv.print_time <= self.time {
            self.found = Some(self.origin);
        }
        Ok(())
    }

    fn origin(&mut self, origin: u64) {
        self.origin = origin;
    }
}

impl std::error::Error for StepStreamError {}
