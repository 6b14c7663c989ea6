//! The typed commands the modal interpreter yields, in file order.
//!
//! Positions are absolute machine coordinates in mm (G90/G91, G92 offsets, G20 inches and the M221
//! extrusion factor already applied, the way Klipper's `gcode_move` computes them); feed rates are mm/s.

/// Where a token or line sits in its input: 1-based line, 1-based column (bytes), length in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Span {
    pub line: u64,
    pub column: u32,
    pub len: u32,
}

/// `[x, y, z, e]` in mm.
pub type Position = [f64; 4];

/// A command with the span of the whole command (first word to the end of its last parameter).
#[derive(Debug, Clone, PartialEq)]
pub struct Spanned<T> {
    pub span: Span,
    pub value: T,
}

/// A straight move (G0/G1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    /// Absolute target; axes the command did not name keep the current value.
    pub target: Position,
    /// Which axes the command named (X, Y, Z, E).
    pub named: [bool; 4],
    /// Requested speed in mm/s (modal: the last F seen, times the M220 factor).
    pub feed: f64,
    /// G0 rather than G1.
    pub rapid: bool,
}

/// An arc (G2/G3) in the XY plane, kept whole: the planner or converter splits it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arc {
    /// Position before the arc.
    pub start: Position,
    /// Absolute end point (axes not named keep the current value; Z and E change linearly along the arc).
    pub target: Position,
    /// Absolute XY centre (from I/J offsets relative to the start, or from R).
    pub centre: [f64; 2],
    /// The I/J offsets as written (from R: the offsets of the computed centre).
    pub offset: [f64; 2],
    /// G2 (clockwise) rather than G3.
    pub clockwise: bool,
    /// Full turns requested by `P` (0 when absent).
    pub turns: u32,
    pub feed: f64,
    /// E as written on the command (in G-code units, before the M221 factor), if given.
    pub e_written: Option<f64>,
    /// The interpreter state the arc was read in (G92 offsets, M221 factor, M82/M83), so that a splitter can
    /// compute every chord end exactly as a firmware's own G1 commands would.
    pub base: Position,
    pub extrude_factor: f64,
    pub absolute_extrude: bool,
}

/// `SET_VELOCITY_LIMIT` parameters; `None` where not given.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VelocityLimit {
    pub velocity: Option<f64>,
    pub accel: Option<f64>,
    pub square_corner_velocity: Option<f64>,
    pub minimum_cruise_ratio: Option<f64>,
    /// Old Klipper `ACCEL_TO_DECEL` (converted by the planner, kept raw here).
    pub accel_to_decel: Option<f64>,
}

/// `M204` parameters as written (firmwares differ in which they honour; the planner decides).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AccelParams {
    pub s: Option<f64>,
    pub p: Option<f64>,
    pub t: Option<f64>,
    pub r: Option<f64>,
}

/// Slicer metadata found in comments.
#[derive(Debug, Clone, PartialEq)]
pub enum Meta {
    /// A new layer begins (`;LAYER_CHANGE`, `;LAYER:n`, `; CHANGE_LAYER`, …); `z` from `;Z:` where given.
    LayerChange {
        index: Option<i64>,
        z: Option<f64>,
    },
    /// Feature type (`;TYPE:Perimeter`, Simplify3D `; feature outer perimeter`, …).
    Feature(String),
    /// Object-exclusion markers (`EXCLUDE_OBJECT_START NAME=…`, `; printing object …`).
    ObjectStart(String),
    ObjectEnd(String),
    /// The slicer's own estimate of the whole print, in seconds (PrusaSlicer/SuperSlicer/Orca/Bambu
    /// `; estimated printing time (normal mode) = 1h 2m 3s`, Cura `;TIME:3723`, Simplify3D
    /// `;   Build time: 1 hours 2 minutes`, KISSlicer `; Estimated Build Time:   62.05 minutes`); `silent`:
    /// PrusaSlicer's second estimate, for its printers' stealth mode (`(silent mode)`).
    PrintTimeEstimate {
        seconds: f64,
        silent: bool,
    },
    /// Cura's time elapsed since the start of the print at this point (`;TIME_ELAPSED:123.4`), seconds.
    TimeElapsed(f64),
}

/// One interpreted command.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    Move(Move),
    /// Boxed: arcs are rare and twice the size of a move, and every command is moved by value
    /// through the reader's hot path.
    Arc(Box<Arc>),
    /// G4 (seconds; from `P` ms or `S` s as written).
    Dwell {
        seconds: f64,
    },
    /// G28; `axes` = which of X, Y, Z were named (all false = home all).
    Home {
        axes: [bool; 3],
    },
    /// G92: the G-code coordinates named were redefined; the machine did not move.
    /// `position` is the new G-code-space position of the named axes (others `None`).
    SetPosition {
        position: [Option<f64>; 4],
    },
    /// `SET_KINEMATIC_POSITION X= Y= Z=`: declares where the toolhead is (machine coordinates).
    SetKinematicPosition {
        position: [Option<f64>; 3],
    },
    /// M400: wait for moves to finish.
    WaitForMoves,
    /// M204.
    SetAccel(AccelParams),
    /// SET_VELOCITY_LIMIT.
    SetVelocityLimit(VelocityLimit),
    /// M220 (percent), M221 (percent): already applied to later moves; reported for pass-through.
    SpeedFactor(f64),
    ExtrudeFactor(f64),
    /// Anything else, kept with its name (`M104`, `SET_FAN_SPEED`, …) for pass-through.
    Other {
        name: String,
    },
    /// Slicer metadata from a comment.
    Meta(Meta),
}

impl Arc {
    /// Radius at the start point, mm.
    pub fn radius(&self) -> f64 {
        (self.start[0] - self.centre[0]).hypot(self.start[1] - self.centre[1])
    }

    /// Angle swept, radians, always > 0 (direction given by `clockwise`); start = end is a full turn,
    /// and each `turns` adds one more.
    pub fn sweep(&self) -> f64 {
        let (ax, ay) = (
            self.start[0] - self.centre[0],
            self.start[1] - self.centre[1],
        );
        let (bx, by) = (
            self.target[0] - self.centre[0],
            self.target[1] - self.centre[1],
        );
        let ccw = (ax * by - ay * bx).atan2(ax * bx + ay * by);
        let mut sweep = if self.clockwise { -ccw } else { ccw };
        if sweep <= 0.0 {
            sweep += std::f64::consts::TAU;
        }
        sweep + f64::from(self.turns) * std::f64::consts::TAU
    }

    /// Length of the arc's projection on XY, mm.
    pub fn length_xy(&self) -> f64 {
        self.radius() * self.sweep()
    }

    /// XY point at `fraction` (0..=1) of the sweep, on the start radius.
    pub fn point_at(&self, fraction: f64) -> [f64; 2] {
        let angle0 = (self.start[1] - self.centre[1]).atan2(self.start[0] - self.centre[0]);
        let signed = if self.clockwise {
            -self.sweep()
        } else {
            self.sweep()
        };
        let angle = angle0 + signed * fraction;
        let r = self.radius();
        [
            self.centre[0] + r * angle.cos(),
            self.centre[1] + r * angle.sin(),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arc(start: [f64; 2], target: [f64; 2], clockwise: bool, turns: u32) -> Arc {
        Arc {
            start: [start[0], start[1], 0.0, 0.0],
            target: [target[0], target[1], 0.0, 0.0],
            centre: [0.0, 0.0],
            offset: [-start[0], -start[1]],
            clockwise,
            turns,
            feed: 1.0,
            e_written: None,
            base: [0.0; 4],
            extrude_factor: 1.0,
            absolute_extrude: true,
        }
    }

    #[test]
    fn sweep_direction_and_full_turns() {
        use std::f64::consts::{FRAC_PI_2, PI, TAU};
        assert!((arc([1.0, 0.0], [0.0, 1.0], false, 0).sweep() - FRAC_PI_2).abs() < 1e-15);
        assert!((arc([1.0, 0.0], [0.0, 1.0], true, 0).sweep() - 3.0 * FRAC_PI_2).abs() < 1e-15);
        assert!((arc([1.0, 0.0], [1.0, 0.0], true, 0).sweep() - TAU).abs() < 1e-15);
        assert!((arc([1.0, 0.0], [-1.0, 0.0], false, 1).sweep() - (PI + TAU)).abs() < 1e-15);
        let quarter = arc([2.0, 0.0], [0.0, 2.0], false, 0);
        assert!((quarter.length_xy() - PI).abs() < 1e-14);
        let mid = quarter.point_at(0.5);
        assert!((mid[0] - 2f64.sqrt()).abs() < 1e-14 && (mid[1] - 2f64.sqrt()).abs() < 1e-14);
    }
}
