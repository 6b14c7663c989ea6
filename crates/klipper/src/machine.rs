//! One machine, built from the printer.cfg text the Python side hands over, and the questions Klipper's
//! kinematics class asks of it: which solver each stepper gets, forward kinematics, whether a move can be made
//! and how fast, the pose to report. The machine is built by the `config` crate exactly as the `jointspace`
//! command line builds it, so one printer.cfg means the same machine in both.

use std::ffi::{CStr, CString};
use std::path::Path;

use calibrate::scara::{Pattern, PatternError, PatternOptions};
use config::MachineConfig;
use kinematics::{Kinematics, MachineParams, MotorMap, SolverGeometry};
use motion::kinematic_limits::{JunctionSide, MotorLimit, caps_corners, junction_v2, split};

use crate::pieces::{Centre, Cuts, Waypoint, waypoints};
use crate::stepper::Solver;

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
}

/// A machine as the Klipper plug-in uses it. Immutable once built.
#[derive(Debug)]
pub struct Machine {
    /// Built by the `machine` crate, as every front-end builds it.
    machine: ::machine::Machine,
    /// The kinematics' motors, in their order, as C strings for the Python side.
    motor_names: Vec<CString>,
    /// `section key` lines of every config key the machine read (Klipper refuses keys nobody read).
    read_keys: CString,
    /// SCARA `home_position` (FEKT-SCARA's declared pose), if configured.
    declared_home: Option<[f64; 3]>,
    /// The host's arithmetic, for the solvers (see `abi::Move::coord`).
    fused: bool,
}

/// What a move may do, for Klipper's `check_move`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveVerdict {
    /// The cruise speed (mm/s) and acceleration (mm/s²) the whole move must stay within, where a motor limit binds.
    pub caps: Option<(f64, f64)>,
    /// It ends at a pose the arm may only rest at (a SCARA's nearly straight or folded arm): it must end at rest,
    /// as jointspace's planner makes it (the plug-in sets Klipper's next junction to zero).
    pub ends_at_rest: bool,
}

impl Machine {
    /// Builds the machine from printer.cfg text (only the sections it needs; includes are already resolved).
    pub fn from_config_text(text: &str, fused: bool) -> Result<Machine, String> {
        let machine =
            ::machine::Machine::from_text(text, "printer.cfg").map_err(|e| e.to_string())?;
        Machine::new(machine, fused)
    }

    /// Builds the machine from the printer.cfg file Klipper was started with (its includes and SAVE_CONFIG block
    /// read as the `jointspace` command line reads them), so an error names the owner's file, line and column.
    pub fn from_config_file(path: &Path, fused: bool) -> Result<Machine, String> {
        let (machine, _notes) = ::machine::Machine::load(path).map_err(|e| e.to_string())?;
        Machine::new(machine, fused)
    }

    fn new(machine: ::machine::Machine, fused: bool) -> Result<Machine, String> {
        let motor_names = machine
            .setup
            .kinematics
            .motors()
            .iter()
            .map(|m| CString::new(m.name.as_str()).map_err(|e| e.to_string()))
            .collect::<Result<_, _>>()?;
        let declared_home = machine
            .config
            .home_position
            .as_ref()
            .and_then(|p| match p[..] {
                [x, y] => Some([x, y, 0.0]),
                [x, y, z, ..] => Some([x, y, z]),
                _ => None,
            });
        Ok(Machine {
            read_keys: read_keys(&machine.config)?,
            machine,
            motor_names,
            declared_home,
            fused,
        })
    }

    pub fn kinematics(&self) -> &dyn Kinematics {
        self.machine.setup.kinematics.as_ref()
    }

    pub fn motor_names(&self) -> &[CString] {
        &self.motor_names
    }

    pub fn read_keys(&self) -> &CStr {
        &self.read_keys
    }

    pub fn fused(&self) -> bool {
        self.fused
    }

    pub fn declared_home(&self) -> Option<[f64; 3]> {
        self.declared_home
    }

    /// The step-time solver of the motor configured in section `name`, or `None` if it is not one of this
    /// machine's motors.
    pub fn solver(&self, name: &str) -> Option<Solver> {
        let kin = self.kinematics();
        let index = kin.motors().iter().position(|m| m.name == name)?;
        let solver = match (kin.motor_map(index), kin.solver_geometry()) {
            (MotorMap::Linear { coeffs }, _) => Solver::Linear { coeffs },
            (MotorMap::Radius { centre: [0.0, 0.0] }, SolverGeometry::Polar(_)) => {
                Solver::PolarRadius
            }
            (MotorMap::Angle { centre: [0.0, 0.0] }, SolverGeometry::Polar(_)) => {
                Solver::PolarAngle
            }
            (_, SolverGeometry::Polar(geometry)) => match index {
                kinematics::polar::BED => Solver::PolarBed {
                    geometry,
                    has_centre: kin.rotation_centre().is_some(),
                },
                kinematics::polar::ARM => Solver::PolarArm(geometry),
                _ => return None,
            },
            (_, SolverGeometry::Scara(geometry)) => match index {
                kinematics::scara::SHOULDER => Solver::ScaraShoulder(geometry),
                kinematics::scara::ELBOW => Solver::ScaraElbow(geometry),
                _ => return None,
            },
            (_, SolverGeometry::Fivebar(geometry)) => match index {
                kinematics::fivebar::LEFT | kinematics::fivebar::RIGHT => {
                    Solver::FivebarJoint(geometry.sides[index])
                }
                _ => return None,
            },
            _ => return None,
        };
        Some(solver)
    }

    /// Whether the straight move `start → end` can be made (the whole segment: reach, centre, singular poses,
    /// joint limits, offsets included), and the cruise speed and acceleration its motor limits allow over its
    /// whole length when requested at `speed` and `accel` (none when `speed` is not positive: the segment only).
    pub fn check_move(
        &self,
        start: [f64; 3],
        end: [f64; 3],
        speed: f64,
        accel: f64,
    ) -> Result<MoveVerdict, String> {
        let kin = self.kinematics();
        self.segment_refusal(start, end)?;
        let ends_at_rest = start != end && kin.rests_at(end);
        if speed.is_nan() || speed <= 0.0 {
            // The segment only (centre_slowdown: klipper caps by Klipper's own rule).
            return Ok(MoveVerdict {
                caps: None,
                ends_at_rest,
            });
        }
        let spans = split(
            kin,
            self.motor_limits(),
            start,
            end,
            speed,
            accel,
            self.cruise_ratio(),
        );
        let caps = (!spans.is_empty()).then(|| {
            let speed = spans.iter().map(|s| s.max_speed).fold(speed, f64::min);
            let accel = spans.iter().map(|s| s.max_accel).fold(accel, f64::min);
            (speed, accel)
        });
        Ok(MoveVerdict { caps, ends_at_rest })
    }

    /// Whether corners need capping ([`Self::junction_speed`]): some motor has an acceleration limit.
    pub fn caps_corners(&self) -> bool {
        caps_corners(self.motor_limits())
    }

    /// The highest speed (mm/s) at the corner where the move `points[0] → points[1]` (planned with acceleration
    /// `accels[0]`) meets `points[1] → points[2]` (`accels[1]`) that keeps each acceleration-limited motor's jump
    /// within its limit (`motion::kinematic_limits::junction_v2`); infinite where nothing caps it.
    pub fn junction_speed(&self, points: [[f64; 3]; 3], accels: [f64; 2]) -> f64 {
        let side = |start, end, accel| JunctionSide { start, end, accel };
        junction_v2(
            self.kinematics(),
            self.motor_limits(),
            side(points[0], points[1], accels[0]),
            side(points[1], points[2], accels[1]),
        )
        .sqrt()
    }

    /// Where the G-code move transform cuts the move `start → end` (see [`crate::pieces`]); `bed_angle` is where
    /// the last move left a polar bed; `cut_spans`: also at the boundaries of its motor limits' spans (else only the
    /// centre shapes the move). The reason, when a piece of it cannot be made.
    pub fn waypoints(
        &self,
        start: [f64; 3],
        end: [f64; 3],
        speed: f64,
        accel: f64,
        bed_angle: f64,
        cut_spans: bool,
    ) -> Result<Vec<Waypoint>, String> {
        let kin = self.kinematics();
        let limits = self.motor_limits();
        let cuts = |a: [f64; 3], b: [f64; 3]| {
            let length = distance(a, b);
            let spans = split(kin, limits, a, b, speed, accel, self.cruise_ratio());
            spans.iter().map(|s| s.end / length).collect::<Vec<_>>()
        };
        let centre = kin.rotation_centre().map(|c| Centre {
            at: c.point,
            radius: c.tolerance,
            bed_angle,
        });
        let points = waypoints(start, end, centre, cut_spans.then_some(&cuts as Cuts));
        self.check_route(start, &points, end[2])?;
        Ok(points)
    }

    /// Every piece of a route the transform would queue can be made (so a refused move queues nothing). A route of
    /// one piece is the move itself: its end is checked here (for the owner's message), its whole segment by
    /// Klipper's `check_move`, which refuses it whole.
    fn check_route(&self, start: [f64; 3], points: &[Waypoint], end_z: f64) -> Result<(), String> {
        let at = |p: &Waypoint| [p.x, p.y, start[2] + (end_z - start[2]) * p.fraction];
        let ends = [start, points.last().map_or(start, at)];
        if ends.iter().flatten().any(|v| !v.is_finite()) {
            return Err("a coordinate of the move is not finite".to_string());
        }
        let kin = self.kinematics();
        if let Some(beyond) = points
            .last()
            .and_then(|p| kin.refusal_in_owner_terms(at(p), at(p)))
        {
            return Err(beyond);
        }
        if points.len() < 2 {
            return Ok(());
        }
        let mut from = start;
        for p in points {
            let to = at(p);
            self.segment_refusal(from, to)?;
            from = to;
        }
        Ok(())
    }

    /// Why the segment `a → b` cannot be made, in the owner's terms: how far beyond the arm's reach its end lies,
    /// how close to a SCARA's shoulder it passes, else the kinematics' reason (where along the segment it lies means
    /// nothing to the G-code line's owner).
    fn segment_refusal(&self, a: [f64; 3], b: [f64; 3]) -> Result<(), String> {
        // The owner's terms are worked out only for a refusal: check_move asks this of every move.
        let kin = self.kinematics();
        kin.check_segment(a, b).map_err(|e| {
            kin.refusal_in_owner_terms(a, b)
                .unwrap_or_else(|| e.reason.to_string())
        })
    }

    /// A SCARA's calibration pattern, made by the one pattern maker `calibrate scara-pattern` uses
    /// (`calibrate::scara::machine_pattern`: every pose through this machine's inverse, from where homing leaves the
    /// arm); `None` for other machines.
    pub fn scara_pattern(
        &self,
        count: usize,
        options: &PatternOptions,
    ) -> Option<Result<Pattern, PatternError>> {
        let scara = kinematics::scara::Scara::of(self.kinematics())?;
        let options = PatternOptions {
            home: self.declared_home.or(self.machine.setup.home_position),
            ..options.clone()
        };
        Some(calibrate::scara::machine_pattern(scara, count, &options))
    }

    /// The `minimum_cruise_ratio` of the config (Klipper's lookahead uses the same).
    fn cruise_ratio(&self) -> f64 {
        self.machine.setup.planner.limits.minimum_cruise_ratio
    }

    fn motor_limits(&self) -> &[MotorLimit] {
        &self.machine.setup.planner.kinematic_limits
    }

    /// How far `p` is from the edge of what the machine reaches (mm, negative outside); `None` for a Cartesian
    /// machine (its limits are per axis).
    pub fn reach_margin(&self, p: [f64; 3]) -> Option<f64> {
        self.kinematics().reach_margin(p)
    }

    /// The value the machine was built with for one of its `[printer]` keys the plug-in needs (a polar arm's
    /// `arm_zero_offset`, `arm_lateral_offset`; a SCARA's `link1_length`, `link2_length`, `offset_x`, `offset_y`; a
    /// five-bar's `{left,right}_base_{x,y}`, `{left,right}_{proximal,distal}_length`; any machine's
    /// `max_z_velocity`, `max_z_accel`), so the plug-in never reads one a second time; `None` for a key this machine
    /// does not have.
    pub fn printer_value(&self, key: &str) -> Option<f64> {
        let planner = &self.machine.setup.planner;
        match (&self.machine.config.params, key) {
            (_, "max_z_velocity") => Some(planner.max_z_velocity),
            (_, "max_z_accel") => Some(planner.max_z_accel),
            (MachineParams::Polar(p), "arm_zero_offset") => Some(p.arm_zero_offset),
            (MachineParams::Polar(p), "arm_lateral_offset") => Some(p.arm_lateral_offset),
            (MachineParams::Scara(s), "link1_length") => Some(s.link1_length),
            (MachineParams::Scara(s), "link2_length") => Some(s.link2_length),
            (MachineParams::Scara(s), "offset_x") => Some(s.offset_x),
            (MachineParams::Scara(s), "offset_y") => Some(s.offset_y),
            (MachineParams::Fivebar(f), key) => fivebar_value(f, key),
            _ => None,
        }
    }
}

/// A five-bar's `[printer]` value by key: `left_` or `right_` and the arm's own key.
fn fivebar_value(params: &kinematics::FivebarParams, key: &str) -> Option<f64> {
    let (arm, rest) = if let Some(rest) = key.strip_prefix("left_") {
        (&params.left, rest)
    } else {
        (&params.right, key.strip_prefix("right_")?)
    };
    match rest {
        "base_x" => Some(arm.base[0]),
        "base_y" => Some(arm.base[1]),
        "proximal_length" => Some(arm.proximal),
        "distal_length" => Some(arm.distal),
        _ => None,
    }
}

/// Every `section key` the config reader read, one per line.
fn read_keys(config: &MachineConfig) -> Result<CString, String> {
    let mut lines = String::new();
    for section in config.document.sections() {
        for entry in section.entries().iter().filter(|e| e.was_read()) {
            lines.push_str(section.name());
            lines.push(' ');
            lines.push_str(entry.key());
            lines.push('\n');
        }
    }
    CString::new(lines).map_err(|e| e.to_string())
}
