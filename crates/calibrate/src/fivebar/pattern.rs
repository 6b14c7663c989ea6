//! The five-bar calibration pattern: one small cross per pose, every pose built through the configured machine's
//! own kinematics (`kinematics::fivebar::Fivebar`: its working mode, reach, serial and parallel bands, motor
//! limits), so the motor readings it lists are the ones that machine commands at each cross centre as written in
//! the G-code. `calibrate fivebar-pattern` and the simulator both call [`machine_pattern`].
//!
//! Candidates lie on a grid over the box both arms reach; one is kept only where the machine accepts the whole
//! cross and a millimetre around it, away from its special poses. A greedy D-optimal design (the identification's
//! Jacobian at the configured geometry) picks the poses one at a time, each at least a cross and a gap from the
//! others; the crosses are printed in order of the left motor, travels between them turning the motors together
//! (via points every few degrees, each segment checked by the machine), or straight where that is refused.

use std::fmt::Write as _;

use kinematics::fivebar::Fivebar;
use kinematics::{Kinematics, Vec3};

use super::FivebarError;
use super::fit::{analyse_poses, suggest_poses};
use super::measurements::{CSV_HEADER, measurement_template};
use super::model::FivebarGeometry;
use crate::measured::degrees;
use crate::scara::PatternOptions;
use crate::scara::pattern::{CrossWriter, joint_travel, num, strokes, written};

/// Grid lines each way over the box both arms reach.
const GRID: usize = 40;
/// What the machine must accept beyond each stroke's end (mm): a machine built a little differently from its
/// config still prints the whole cross.
const CROSS_MARGIN: f64 = 1.0;
/// Least gap (mm) between two crosses' reaches: each stands alone, and calipers reach it.
const CROSS_GAP: f64 = 4.0;
/// Least |sin| of each side's proximal–distal angle and of the distal links' angle at a cross: a machine built a
/// little differently from its config still reaches it, and the distal links still meet there.
const POSE_SIN_FLOOR: f64 = 0.25;
/// Crosses in a pattern unless asked otherwise.
pub const DEFAULT_POSES: usize = 20;
/// Fewest poses a pattern may have: 10 parameters need 5 poses (10 equations).
pub const MIN_POSES: usize = 5;
/// The motor-space steps tried for a travel (degrees of the motor that turns most), coarse first.
const TRAVEL_STEPS_DEG: [f64; 4] = [5.0, 2.0, 1.0, 0.5];

/// A five-bar calibration pattern.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// Motor readings `(stepper_left, stepper_right)` (rad) the machine commands at each cross centre.
    pub poses: Vec<(f64, f64)>,
    /// Each cross centre as written in the G-code (the printer's X, Y in mm).
    pub centres: Vec<[f64; 2]>,
    pub gcode: String,
    /// The measurements file to fill in.
    pub template: String,
    pub condition_number: f64,
}

/// A candidate cross: its centre as written and the motor readings the machine commands there.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    centre: [f64; 2],
    motors: (f64, f64),
}

/// The candidate at bed point `p` (rounded as written) if the machine takes the whole cross there.
fn candidate(kin: &Fivebar, p: [f64; 2], o: &PatternOptions) -> Option<Candidate> {
    let (c, z, h) = (
        [written(p[0]), written(p[1])],
        written(o.layer_height),
        o.cross_size / 2.0,
    );
    let pose = kin.pose(c[0], c[1]).ok()?;
    if pose.parallel_sin.min(pose.arm_sin[0]).min(pose.arm_sin[1]) < POSE_SIN_FLOOR {
        return None;
    }
    let mut motors = [0.0; 3];
    kin.inverse([c[0], c[1], z], &mut motors).ok()?;
    kin.check_point([c[0], c[1], z]).ok()?;
    let accepted = strokes(c, h + CROSS_MARGIN, z)
        .iter()
        .chain(&strokes(c, h, z))
        .all(|(a, b)| kin.check_segment(*a, *b).is_ok());
    accepted.then_some(Candidate {
        centre: c,
        motors: (motors[0], motors[1]),
    })
}

/// Candidate crosses on a grid over the box of the points both arms reach.
fn candidates(kin: &Fivebar, o: &PatternOptions) -> Vec<Candidate> {
    let reach = |side: usize| {
        let arm = kin.arm(side);
        let r = arm.proximal + arm.distal;
        [
            arm.base[0] - r,
            arm.base[0] + r,
            arm.base[1] - r,
            arm.base[1] + r,
        ]
    };
    let (l, r) = (reach(0), reach(1));
    let (x0, x1) = (l[0].max(r[0]), l[1].min(r[1]));
    let (y0, y1) = (l[2].max(r[2]), l[3].min(r[3]));
    let at = |lo: f64, hi: f64, k: usize| lo + (hi - lo) * (k as f64 + 0.5) / GRID as f64;
    let mut out = Vec::new();
    for i in 0..GRID {
        for k in 0..GRID {
            out.extend(candidate(kin, [at(x0, x1, i), at(y0, y1, k)], o));
        }
    }
    out
}

/// Checks the options a pattern is made with.
fn check_options(o: &PatternOptions, count: usize) -> Result<(), FivebarError> {
    match o.problem(count, MIN_POSES, 10) {
        Some(problem) => Err(FivebarError::Pattern(problem)),
        None => Ok(()),
    }
}

/// The calibration pattern of `count` crosses for this machine (fewer when fewer poses take a whole cross, but at
/// least [`MIN_POSES`]).
pub fn machine_pattern(
    kin: &Fivebar,
    count: usize,
    o: &PatternOptions,
) -> Result<Pattern, FivebarError> {
    check_options(o, count)?;
    let all = candidates(kin, o);
    let nominal = FivebarGeometry::from(kin.params());
    let mut chosen = spaced_design(&nominal, &all, count, o.cross_size + CROSS_GAP);
    if chosen.len() < MIN_POSES {
        return Err(FivebarError::Pattern(format!(
            "only {} poses of this machine take a whole {} mm cross apart from the others (reach, serial and \
             parallel bands, motor limits); a pattern needs at least {MIN_POSES}",
            chosen.len(),
            o.cross_size
        )));
    }
    chosen.sort_by(|p, q| {
        p.motors
            .0
            .total_cmp(&q.motors.0)
            .then(p.motors.1.total_cmp(&q.motors.1))
    });
    let poses: Vec<(f64, f64)> = chosen.iter().map(|c| c.motors).collect();
    Ok(Pattern {
        gcode: pattern_gcode(kin, &chosen, o)?,
        template: measurement_template(&poses),
        condition_number: analyse_poses(&nominal, &poses)?.condition_number,
        centres: chosen.iter().map(|c| c.centre).collect(),
        poses,
    })
}

/// The greedy D-optimal design of up to `count` candidates, each at least `spacing` (mm) from those chosen before.
fn spaced_design(
    nominal: &FivebarGeometry,
    all: &[Candidate],
    count: usize,
    spacing: f64,
) -> Vec<Candidate> {
    let apart = |c: &Candidate, d: &Candidate| {
        (c.centre[0] - d.centre[0]).hypot(c.centre[1] - d.centre[1]) >= spacing
    };
    let mut chosen: Vec<Candidate> = Vec::new();
    while chosen.len() < count {
        let free: Vec<Candidate> = all
            .iter()
            .filter(|c| chosen.iter().all(|d| apart(c, d)))
            .copied()
            .collect();
        let motors: Vec<(f64, f64)> = free.iter().map(|c| c.motors).collect();
        let current: Vec<(f64, f64)> = chosen.iter().map(|c| c.motors).collect();
        match suggest_poses(nominal, &current, &motors, 1).first() {
            Some(&i) => chosen.push(free[i]),
            None => break,
        }
    }
    chosen
}

/// The G-code of the crosses in order, with the travels between them.
fn pattern_gcode(
    kin: &Fivebar,
    crosses: &[Candidate],
    o: &PatternOptions,
) -> Result<String, FivebarError> {
    let mut s = String::new();
    let writer = CrossWriter::new(o);
    let _ = writeln!(
        s,
        "; jointspace five-bar calibration pattern: {} crosses of {} mm\n\
         ; at each cross centre (x, y: the printer's X/Y) this machine commands the listed motor readings; measure\n\
         ; each cross centre on the bed and record: {}",
        crosses.len(),
        num(o.cross_size),
        CSV_HEADER.join(",")
    );
    writer.begin(&mut s);
    let mut last = start_of(kin, o.home);
    for (i, c) in crosses.iter().enumerate() {
        let _ = writeln!(
            s,
            "; pose {} motor_left_deg={} motor_right_deg={} x={} y={}",
            i + 1,
            degrees(c.motors.0),
            degrees(c.motors.1),
            num(c.centre[0]),
            num(c.centre[1])
        );
        let strokes = writer.strokes(c.centre);
        let vias = match last {
            Some(from) => travel(kin, from, c.motors, strokes[0].0)?,
            None => Vec::new(),
        };
        writer.cross(&mut s, &vias, &strokes);
        last = Some((strokes[2].1, c.motors));
    }
    writer.finish(&mut s);
    Ok(s)
}

/// Where a travel leaves from: the nozzle (as written) and the motor readings there.
type Travelling = (Vec3, (f64, f64));

/// The pose `G28` leaves, when known and the machine has motor readings for it.
fn start_of(kin: &Fivebar, home: Option<Vec3>) -> Option<Travelling> {
    let p = home?;
    let mut motors = [0.0; 3];
    kin.inverse(p, &mut motors).ok()?;
    Some((p, (motors[0], motors[1])))
}

/// Via points of the travel to a cross starting at `to` (motor readings `target` at its centre): the joint-space
/// travel both pattern makers use, else the straight line if the machine accepts that.
fn travel(
    kin: &Fivebar,
    from: Travelling,
    target: (f64, f64),
    to: Vec3,
) -> Result<Vec<[f64; 2]>, FivebarError> {
    if let Ok(vias) = joint_travel(kin, from, target, to, &TRAVEL_STEPS_DEG) {
        return Ok(vias);
    }
    let at = from.0;
    match kin.check_segment([at[0], at[1], to[2]], to) {
        Ok(()) => Ok(Vec::new()),
        Err(e) => Err(FivebarError::Pattern(format!(
            "no travel the machine accepts from X{} Y{} to the cross at X{} Y{}: {}",
            num(at[0]),
            num(at[1]),
            num(to[0]),
            num(to[1]),
            e.reason
        ))),
    }
}
