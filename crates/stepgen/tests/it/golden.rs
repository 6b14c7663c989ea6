//! Every case of `../shared/golden`: Klipper's planned moves in, Klipper's exact step files to compare with.
//!
//! Requirement: per motor the same number of steps and the same direction sequence, every clock within
//! ±1 tick, with two documented exceptions checked independently:
//! * Klipper's secant search stops once the position is within 1e-9 (motor units) of the half-step level.
//!   Where the motor is slow (a bed or joint turning round) that is more than a tick; such a step must then
//!   be a valid Klipper answer: the ideal position at the golden clock (evaluated here through the
//!   kinematics, not through stepgen) is within 1e-9 of the level, up to half a tick of motion.
//! * `queue_step` intervals are 32-bit, so after an idle gap longer than 2^32 ticks (268 s) the golden clocks
//!   are 2^32 ticks early; clocks are compared modulo 2^32 (the MCU clock is 32-bit).

use std::path::{Path, PathBuf};

use std::f64::consts::TAU;

use kinematics::{Kinematics, MotorMap};
use serde_json::Value;
use stepgen::{ExtruderSpec, Step, StepGenConfig, StepGenerator, read_moves_csv, read_step_file};
use trapq::{Piece, Queue};

use crate::machines;

fn golden_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/golden");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!("SKIPPED: golden data not found at {}", dir.display());
        None
    }
}

fn number(v: &Value, path: &[&str]) -> f64 {
    let mut cur = v;
    for key in path {
        cur = &cur[*key];
    }
    cur.as_f64()
        .unwrap_or_else(|| panic!("summary.json: {path:?} is not a number"))
}

/// The case's machine; a SCARA with the FEKT fork's cos quirk when `cos_quirk`.
fn machine(summary: &Value, cos_quirk: bool) -> Box<dyn Kinematics> {
    let step = |name: &str| number(summary, &["steppers", name, "step_dist"]);
    match summary["kinematics"].as_str() {
        Some("cartesian") => {
            machines::cartesian(step("stepper_x"), step("stepper_y"), step("stepper_z"))
        }
        Some("polar") => {
            machines::polar(step("stepper_bed"), step("stepper_arm"), step("stepper_z"))
        }
        Some("scara") => {
            let p = |k: &str| number(summary, &["kinematics_params", k]);
            machines::scara_fekt_arm(
                step("stepper_a"),
                step("stepper_b"),
                step("stepper_z"),
                p("link1_length"),
                p("link2_length"),
                [p("offset_x"), p("offset_y")],
                p("ecr"),
                cos_quirk,
            )
        }
        other => panic!("unknown kinematics {other:?}"),
    }
}

/// Result of comparing one motor's steps with the golden file.
#[derive(Debug, Default)]
struct Comparison {
    ours: usize,
    theirs: usize,
    first_dir_mismatch: Option<usize>,
    max_clock_diff: i64,
    off_by_one: usize,
    /// Indices of steps more than one tick apart.
    beyond_one: Vec<usize>,
}

/// Clock difference modulo 2^32 (see the module comment).
fn clock_diff(ours: u64, theirs: u64) -> i64 {
    ours.wrapping_sub(theirs) as u32 as i32 as i64
}

fn compare(ours: &[Step], theirs: &[Step]) -> Comparison {
    let mut c = Comparison {
        ours: ours.len(),
        theirs: theirs.len(),
        ..Default::default()
    };
    for (i, (a, b)) in ours.iter().zip(theirs).enumerate() {
        if a.dir != b.dir && c.first_dir_mismatch.is_none() {
            c.first_dir_mismatch = Some(i);
        }
        let diff = clock_diff(a.clock, b.clock);
        if diff.abs() == 1 {
            c.off_by_one += 1;
        }
        if diff.abs() > 1 {
            c.beyond_one.push(i);
        }
        if diff.abs() > c.max_clock_diff.abs() {
            c.max_clock_diff = diff;
        }
    }
    c
}

/// The motor's ideal position at absolute time `t`, from the toolhead pieces and the kinematics.
struct IdealMotor<'a> {
    kin: &'a dyn Kinematics,
    pieces: &'a [Piece],
    index: usize,
    is_angle: bool,
}

impl IdealMotor<'_> {
    fn position(&self, t: f64, near: f64) -> f64 {
        let at = self
            .pieces
            .partition_point(|p| p.print_time <= t)
            .saturating_sub(1);
        let piece = &self.pieces[at];
        let local = (t - piece.print_time).clamp(0.0, piece.duration.max(0.0));
        let mut motors = vec![0.0; self.kin.motors().len()];
        self.kin
            .inverse(piece.position(local), &mut motors)
            .expect("pose along a golden move is reachable");
        let raw = motors[self.index];
        if self.is_angle {
            raw + TAU * ((near - raw) / TAU).round()
        } else {
            raw
        }
    }

    /// True when the exact crossing of `level` lies within half a tick of clock `ours`.
    fn exact_at(&self, ours: u64, hz: f64, level: f64) -> bool {
        let t = ours as f64 / hz;
        let half_tick = 0.5 / hz;
        let before = self.position(t - half_tick, level) - level;
        let after = self.position(t + half_tick, level) - level;
        // A crossing inside the tick, or a touch within rounding of the level.
        before * after <= 0.0 || before.abs().min(after.abs()) <= 1e-12
    }

    /// True when clock `golden` is an answer Klipper's search can return for the crossing of `level`:
    /// within 1e-9 of the level, allowing half a tick of motion for the rounding to a clock.
    fn accepts(&self, golden: u64, hz: f64, level: f64) -> bool {
        let t = golden as f64 / hz;
        let half_tick = 0.5 / hz;
        let values = [t - half_tick, t, t + half_tick].map(|x| self.position(x, level) - level);
        let slack = (values[2] - values[0]).abs() * 0.5;
        values[1].abs() <= 1e-9 + slack + 1e-12
    }
}

fn run_case(dir: &Path, solver: Solver) -> Vec<String> {
    let case = dir
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json readable");
    let summary: Value = serde_json::from_str(&text).expect("summary.json is JSON");
    // `reference` evaluates ideal positions for the checks; `kin` drives the generator.
    let reference = machine(&summary, true);
    let kin = match solver {
        Solver::ClosedForms => machine(&summary, true),
        Solver::General => Box::new(AsGeneral(machine(&summary, true))),
        Solver::ScaraJoint => machine(&summary, false),
    };
    let start = [
        number(&summary, &["start_position", "x"]),
        number(&summary, &["start_position", "y"]),
        number(&summary, &["start_position", "z"]),
    ];
    let extruder = ExtruderSpec {
        name: "extruder".to_string(),
        step_distance: number(&summary, &["steppers", "extruder", "step_dist"]),
        start_position: 0.0,
    };
    let config = StepGenConfig {
        clock_hz: number(&summary, &["mcu_clock_freq"]),
        ..Default::default()
    };
    let moves = read_moves_csv(dir.join("moves.csv.gz")).expect("moves.csv.gz readable");
    let toolhead_pieces: Vec<Piece> = moves
        .iter()
        .filter(|(q, _)| *q == Queue::Toolhead)
        .flat_map(|(_, m)| m.pieces())
        .collect();
    let mut start_motors = vec![0.0; kin.motors().len()];
    kin.inverse(start, &mut start_motors)
        .expect("start pose reachable");
    let mut generator =
        StepGenerator::new(kin.as_ref(), start, Some(extruder), config).expect("generator");
    let names = generator.motor_names();
    let mut sinks: Vec<Vec<Step>> = vec![Vec::new(); names.len()];
    generator
        .run_moves(moves.iter().copied(), 4096, &mut sinks)
        .expect("steps generated");

    let mut problems = Vec::new();
    for (index, (name, ours)) in names.iter().zip(&sinks).enumerate() {
        let theirs =
            read_step_file(dir.join("steps").join(format!("{name}.txt.gz"))).expect("golden steps");
        let c = compare(ours, &theirs);
        let filtered = generator.motor(index).map_or(0, |m| m.filtered_pairs());
        // Steps more than a tick away must be within Klipper's own search tolerance (toolhead motors only:
        // the extruder and linear axes never need it).
        let unexplained: Vec<usize> = if c.beyond_one.is_empty() || index >= start_motors.len() {
            c.beyond_one.clone()
        } else {
            let ideal = IdealMotor {
                kin: reference.as_ref(),
                pieces: &toolhead_pieces,
                index,
                is_angle: matches!(reference.motor_map(index), MotorMap::Angle { .. }),
            };
            let step_dist = kin.motors()[index].step_distance;
            let mut net = 0i64;
            let mut bad = Vec::new();
            let mut next = c.beyond_one.iter().peekable();
            for (i, (step, mine)) in theirs.iter().zip(ours).enumerate() {
                if next.peek() == Some(&&i) {
                    next.next();
                    let half = if step.dir { 0.5 } else { -0.5 };
                    let level = start_motors[index] + (net as f64 + half) * step_dist;
                    let hz = config.clock_hz;
                    if !ideal.accepts(step.clock, hz, level)
                        || !ideal.exact_at(mine.clock, hz, level)
                    {
                        bad.push(i);
                    }
                }
                net += if step.dir { 1 } else { -1 };
            }
            bad
        };
        println!(
            "{case:27} {name:11} steps {:7}/{:7} max|Δclock| {:2} off by one {:6} beyond one {:4} \
             (unexplained {}) filtered pairs {}",
            c.ours,
            c.theirs,
            c.max_clock_diff,
            c.off_by_one,
            c.beyond_one.len(),
            unexplained.len(),
            filtered
        );
        let first_bad = unexplained.first().copied();
        if c.ours != c.theirs || c.first_dir_mismatch.is_some() || first_bad.is_some() {
            let at = first_bad
                .or(c.first_dir_mismatch)
                .unwrap_or(ours.len().min(theirs.len()));
            let lo = at.saturating_sub(3);
            problems.push(format!(
                "{case} {name}: ours {} golden {} first mismatch at step {at}: ours {:?} golden {:?}",
                c.ours,
                c.theirs,
                &ours[lo.min(ours.len())..(at + 3).min(ours.len())],
                &theirs[lo.min(theirs.len())..(at + 3).min(theirs.len())]
            ));
        }
    }
    problems
}

#[test]
fn every_golden_case_matches_klipper_steps() {
    let Some(root) = golden_dir() else { return };
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&root)
        .expect("golden dir readable")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("moves.csv.gz").is_file())
        .collect();
    cases.sort();
    assert!(
        !cases.is_empty(),
        "no golden cases found in {}",
        root.display()
    );
    let problems: Vec<String> = cases
        .iter()
        .flat_map(|c| run_case(c, Solver::ClosedForms))
        .collect();
    assert!(problems.is_empty(), "mismatches:\n{}", problems.join("\n"));
}

/// The general (bracketed) solver on polar and Cartesian machines, whose motors normally use closed forms:
/// it must reproduce Klipper's steps just as well, including the bed near the centre.
#[test]
fn general_solver_matches_klipper_on_closed_form_machines() {
    let Some(root) = golden_dir() else { return };
    let cases = [
        "polar-synthetic",
        "polar-cura-circle",
        "cartesian-bambu-square-ring",
    ];
    let problems: Vec<String> = cases
        .iter()
        .map(|c| root.join(c))
        .filter(|p| p.join("moves.csv.gz").is_file())
        .flat_map(|c| run_case(&c, Solver::General))
        .collect();
    assert!(problems.is_empty(), "mismatches:\n{}", problems.join("\n"));
}

/// SCARA joints through stepgen's one-motor SCARA solver (the arm without the fork's cos quirk, which
/// changes only points with |cos q2| < 1e-9): Kalico's steps are matched as well as by the general solver.
#[test]
fn scara_joint_solver_matches_kalico() {
    let Some(root) = golden_dir() else { return };
    let cases = ["scara-fekt-cura-hex", "scara-fekt-synthetic"];
    let problems: Vec<String> = cases
        .iter()
        .map(|c| root.join(c))
        .filter(|p| p.join("moves.csv.gz").is_file())
        .flat_map(|c| run_case(&c, Solver::ScaraJoint))
        .collect();
    assert!(problems.is_empty(), "mismatches:\n{}", problems.join("\n"));
}

#[derive(Debug, Clone, Copy)]
enum Solver {
    /// As the machine declares its motors (the FEKT SCARA with its quirk: general solver).
    ClosedForms,
    General,
    ScaraJoint,
}

/// A machine whose motors all claim to have no closed form, so stepgen uses its general solver.
#[derive(Debug)]
struct AsGeneral(Box<dyn Kinematics>);

impl Kinematics for AsGeneral {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn motors(&self) -> &[kinematics::Motor] {
        self.0.motors()
    }
    fn motor_map(&self, _motor: usize) -> MotorMap {
        MotorMap::General
    }
    fn inverse(&self, p: [f64; 3], motors: &mut [f64]) -> Result<(), kinematics::ReachError> {
        self.0.inverse(p, motors)
    }
    fn inverse_near(
        &self,
        p: [f64; 3],
        previous: &[f64],
        motors: &mut [f64],
    ) -> Result<(), kinematics::ReachError> {
        self.0.inverse_near(p, previous, motors)
    }
    fn forward(&self, motors: &[f64]) -> Result<[f64; 3], kinematics::ReachError> {
        self.0.forward(motors)
    }
    fn jacobian(&self, p: [f64; 3], rows: &mut [[f64; 3]]) -> Result<(), kinematics::ReachError> {
        self.0.jacobian(p, rows)
    }
    fn check_segment(&self, a: [f64; 3], b: [f64; 3]) -> Result<(), kinematics::SegmentError> {
        self.0.check_segment(a, b)
    }
}
