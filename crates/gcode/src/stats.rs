//! Streaming summary of a G-code file (backs `jointspace stats`): lines, commands by name, moves,
//! extrusion, XY travel, bounding box of extruding moves (arcs included exactly), layers, features.
//! Memory is constant: one pass, nothing kept per line.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::BufRead;
use std::sync::Arc;

use serde::Serialize;

use crate::command::{Arc as ArcMove, Command, Meta, Position};
use crate::error::GcodeError;
use crate::interp::{Interpreter, InterpreterOptions};
use crate::lexer::{CommandWord, Line};
use crate::reader::Reader;

/// Axis-aligned box, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoundingBox {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl BoundingBox {
    fn point(p: [f64; 3]) -> Self {
        BoundingBox { min: p, max: p }
    }

    fn include(&mut self, p: [f64; 3]) {
        for (axis, value) in p.into_iter().enumerate() {
            self.min[axis] = self.min[axis].min(value);
            self.max[axis] = self.max[axis].max(value);
        }
    }
}

/// The summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Stats {
    pub lines: u64,
    /// Command lines by upper-case name (`G1`, `M104`, `SET_FAN_SPEED`…), state changes included.
    pub commands: BTreeMap<String, u64>,
    /// G0 + G1.
    pub moves: u64,
    /// G2 + G3.
    pub arcs: u64,
    /// Moves and arcs that push filament while moving in XY.
    pub extruding_moves: u64,
    /// Filament pushed (sum of positive E steps), mm.
    pub total_extrusion: f64,
    /// Filament pulled back (sum of negative E steps, positive number), mm.
    pub total_retraction: f64,
    /// XY path length of all moves and arcs, mm.
    pub xy_travel: f64,
    /// Bounding box of the extruding moves (`None` if nothing was extruded).
    pub extrusion_bbox: Option<BoundingBox>,
    /// Layers: those the slicer announces with layer markers; in a file without markers, the Z levels
    /// extrusion starts at (a new one after a non-extruding move, or a Z step of more than 0.02 mm).
    pub layers: u64,
    /// Layer markers seen (`;LAYER_CHANGE`, `;LAYER:n`…).
    pub layer_markers: u64,
    /// Layers counted from Z changes while extruding.
    pub extrusion_z_levels: u64,
    /// Feature types seen (`;TYPE:`…).
    pub features: BTreeSet<String>,
    pub warnings: u64,
}

/// Accumulates [`Stats`] from lines and commands.
#[derive(Debug, Clone, Default)]
pub struct StatsCollector {
    stats: Stats,
    codes: HashMap<(u8, u32, Option<u32>), u64>,
    position: Position,
    /// Z of the current extrusion level, and whether the previous move extruded.
    level_z: Option<f64>,
    last_extruded: bool,
}

/// A Z step (mm) between two extruding moves that starts a new level (smaller ones are a spiral's climb).
const LEVEL_STEP: f64 = 0.02;

impl StatsCollector {
    pub fn new() -> Self {
        Self::default()
    }

    /// Counts a lexed line and its command name.
    pub fn add_line(&mut self, line: &Line<'_>) {
        self.stats.lines += 1;
        match line.command() {
            Some(CommandWord::Code {
                letter,
                major,
                minor,
            }) => *self.codes.entry((letter, major, minor)).or_default() += 1,
            Some(CommandWord::Extended) => {
                let name = line.command_text().unwrap_or_default().to_ascii_uppercase();
                *self.stats.commands.entry(name).or_default() += 1;
            }
            None => {}
        }
    }

    /// Accounts for one interpreted command.
    pub fn add_command(&mut self, command: &Command) {
        match command {
            Command::Move(m) => {
                self.stats.moves += 1;
                let start = self.position;
                let xy = (m.target[0] - start[0]).hypot(m.target[1] - start[1]);
                self.travel(&start, &m.target, xy);
                let extruding = self.is_extruding(&start, &m.target, xy);
                if extruding {
                    self.include(&start);
                    self.include(&m.target);
                }
                self.level(extruding, m.target[2]);
                self.position = m.target;
            }
            Command::Arc(arc) => {
                self.stats.arcs += 1;
                let xy = arc.length_xy();
                self.travel(&arc.start, &arc.target, xy);
                let extruding = self.is_extruding(&arc.start, &arc.target, xy);
                if extruding {
                    self.include_arc(arc);
                }
                self.level(extruding, arc.target[2]);
                self.position = arc.target;
            }
            Command::SetKinematicPosition { position } => {
                for (axis, value) in position.iter().enumerate() {
                    if let Some(value) = value {
                        self.position[axis] = *value;
                    }
                }
            }
            Command::Meta(Meta::LayerChange { .. }) => self.stats.layer_markers += 1,
            Command::Meta(Meta::Feature(name)) if !self.stats.features.contains(name) => {
                self.stats.features.insert(name.clone());
            }
            _ => {}
        }
    }

    fn travel(&mut self, start: &Position, end: &Position, xy: f64) {
        self.stats.xy_travel += xy;
        let de = end[3] - start[3];
        if de > 0.0 {
            self.stats.total_extrusion += de;
        } else {
            self.stats.total_retraction -= de;
        }
    }

    /// Counts extrusion Z levels (see [`Stats::layers`]).
    fn level(&mut self, extruding: bool, z: f64) {
        if extruding {
            let new = match self.level_z {
                None => true,
                Some(level) => {
                    let step = (z - level).abs();
                    step > LEVEL_STEP || (!self.last_extruded && step > 1e-6)
                }
            };
            if new {
                self.stats.extrusion_z_levels += 1;
            }
            if new || !self.last_extruded {
                self.level_z = Some(z);
            }
        }
        self.last_extruded = extruding;
    }

    fn is_extruding(&mut self, start: &Position, end: &Position, xy: f64) -> bool {
        let extruding = end[3] > start[3] && xy > 0.0;
        if extruding {
            self.stats.extruding_moves += 1;
        }
        extruding
    }

    fn include(&mut self, p: &Position) {
        let point = [p[0], p[1], p[2]];
        match &mut self.stats.extrusion_bbox {
            Some(bbox) => bbox.include(point),
            None => self.stats.extrusion_bbox = Some(BoundingBox::point(point)),
        }
    }

    /// End points plus every axis extreme (0°, 90°, 180°, 270°) the arc passes.
    fn include_arc(&mut self, arc: &ArcMove) {
        self.include(&arc.start);
        self.include(&arc.target);
        let r = arc.radius();
        let start_angle = (arc.start[1] - arc.centre[1]).atan2(arc.start[0] - arc.centre[0]);
        let sweep = arc.sweep();
        let z_mid = 0.5 * (arc.start[2] + arc.target[2]);
        for quarter in 0..4 {
            let angle = f64::from(quarter) * std::f64::consts::FRAC_PI_2;
            let travelled = if arc.clockwise {
                start_angle - angle
            } else {
                angle - start_angle
            };
            if travelled.rem_euclid(std::f64::consts::TAU) <= sweep {
                let (s, c) = angle.sin_cos();
                let z = if arc.start[2] == arc.target[2] {
                    arc.start[2]
                } else {
                    z_mid
                };
                self.include(&[arc.centre[0] + r * c, arc.centre[1] + r * s, z, 0.0]);
            }
        }
    }

    /// The summary so far.
    pub fn finish(mut self, warnings: u64) -> Stats {
        for ((letter, major, minor), count) in self.codes.drain() {
            let name = match minor {
                Some(minor) => format!("{}{major}.{minor}", letter as char),
                None => format!("{}{major}", letter as char),
            };
            *self.stats.commands.entry(name).or_default() += count;
        }
        self.stats.warnings = warnings;
        self.stats.layers = if self.stats.layer_markers > 0 {
            self.stats.layer_markers
        } else {
            self.stats.extrusion_z_levels
        };
        self.stats
    }
}

/// Summarises a whole input; stops at the first error.
pub fn file_stats(input: impl BufRead, source: impl Into<Arc<str>>) -> Result<Stats, GcodeError> {
    let mut reader = Reader::new(input, source);
    let source = Arc::clone(reader.source());
    let mut interpreter = Interpreter::new(InterpreterOptions::default());
    let mut collector = StatsCollector::new();
    while let Some(line) = reader.next_line() {
        let line = line?;
        collector.add_line(&line);
        interpreter.interpret_line(&line, &source)?;
        while let Some(command) = interpreter.pop_command() {
            collector.add_command(&command.value);
        }
    }
    interpreter.finish();
    while let Some(command) = interpreter.pop_command() {
        collector.add_command(&command.value);
    }
    let warnings = reader.warnings().total() + interpreter.warnings().total();
    Ok(collector.finish(warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_with_extrusion() {
        let text =
            "G90\nM82\nG0 X0 Y0 Z0.2\n;TYPE:Wall\nG1 X10 E1\nG1 Y10 E2\nG1 X0 E1.5\nG0 X-5 Y-5\n";
        let stats = file_stats(text.as_bytes(), "t").expect("stats");
        assert_eq!(stats.lines, 8);
        assert_eq!(stats.commands.get("G1"), Some(&3));
        assert_eq!(stats.commands.get("G90"), Some(&1));
        assert_eq!(stats.moves, 5);
        assert_eq!(stats.extruding_moves, 2);
        assert_eq!(stats.total_extrusion, 2.0);
        assert_eq!(stats.total_retraction, 0.5);
        assert!((stats.xy_travel - (30.0 + 250f64.sqrt())).abs() < 1e-12);
        assert_eq!(
            stats.extrusion_bbox,
            Some(BoundingBox {
                min: [0.0, 0.0, 0.2],
                max: [10.0, 10.0, 0.2]
            })
        );
        assert!(stats.features.contains("Wall"));
    }

    #[test]
    fn arc_bbox_reaches_the_circle_extremes() {
        // Half circle of radius 5 around (5, 0), counter-clockwise from (10,0) through (5,5) to (0,0).
        let stats = file_stats(&b"G1 X10 Y0\nG3 X0 Y0 I-5 J0 E3\n"[..], "t").expect("stats");
        let bbox = stats.extrusion_bbox.expect("bbox");
        assert!((bbox.max[1] - 5.0).abs() < 1e-12 && bbox.min[1].abs() < 1e-12);
        assert!((stats.xy_travel - (10.0 + 5.0 * std::f64::consts::PI)).abs() < 1e-12);
    }

    #[test]
    fn serialises_to_json() {
        let stats = file_stats(&b"G1 X1 E1\n"[..], "t").expect("stats");
        let json = serde_json::to_string(&stats).expect("json");
        assert!(json.contains("\"moves\":1"));
    }
}
