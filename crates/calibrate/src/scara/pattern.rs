//! The SCARA calibration pattern: one small cross per pose, every pose built through the configured machine's own
//! inverse kinematics (its elbow branch, frame, offsets, coupling, zeros, joint and motor limits, base radius and
//! singular band), so the motor angles it lists are the angles that machine commands at each cross centre as
//! written in the G-code. The CLI (`calibrate scara-pattern`) and the printer (`JOINTSPACE_SCARA_PATTERN`) both
//! call [`machine_pattern`].
//!
//! Candidates lie on rings about the shoulder (every 5° of direction); a candidate is kept only where the machine
//! accepts the whole cross and a millimetre around it (`check_segment` of each stroke at the first layer's height).
//! Among them a greedy D-optimal design picks the poses (the identification's Jacobian at the nominal geometry);
//! no cross or travel crosses the shoulder's branch cut (q1 = ±π, where the printer's solvers refuse a move);
//! the crosses are printed in shoulder order, travels between them turning the joints (via points every few degrees
//! of motor angle, each travel segment checked by the machine and cut finer where it refuses one).

use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;

use kinematics::scara::Scara;
use kinematics::{Kinematics, ScaraFrame, Vec3};
use serde::{Deserialize, Serialize};

use super::measurements::{CSV_HEADER, degrees, frame_name, measurement_template};
use super::{ScaraGeometry, analyse_poses, suggest_poses};

/// Rings of candidate cross centres between the innermost and outermost distance the links allow.
const RINGS: usize = 24;
/// Directions of candidate cross centres about the shoulder.
const DIRECTIONS: usize = 72;
/// What the machine must accept beyond each stroke's end (mm): an arm built a little differently from its config
/// still prints the whole cross.
const CROSS_MARGIN: f64 = 1.0;
/// Least gap (mm) between two crosses' reaches: each cross stands alone on a scan, and calipers reach it.
const CROSS_GAP: f64 = 4.0;
/// Crosses in a pattern unless asked otherwise.
pub const DEFAULT_POSES: usize = 20;
/// Fewest poses a pattern may have: 7 parameters need 4 poses (8 equations).
pub const MIN_POSES: usize = 4;
/// The joint-space steps tried for a travel (degrees of the motor that turns most), coarse first.
const TRAVEL_STEPS_DEG: [f64; 5] = [5.0, 2.0, 1.0, 0.5, 0.2];

/// Options for the printed calibration pattern.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PatternOptions {
    /// Length of each cross arm, tip to tip (mm).
    pub cross_size: f64,
    pub layer_height: f64,
    /// Filament length per mm of line (mm).
    pub extrusion_per_mm: f64,
    pub print_speed: f64,
    pub travel_speed: f64,
    /// Where `G28` leaves the nozzle (bed X, Y, Z), if known: the first travel then turns the joints from there
    /// instead of going straight.
    #[serde(default)]
    pub home: Option<Vec3>,
}

impl PatternOptions {
    /// What is wrong with these options for a pattern of `count` crosses (at least `min_poses`, for a fit of
    /// `parameters`), if anything.
    pub(crate) fn problem(
        &self,
        count: usize,
        min_poses: usize,
        parameters: usize,
    ) -> Option<String> {
        let positive = [
            ("cross size", self.cross_size),
            ("layer height", self.layer_height),
            ("extrusion per mm", self.extrusion_per_mm),
            ("print speed", self.print_speed),
            ("travel speed", self.travel_speed),
        ];
        if let Some((name, v)) = positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Some(format!(
                "the pattern's {name} must be a positive number, not {v}"
            ));
        }
        (count < min_poses).then(|| {
            format!("a pattern needs at least {min_poses} crosses ({parameters} parameters), {count} asked")
        })
    }
}

/// How a pattern's crosses are written: the layer, each cross's strokes and the travels to them, as both pattern
/// makers (SCARA, five-bar) write them.
pub(crate) struct CrossWriter {
    /// Half the cross size and the layer height as written (mm).
    half: f64,
    z: f64,
    /// Filament per stroke and the print and travel feed rates, as written.
    extrusion: String,
    print_feed: String,
    travel_feed: String,
}

impl CrossWriter {
    pub(crate) fn new(o: &PatternOptions) -> Self {
        CrossWriter {
            half: o.cross_size / 2.0,
            z: written(o.layer_height),
            extrusion: num(o.cross_size * o.extrusion_per_mm),
            print_feed: num(o.print_speed * 60.0),
            travel_feed: num(o.travel_speed * 60.0),
        }
    }

    /// Units, modes, homing and the first layer's height.
    pub(crate) fn begin(&self, s: &mut String) {
        let _ = writeln!(s, "G21\nG90\nM83\nG28\nG1 Z{} F600", num(self.z));
    }

    /// The strokes of the cross at `centre` (see [`strokes`]).
    pub(crate) fn strokes(&self, centre: [f64; 2]) -> [(Vec3, Vec3); 3] {
        strokes(centre, self.half, self.z)
    }

    /// The travel's via points to the cross, then its two strokes.
    pub(crate) fn cross(&self, s: &mut String, vias: &[[f64; 2]], strokes: &[(Vec3, Vec3); 3]) {
        let [(start, first), (_, second), (_, end)] = strokes;
        let (e, fp, ft) = (&self.extrusion, &self.print_feed, &self.travel_feed);
        for [vx, vy] in vias {
            let _ = writeln!(s, "G0 X{} Y{} F{ft}", num(*vx), num(*vy));
        }
        let _ = writeln!(s, "G0 X{} Y{} F{ft}", num(start[0]), num(start[1]));
        let _ = writeln!(s, "G1 X{} Y{} E{e} F{fp}", num(first[0]), num(first[1]));
        let _ = writeln!(s, "G0 X{} Y{} F{ft}", num(second[0]), num(second[1]));
        let _ = writeln!(s, "G1 X{} Y{} E{e} F{fp}", num(end[0]), num(end[1]));
    }

    /// The nozzle lifted clear and the motors off.
    pub(crate) fn finish(&self, s: &mut String) {
        let _ = writeln!(s, "G1 Z{} F600\nM84", num(self.z + 5.0));
    }
}

impl Default for PatternOptions {
    fn default() -> Self {
        Self {
            cross_size: 6.0,
            layer_height: 0.3,
            extrusion_per_mm: 0.04,
            print_speed: 20.0,
            travel_speed: 100.0,
            home: None,
        }
    }
}

/// A calibration pattern for one machine.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// Motor angles `(stepper_a, stepper_b)` (rad) the machine commands at each cross centre.
    pub poses: Vec<(f64, f64)>,
    /// Each cross centre as written in the G-code (the printer's X, Y in mm).
    pub centres: Vec<[f64; 2]>,
    /// The frame the angles count in (the machine's).
    pub frame: ScaraFrame,
    pub gcode: String,
    /// The measurements file to fill in (see [`measurement_template`]).
    pub template: String,
    pub condition_number: f64,
    /// The two crosses (0-based) best for a scan's reference distance: the farthest apart along X within
    /// [`REFERENCE_ACROSS`] along Y and [`REFERENCE_REACH`] along X, so calipers measure across their strokes
    /// along Y.
    pub reference: Option<(usize, usize)>,
}

/// How far apart along Y (mm) a reference pair's crosses may be: the calipers' jaws reach both strokes along Y.
pub const REFERENCE_ACROSS: f64 = 20.0;
/// How far apart along X (mm) they may be: common calipers' range.
pub const REFERENCE_REACH: f64 = 150.0;

/// The reference pair among `centres` (see [`Pattern::reference`]).
fn reference_pair(centres: &[[f64; 2]]) -> Option<(usize, usize)> {
    let mut best: Option<(usize, usize, f64)> = None;
    for i in 0..centres.len() {
        for j in i + 1..centres.len() {
            let dx = (centres[i][0] - centres[j][0]).abs();
            let dy = (centres[i][1] - centres[j][1]).abs();
            if dy <= REFERENCE_ACROSS && dx <= REFERENCE_REACH && best.is_none_or(|b| dx > b.2) {
                best = Some((i, j, dx));
            }
        }
    }
    best.map(|(i, j, _)| (i, j))
}

/// The comment lines naming the reference pair, `prefix` before each (`;` for G-code, `#` for the file).
fn reference_note(reference: Option<(usize, usize)>, prefix: &str) -> String {
    match reference {
        Some((a, b)) => format!(
            "{prefix} for a scan: measure with calipers between crosses {} and {} across their strokes along Y (the mean of\n\
             {prefix} the outside and the inside distance) and give it as --reference {},{}=MM\n",
            a + 1,
            b + 1,
            a + 1,
            b + 1
        ),
        None => String::new(),
    }
}

/// Why no pattern could be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PatternError {
    #[error("{0}")]
    Options(String),
    #[error(
        "only {found} poses of this arm take a whole {cross} mm cross (reach, base radius, singular band, joint and \
         motor limits); a pattern needs at least {MIN_POSES}"
    )]
    TooFewPoses { found: usize, cross: f64 },
    #[error("no travel the machine accepts from X{} Y{} to the cross at X{} Y{}: {reason}", num(from[0]), num(from[1]), num(to[0]), num(to[1]))]
    Travel {
        from: [f64; 2],
        to: [f64; 2],
        reason: String,
    },
}

/// Fixed-decimal number without `-0.000`.
pub(crate) fn num(v: f64) -> String {
    let s = format!("{v:.3}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0.000".to_string()
    } else {
        s
    }
}

/// `v` as the G-code writes it and the firmware reads it back (3 decimals).
pub(crate) fn written(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

/// A candidate cross: its centre as written and the motor angles the machine commands there.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    centre: [f64; 2],
    motors: (f64, f64),
}

/// The strokes of a cross at `c` of half-size `h` as written: horizontal, the travel between, vertical.
pub(crate) fn strokes(c: [f64; 2], h: f64, z: f64) -> [(Vec3, Vec3); 3] {
    let (x0, x1) = (written(c[0] - h), written(c[0] + h));
    let (y0, y1) = (written(c[1] - h), written(c[1] + h));
    [
        ([x0, c[1], z], [x1, c[1], z]),
        ([x1, c[1], z], [c[0], y0, z]),
        ([c[0], y0, z], [c[0], y1, z]),
    ]
}

/// The candidate at bed point `p` (rounded as written) if the machine takes the whole cross there.
fn candidate(kin: &Scara, p: [f64; 2], o: &PatternOptions) -> Option<Candidate> {
    let (c, z, h) = (
        [written(p[0]), written(p[1])],
        written(o.layer_height),
        o.cross_size / 2.0,
    );
    let mut motors = [0.0; 3];
    kin.inverse([c[0], c[1], z], &mut motors).ok()?;
    kin.check_point([c[0], c[1], z]).ok()?;
    let wide = strokes(c, h + CROSS_MARGIN, z);
    let exact = strokes(c, h, z);
    let accepted = wide
        .iter()
        .chain(&exact)
        .all(|(a, b)| kin.check_segment(*a, *b).is_ok());
    accepted.then_some(Candidate {
        centre: c,
        motors: (motors[0], motors[1]),
    })
}

/// Candidate crosses on rings about the shoulder, in the arm's frame turned into the bed's.
fn candidates(kin: &Scara, o: &PatternOptions) -> Vec<Candidate> {
    let g = kin.geometry();
    let (l1, l2) = g.link_lengths();
    let (lo, hi) = ((l1 - l2).abs(), l1 + l2);
    let mut out = Vec::new();
    for ring in 1..RINGS {
        let rho = lo + (hi - lo) * ring as f64 / RINGS as f64;
        for k in 0..DIRECTIONS {
            let theta = -PI + TAU * k as f64 / DIRECTIONS as f64;
            let (x, y) = g.bed_frame(rho * theta.cos(), rho * theta.sin());
            out.extend(candidate(kin, [x, y], o));
        }
    }
    out
}

/// Checks the options a pattern is made with.
fn check_options(o: &PatternOptions, count: usize) -> Result<(), PatternError> {
    match o.problem(count, MIN_POSES, 7) {
        Some(problem) => Err(PatternError::Options(problem)),
        None => Ok(()),
    }
}

/// The calibration pattern of `count` crosses for this machine (fewer when fewer poses take a whole cross, but at
/// least [`MIN_POSES`]).
pub fn machine_pattern(
    kin: &Scara,
    count: usize,
    o: &PatternOptions,
) -> Result<Pattern, PatternError> {
    check_options(o, count)?;
    let kin = &within_branch_cut(kin)?;
    let all = candidates(kin, o);
    if all.len() < MIN_POSES {
        return Err(PatternError::TooFewPoses {
            found: all.len(),
            cross: o.cross_size,
        });
    }
    let nominal = ScaraGeometry::from(kin.params());
    let mut chosen = spaced_design(&nominal, &all, count, o.cross_size + CROSS_GAP);
    if chosen.len() < MIN_POSES {
        return Err(PatternError::TooFewPoses {
            found: chosen.len(),
            cross: o.cross_size,
        });
    }
    // One sweep of the shoulder: short joint-space travels.
    chosen.sort_by(|p, q| {
        p.motors
            .0
            .total_cmp(&q.motors.0)
            .then(p.motors.1.total_cmp(&q.motors.1))
    });
    let poses: Vec<(f64, f64)> = chosen.iter().map(|c| c.motors).collect();
    let frame = kin.params().frame;
    let centres: Vec<[f64; 2]> = chosen.iter().map(|c| c.centre).collect();
    let reference = reference_pair(&centres);
    let mut gcode = pattern_gcode(kin, &chosen, o)?;
    let mut template = measurement_template(&poses, frame);
    let header = |text: &mut String, prefix: &str| {
        let at = text.find('\n').map_or(0, |i| i + 1);
        text.insert_str(at, &reference_note(reference, prefix));
    };
    header(&mut gcode, ";");
    header(&mut template, "#");
    Ok(Pattern {
        gcode,
        template,
        reference,
        condition_number: analyse_poses(&nominal, &poses).condition_number,
        centres,
        poses,
        frame,
    })
}

/// The greedy D-optimal design of `count` candidates, each at least `spacing` (mm) from those chosen before it.
/// The plain design is kept when its crosses are already that far apart.
fn spaced_design(
    nominal: &ScaraGeometry,
    all: &[Candidate],
    count: usize,
    spacing: f64,
) -> Vec<Candidate> {
    let apart = |c: &Candidate, d: &Candidate| {
        (c.centre[0] - d.centre[0]).hypot(c.centre[1] - d.centre[1]) >= spacing
    };
    let motors: Vec<(f64, f64)> = all.iter().map(|c| c.motors).collect();
    let plain: Vec<Candidate> = suggest_poses(nominal, &[], &motors, count)
        .iter()
        .filter_map(|p| all.iter().find(|c| c.motors == *p).copied())
        .collect();
    if plain
        .iter()
        .enumerate()
        .all(|(i, c)| plain[i + 1..].iter().all(|d| apart(c, d)))
    {
        return plain;
    }
    let mut chosen: Vec<Candidate> = Vec::new();
    while chosen.len() < count {
        let free: Vec<(f64, f64)> = all
            .iter()
            .filter(|c| chosen.iter().all(|d| apart(c, d)))
            .map(|c| c.motors)
            .collect();
        let current: Vec<(f64, f64)> = chosen.iter().map(|c| c.motors).collect();
        let Some(pick) = suggest_poses(nominal, &current, &free, 1).first().copied() else {
            break;
        };
        match all.iter().find(|c| c.motors == pick) {
            Some(c) => chosen.push(*c),
            None => break,
        }
    }
    chosen
}

/// The machine with its shoulder joint kept within (−π, π]: the printer's step solvers take q1 there (as the
/// FEKT-SCARA module does) and refuse a move through q1 = ±π, so no cross or travel crosses it, and the printer and
/// the command line make the same pattern of one config.
fn within_branch_cut(kin: &Scara) -> Result<Scara, PatternError> {
    let mut params = kin.params().clone();
    params.shoulder_limits = Some(kinematics::scara::within_branch_cut(params.shoulder_limits));
    Scara::new(params).map_err(|e| PatternError::Options(e.to_string()))
}

/// The G-code of the crosses in order, with the travels between them.
fn pattern_gcode(
    kin: &Scara,
    crosses: &[Candidate],
    o: &PatternOptions,
) -> Result<String, PatternError> {
    let mut s = String::new();
    let writer = CrossWriter::new(o);
    let _ = writeln!(
        s,
        "; jointspace SCARA calibration pattern: {} crosses of {} mm, frame {}",
        crosses.len(),
        num(o.cross_size),
        frame_name(kin.params().frame)
    );
    let _ = writeln!(
        s,
        "; at each cross centre (x, y: the printer's X/Y) this machine's inverse kinematics commands the listed motor\n\
         ; angles; measure each cross centre on the bed and record: {}",
        CSV_HEADER.join(",")
    );
    writer.begin(&mut s);
    let mut last = start_of(kin, o.home);
    for (i, c) in crosses.iter().enumerate() {
        let [x, y] = c.centre;
        let _ = writeln!(
            s,
            "; pose {} motor_a_deg={} motor_b_deg={} x={} y={}",
            i + 1,
            degrees(c.motors.0),
            degrees(c.motors.1),
            num(x),
            num(y)
        );
        let strokes = writer.strokes(c.centre);
        let vias = match last {
            Some(from) => travel(kin, from, c.motors, strokes[0].0)?,
            None => Vec::new(),
        };
        writer.cross(&mut s, &vias, &strokes);
        last = Some(Travelling {
            at: strokes[2].1,
            motors: c.motors,
        });
    }
    writer.finish(&mut s);
    Ok(s)
}

/// Where a travel leaves from: the nozzle (as written, at the layer's height) and the motor angles near it.
#[derive(Debug, Clone, Copy)]
struct Travelling {
    at: Vec3,
    motors: (f64, f64),
}

/// The pose `G28` leaves, when known and the machine has motor angles for it.
fn start_of(kin: &Scara, home: Option<Vec3>) -> Option<Travelling> {
    let p = home?;
    let mut motors = [0.0; 3];
    kin.inverse(p, &mut motors).ok()?;
    Some(Travelling {
        at: p,
        motors: (motors[0], motors[1]),
    })
}

/// Via points of the travel to a cross starting at `to` (motor angles `target` at its centre): the motors turned
/// linearly from one pose's angles to the next's, as a joint move would (on a branch the radius depends on the
/// elbow joint alone, which changes monotonically, so the travel keeps clear of the base and the singular
/// circles); see [`joint_travel`].
fn travel(
    kin: &Scara,
    from: Travelling,
    target: (f64, f64),
    to: Vec3,
) -> Result<Vec<[f64; 2]>, PatternError> {
    joint_travel(kin, (from.at, from.motors), target, to, &TRAVEL_STEPS_DEG).map_err(|reason| {
        PatternError::Travel {
            from: [from.at[0], from.at[1]],
            to: [to[0], to[1]],
            reason,
        }
    })
}

/// Via points of a travel from `at` (motor readings `motors`) to `to` (readings `target` at the next cross, the
/// layer's height): both motors turned together from one pose's readings to the next's, each via point rounded as
/// written; the coarsest of `steps_deg` (degrees of the motor that turns most) at which the machine accepts every
/// segment. Else why the last segment tried was refused (empty when no via point had a pose). Both pattern makers'
/// travels.
pub(crate) fn joint_travel(
    kin: &dyn Kinematics,
    (at, motors): (Vec3, (f64, f64)),
    target: (f64, f64),
    to: Vec3,
    steps_deg: &[f64],
) -> Result<Vec<[f64; 2]>, String> {
    let z = to[2];
    let (da, db) = (target.0 - motors.0, target.1 - motors.1);
    let mut refusal = String::new();
    for step in steps_deg {
        let steps = (da.abs().max(db.abs()) / step.to_radians()).ceil().max(1.0) as usize;
        let vias: Option<Vec<[f64; 2]>> = (1..steps)
            .map(|i| {
                let f = i as f64 / steps as f64;
                let p = kin
                    .forward(&[motors.0 + da * f, motors.1 + db * f, z])
                    .ok()?;
                Some([written(p[0]), written(p[1])]).filter(|p| p.iter().all(|v| v.is_finite()))
            })
            .collect();
        let Some(vias) = vias else { continue };
        let mut points = vec![[at[0], at[1], z]];
        points.extend(vias.iter().map(|p| [p[0], p[1], z]));
        points.push(to);
        match points
            .windows(2)
            .map(|w| kin.check_segment(w[0], w[1]))
            .find_map(Result::err)
        {
            None => return Ok(vias),
            Some(e) => refusal = e.reason.to_string(),
        }
    }
    Err(refusal)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_format_has_no_negative_zero() {
        assert_eq!(num(-0.0001), "0.000");
        assert_eq!(num(-1.25), "-1.250");
        assert_eq!(written(1.23449), 1.234);
    }
}
