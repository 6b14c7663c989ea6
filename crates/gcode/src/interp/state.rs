//! The interpreter's modal state, its public surface, and the modal arithmetic both paths share
//! (where a move or an arc ends, the speed an F gives, what G92 does to the offsets).

use std::collections::VecDeque;

use crate::command::{Arc as ArcMove, Command, Meta, Move, Position, Span, Spanned};
use crate::error::{Warning, WarningKind, Warnings};

use super::arcs::ArcEnds;

/// Interpreter settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterpreterOptions {
    /// Speed before the first F, mm/s (Klipper: 25).
    pub initial_speed: f64,
    /// Machine position at start.
    pub initial_position: Position,
    /// Arcs given by their radius (`G2 … R`), as Marlin and RepRapFirmware read them. Klipper refuses them ("G2/G3
    /// does not support R moves"), so a job planned as Klipper plans refuses them too.
    pub radius_arcs: bool,
    /// The optional commands the firmware has.
    pub commands: CommandSet,
}

/// Which optional commands the firmware has. One it lacks is skipped with a warning where the firmware answers
/// "Unknown command" and goes on (Klipper), and refused where the firmware refuses it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommandSet {
    /// G2/G3 and G17–G19 (Klipper: only with `[gcode_arcs]`).
    pub arcs: bool,
    /// G20, inch units (Klipper refuses it: "Machine does not support G20 (inches) command").
    pub inches: bool,
    /// `SET_KINEMATIC_POSITION` (Klipper: only with `[force_move] enable_force_move: True`).
    pub kinematic_position: bool,
}

impl CommandSet {
    /// Every command this reader knows.
    pub const ALL: CommandSet = CommandSet {
        arcs: true,
        inches: true,
        kinematic_position: true,
    };
}

impl Default for InterpreterOptions {
    fn default() -> Self {
        InterpreterOptions {
            initial_speed: 25.0,
            initial_position: [0.0; 4],
            radius_arcs: true,
            commands: CommandSet::ALL,
        }
    }
}

impl InterpreterOptions {
    /// As Klipper's `gcode_move` and `gcode_arcs` read G-code, on a printer whose configuration gives `commands`
    /// (inch units are never among them).
    pub fn klipper(commands: CommandSet) -> Self {
        InterpreterOptions {
            radius_arcs: false,
            commands: CommandSet {
                inches: false,
                ..commands
            },
            ..InterpreterOptions::default()
        }
    }
}

/// Arc plane (G17/G18/G19); only XY arcs are supported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Plane {
    Xy,
    Xz,
    Yz,
}

/// The layer change of the layer start at `span`, with the Z its slicer wrote after it (if any).
pub(super) fn layer_change(span: Span, z: Option<f64>) -> Spanned<Command> {
    let value = Command::Meta(Meta::LayerChange { index: None, z });
    Spanned { span, value }
}

/// The modal state and the queue of interpreted commands.
#[derive(Debug, Clone)]
pub struct Interpreter {
    pub(super) last: Position,
    pub(super) base: Position,
    pub(super) absolute_coord: bool,
    pub(super) absolute_extrude: bool,
    pub(super) unit: f64,
    pub(super) speed: f64,
    pub(super) speed_factor: f64,
    pub(super) extrude_factor: f64,
    pub(super) plane: Plane,
    pub(super) queue: VecDeque<Spanned<Command>>,
    /// A layer start seen whose Z has not arrived yet.
    pub(super) pending_layer: Option<Span>,
    pub(super) warnings: Warnings,
    /// See [`InterpreterOptions::radius_arcs`].
    pub(super) radius_arcs: bool,
    /// See [`InterpreterOptions::commands`].
    pub(super) commands: CommandSet,
    /// The G-code offsets `SET_GCODE_OFFSET` set (Klipper's `homing_position`): what G28 restores.
    pub(super) homing: Position,
}

impl Default for Interpreter {
    fn default() -> Self {
        Self::new(InterpreterOptions::default())
    }
}

impl Interpreter {
    pub fn new(options: InterpreterOptions) -> Self {
        Interpreter {
            last: options.initial_position,
            base: [0.0; 4],
            absolute_coord: true,
            absolute_extrude: true,
            unit: 1.0,
            speed: options.initial_speed,
            speed_factor: 1.0 / 60.0,
            extrude_factor: 1.0,
            plane: Plane::Xy,
            queue: VecDeque::new(),
            pending_layer: None,
            warnings: Warnings::default(),
            radius_arcs: options.radius_arcs,
            commands: options.commands,
            homing: [0.0; 4],
        }
    }

    /// Machine position after the commands interpreted so far.
    pub fn last_position(&self) -> Position {
        self.last
    }

    /// G92 offsets (machine = G-code + base).
    pub fn base_position(&self) -> Position {
        self.base
    }

    /// Position in the G-code frame (`last − base`, E divided by the extrude factor), mm.
    pub fn gcode_position(&self) -> Position {
        let mut p = [0.0; 4];
        for (i, value) in p.iter_mut().enumerate() {
            *value = self.last[i] - self.base[i];
        }
        p[3] /= self.extrude_factor;
        p
    }

    /// Declares the machine position (after homing or `SET_KINEMATIC_POSITION`).
    pub fn set_position(&mut self, position: Position) {
        self.last = position;
    }

    /// Current requested speed, mm/s.
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// G90 (true) or G91.
    pub fn absolute_coordinates(&self) -> bool {
        self.absolute_coord
    }

    /// M82 (true) or M83.
    pub fn absolute_extrusion(&self) -> bool {
        self.absolute_extrude
    }

    /// M221 factor (1 = 100 %).
    pub fn extrude_factor(&self) -> f64 {
        self.extrude_factor
    }

    pub fn warnings(&self) -> &Warnings {
        &self.warnings
    }

    pub fn take_warnings(&mut self) -> Vec<Warning> {
        self.warnings.take()
    }

    /// Next interpreted command, if any is queued.
    #[inline]
    pub fn pop_command(&mut self) -> Option<Spanned<Command>> {
        self.queue.pop_front()
    }

    /// End of input: emits a layer start still waiting for its Z.
    pub fn finish(&mut self) {
        self.flush_pending_layer();
    }

    pub(super) fn flush_pending_layer(&mut self) {
        if let Some(span) = self.pending_layer.take() {
            self.queue.push_back(layer_change(span, None));
        }
    }

    /// The move to `target` at `speed` (mm/s), which becomes the modal position and speed.
    #[inline(always)]
    pub(super) fn move_to(
        &mut self,
        target: Position,
        named: [bool; 4],
        speed: f64,
        rapid: bool,
    ) -> Move {
        self.last = target;
        self.speed = speed;
        Move {
            target,
            named,
            feed: speed,
            rapid,
        }
    }

    /// Per axis, decided once per line rather than per word: the factor after the unit (M221 on E
    /// only; `x * 1.0` is exact, so X Y Z round as without it) and whether a value is absolute.
    #[inline]
    pub(super) fn axis_modes(&self) -> ([f64; 4], [bool; 4]) {
        let coord = self.absolute_coord;
        let factor = [1.0, 1.0, 1.0, self.extrude_factor];
        (
            factor,
            [coord, coord, coord, coord && self.absolute_extrude],
        )
    }

    /// Machine position of `axis` for the G-code value `value` (`current`: the position so far).
    #[inline]
    pub(super) fn axis_position(
        &self,
        axis: usize,
        value: f64,
        current: f64,
        factor: &[f64; 4],
        absolute: &[bool; 4],
    ) -> f64 {
        let value = value * self.unit * factor[axis];
        let origin = if absolute[axis] {
            self.base[axis]
        } else {
            current
        };
        value + origin
    }

    /// Speed for the F value `f`, mm/s; `None` when not a positive finite speed.
    #[inline]
    pub(super) fn speed_from_f(&self, f: f64) -> Option<f64> {
        let speed = f * self.unit * self.speed_factor;
        (f > 0.0 && speed.is_finite() && speed > 0.0).then_some(speed)
    }

    /// Moves to the arc's end (the checks passed) and gives the arc from the current position.
    pub(super) fn commit_arc(&mut self, ends: ArcEnds) -> ArcMove {
        let start = self.last;
        self.last = ends.target;
        self.speed = ends.speed;
        ArcMove {
            start,
            target: ends.target,
            centre: ends.centre,
            offset: ends.offset,
            clockwise: ends.clockwise,
            turns: ends.turns,
            feed: ends.speed,
            e_written: ends.e_written,
            base: self.base,
            extrude_factor: self.extrude_factor,
            absolute_extrude: self.absolute_extrude,
        }
    }

    /// G92 for the G-code values given (in mm): `base = last − value` for each, or all four zeroed
    /// when none is given. `Err(axis)`, with nothing changed, when an axis's offset overflows.
    pub(super) fn apply_set_position(
        &mut self,
        values: [Option<f64>; 4],
    ) -> Result<Command, usize> {
        let mut position = [None; 4];
        if values.iter().all(Option::is_none) {
            self.base = self.last;
            return Ok(Command::SetPosition {
                position: [Some(0.0); 4],
            });
        }
        let mut base = self.base;
        for (axis, value) in values.iter().enumerate() {
            let Some(value) = *value else {
                continue;
            };
            let offset = if axis == 3 {
                value * self.extrude_factor
            } else {
                value
            };
            base[axis] = self.last[axis] - offset;
            if !base[axis].is_finite() {
                return Err(axis);
            }
            position[axis] = Some(value);
        }
        self.base = base;
        Ok(Command::SetPosition { position })
    }

    pub(super) fn warn(&mut self, span: Option<Span>, kind: WarningKind, message: &str) {
        self.warnings.push(Warning {
            span: span.unwrap_or_default(),
            kind,
            message: message.to_owned(),
        });
    }
}
