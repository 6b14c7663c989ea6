//! Planning a whole G-code stream on a machine: typed commands from the reader into Klipper's toolhead.

use std::io::BufRead;

use gcode::{Commands, GcodeError};
use machine::MachineSetup;
use motion::{PlanError, Planner, SlowMoves, Toolhead, Warning};
use trapq::{MoveSink, SinkError};

/// Why planning stopped.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// A consumer of the planned moves failed (a full disk, a motor whose steps could not be written) while
    /// the line at `span` was planned; planning stopped there.
    #[error("{error}")]
    Sink { span: gcode::Span, error: SinkError },
}

impl PipelineError {
    /// The G-code line and column it stopped at.
    pub fn place(&self) -> (u64, u32) {
        let span = match self {
            PipelineError::Gcode(e) => e.span,
            PipelineError::Plan(e) => e.span,
            PipelineError::Sink { span, .. } => *span,
        };
        (span.line, span.column)
    }

    /// What went wrong, without the place.
    pub fn message(&self) -> String {
        match self {
            PipelineError::Gcode(e) => e.kind.to_string(),
            PipelineError::Plan(e) => e.kind.to_string(),
            PipelineError::Sink { error, .. } => error.to_string(),
        }
    }
}

/// What planning a stream produced besides the moves.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSummary {
    /// Print time at which the last move ends (s).
    pub end_time: f64,
    pub warnings: Vec<Warning>,
    pub gcode_warnings: Vec<gcode::Warning>,
    /// Moves a machine limit slowed below a quarter of their requested speed.
    pub slow_moves: SlowMoves,
    /// With Klipper's batch-mode flushing: the print time Klipper logs at the end of its input (the end of the print,
    /// or where its step generation could restart when that is later).
    pub klipper_exit_time: Option<f64>,
}

/// The reader and the planner of one stream, both at the machine's homing pose (a file is printed on a homed
/// machine).
pub(crate) fn start<'a, R: BufRead, S: MoveSink>(
    setup: &'a MachineSetup,
    input: R,
    source_name: &str,
    sink: S,
) -> (Commands<R>, Planner<'a, S>) {
    let toolhead = Toolhead::new(setup.planner.clone(), setup.kinematics.as_ref(), sink);
    let mut planner = Planner::new(toolhead, setup.planner.arc_resolution, setup.home_position);
    // Read as Klipper reads it: the job is planned as Klipper plans it.
    let reader = gcode::Reader::new(input, source_name);
    let mut commands = Commands::new(reader, setup.reading);
    if let Some(home) = setup.home_position {
        planner.start_at(home);
        let mut position = commands.interpreter().last_position();
        position[..3].copy_from_slice(&home);
        commands.interpreter_mut().set_position(position);
    }
    (commands, planner)
}

/// Bytes Klipper's batch mode reads from its input at a time.
const KLIPPER_INPUT_BLOCK: u64 = 4096;

/// Plan a whole G-code stream on `setup`, handing planned moves to `sink`. Memory stays bounded: the
/// stream is read line by line and the lookahead holds at most a few seconds of moves.
pub fn plan_gcode<S: MoveSink>(
    setup: &MachineSetup,
    input: impl BufRead,
    source_name: &str,
    sink: S,
) -> Result<(S, PlanSummary), PipelineError> {
    plan_gcode_observed(setup, input, source_name, sink, |_| {})
}

/// What a caller sees of a stream while it is planned, beside the planned moves.
pub trait Observer {
    /// Every command (metadata and pass-through commands included), before it is planned.
    fn command(&mut self, command: &gcode::Spanned<gcode::Command>);
    /// With `skip_unreachable`: a move the machine refused, the machine at `at` (where it stays), and why.
    fn refused(&mut self, _command: &gcode::Spanned<gcode::Command>, _at: [f64; 4], _reason: &str) {
    }
}

/// A closure as an [`Observer`] of commands.
struct EachCommand<F>(F);

impl<F: FnMut(&gcode::Spanned<gcode::Command>)> Observer for EachCommand<F> {
    fn command(&mut self, command: &gcode::Spanned<gcode::Command>) {
        (self.0)(command);
    }
}

/// [`plan_gcode`], showing `observe` every command (metadata and pass-through commands included) before it is
/// planned: for a breakdown of the planned time by what the file says between its moves.
pub fn plan_gcode_observed<S: MoveSink>(
    setup: &MachineSetup,
    input: impl BufRead,
    source_name: &str,
    sink: S,
    observe: impl FnMut(&gcode::Spanned<gcode::Command>),
) -> Result<(S, PlanSummary), PipelineError> {
    plan_gcode_watched(setup, input, source_name, sink, &mut EachCommand(observe))
}

/// [`plan_gcode`] with an [`Observer`]: every command before it is planned, and each refused move.
pub fn plan_gcode_watched<S: MoveSink>(
    setup: &MachineSetup,
    input: impl BufRead,
    source_name: &str,
    sink: S,
    observer: &mut dyn Observer,
) -> Result<(S, PlanSummary), PipelineError> {
    let (mut commands, mut planner) = start(setup, input, source_name, sink);
    let mut block = 0u64;
    while let Some(command) = commands.next_command() {
        let command = command?;
        observer.command(&command);
        // Klipper's batch mode reads its input in 4096-byte blocks and runs its timers between blocks.
        let line_end_block =
            commands.reader().bytes_consumed().saturating_sub(1) / KLIPPER_INPUT_BLOCK;
        while block < line_end_block {
            planner.input_block_boundary();
            block += 1;
        }
        match planner.command(&command) {
            Ok(Some(position)) => commands.interpreter_mut().set_position(position),
            Ok(None) => {}
            Err(e) if setup.planner.skip_unreachable && e.is_unreachable() => {
                let reason = e.kind.to_string();
                planner.warn(e.span, reason.clone());
                // The machine stays where it was (later relative moves continue from there); the skipped
                // move's filament is not pushed by the next one.
                let position = planner.skip(&command);
                observer.refused(&command, position, &reason);
                commands.interpreter_mut().set_position(position);
            }
            Err(e) => return Err(e.into()),
        }
        if let Some(error) = planner.take_sink_error() {
            return Err(PipelineError::Sink {
                span: command.span,
                error,
            });
        }
    }
    let gcode_warnings = commands.take_warnings();
    let last_line = commands.reader().line_number();
    let klipper_exit_time = setup
        .planner
        .klipper_batch_flush
        .then(|| planner.klipper_exit_time());
    let (sink, end_time, warnings, slow_moves) =
        planner.finish().map_err(|error| PipelineError::Sink {
            span: line_start(last_line),
            error,
        })?;
    Ok((
        sink,
        PlanSummary {
            end_time,
            warnings,
            gcode_warnings,
            slow_moves,
            klipper_exit_time,
        },
    ))
}

/// The start of G-code line `line`.
pub(crate) fn line_start(line: u64) -> gcode::Span {
    gcode::Span {
        line,
        column: 1,
        len: 0,
    }
}
