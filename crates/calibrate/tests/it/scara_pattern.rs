//! The SCARA calibration loop as a user runs it, against geometry written here (not the tool's model): the
//! pattern's listed motor angles are the ones the configured machine commands at each cross centre (its inverse,
//! and a forward model of this file), and from the default pattern, arms built differently from their config
//! (FEKT-like and X-SCARA-like) are identified within 0.02 mm / 0.02° / 0.02 % with an honest σ; wrong inputs are
//! judged not trustworthy. The whole loop (pattern, arm as built, measured crosses, fit, corrected config) puts the
//! nozzle within 0.04 mm of where a part asks over the workspace (the crosses kept 10 mm apart, so each stands
//! alone for calipers and on a scan).

use std::f64::consts::PI;

use calibrate::scara::{self, Measurement, PatternOptions, ScaraGeometry};
use kinematics::scara::Scara;
use kinematics::{ElbowBranch, Kinematics, ScaraFrame, ScaraParams, StepperParams};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// An arm as built: link lengths, shoulder position in the printer's X/Y, motor readings at the joints' zeros, the
/// elbow motor's coupling to the shoulder, and the direction angles count from.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Arm {
    pub(crate) l1: f64,
    pub(crate) l2: f64,
    pub(crate) shoulder: [f64; 2],
    pub(crate) zero_a: f64,
    pub(crate) zero_b: f64,
    pub(crate) coupling: f64,
    /// Angles from +Y turning towards +X (X-SCARA), else from +X turning towards +Y.
    pub(crate) from_y: bool,
}

impl Arm {
    /// The unit vector at angle `t` in the arm's convention, in the printer's X/Y.
    fn direction(&self, t: f64) -> [f64; 2] {
        if self.from_y {
            [t.sin(), t.cos()]
        } else {
            [t.cos(), t.sin()]
        }
    }

    /// Where the nozzle is at motor readings `(a, b)`: the elbow at L1 along the shoulder joint's angle, the nozzle
    /// at L2 along the proximal link's angle plus the elbow joint's (the elbow motor also turns by `coupling` times
    /// the shoulder joint).
    pub(crate) fn nozzle(&self, a: f64, b: f64) -> [f64; 2] {
        let shoulder_joint = a - self.zero_a;
        let elbow_joint = b - self.zero_b - self.coupling * shoulder_joint;
        let d1 = self.direction(shoulder_joint);
        let d2 = self.direction(shoulder_joint + elbow_joint);
        [
            self.shoulder[0] + self.l1 * d1[0] + self.l2 * d2[0],
            self.shoulder[1] + self.l1 * d1[1] + self.l2 * d2[1],
        ]
    }

    fn values(&self) -> [f64; 7] {
        [
            self.l1,
            self.l2,
            self.shoulder[0],
            self.shoulder[1],
            self.zero_a,
            self.zero_b,
            self.coupling,
        ]
    }
}

/// The printer.cfg of an arm believed to be `arm`: FEKT-like (standard frame, left elbow, `ecr`, 60 mm-style base
/// radius, motor limits ±200°) or X-SCARA-like (its frame, right elbow, a coupling, a singular band).
pub(crate) fn config(arm: &Arm) -> ScaraParams {
    let deg = |v: f64| v.to_radians();
    let joint = |name: &str, fekt: bool| StepperParams {
        position_min: fekt.then_some(deg(-200.0)),
        position_max: fekt.then_some(deg(200.0)),
        ..StepperParams::new(name, std::f64::consts::TAU / 9600.0)
    };
    let fekt = !arm.from_y;
    ScaraParams {
        shoulder_stepper: joint("stepper_a", fekt),
        elbow_stepper: joint("stepper_b", fekt),
        z: StepperParams::new("stepper_z", 1.0 / 400.0),
        link1_length: arm.l1,
        link2_length: arm.l2,
        offset_x: arm.shoulder[0],
        offset_y: arm.shoulder[1],
        elbow_coupling: arm.coupling,
        ecr: fekt.then_some(1.0 / arm.coupling),
        elbow: if fekt {
            ElbowBranch::Left
        } else {
            ElbowBranch::Right
        },
        frame: if fekt {
            ScaraFrame::Standard
        } else {
            ScaraFrame::XScara
        },
        shoulder_zero: arm.zero_a,
        elbow_zero: arm.zero_b,
        shoulder_limits: None,
        elbow_limits: None,
        base_protection_radius: 0.3 * (arm.l1 + arm.l2),
        singularity_margin: if fekt { 0.0 } else { 0.05 },
    }
}

/// A random arm as built (lengths 90–150 mm, ECR 1–4, shoulder within ±5 mm, zeros within ±3°) and the config its
/// owner believes (within ±1 mm, ±0.5° and ±0.5 % of it).
fn random_arm(rng: &mut StdRng, x_scara: bool) -> (Arm, Arm) {
    random_arm_with_links(rng, x_scara, 90.0..150.0)
}

/// [`random_arm`] with both link lengths drawn from `links` (mm).
pub(crate) fn random_arm_with_links(
    rng: &mut StdRng,
    x_scara: bool,
    links: std::ops::Range<f64>,
) -> (Arm, Arm) {
    let truth = Arm {
        l1: rng.random_range(links.clone()),
        l2: rng.random_range(links),
        shoulder: [rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0)],
        zero_a: rng.random_range(-3.0f64..3.0).to_radians(),
        zero_b: rng.random_range(-3.0f64..3.0).to_radians(),
        coupling: 1.0 / rng.random_range(1.0..4.0),
        from_y: x_scara,
    };
    let mut mm = || rng.random_range(-1.0..1.0);
    let believed = Arm {
        l1: truth.l1 + mm(),
        l2: truth.l2 + mm(),
        shoulder: [truth.shoulder[0] + mm(), truth.shoulder[1] + mm()],
        zero_a: truth.zero_a + 0.5 * mm().to_radians(),
        zero_b: truth.zero_b + 0.5 * mm().to_radians(),
        coupling: truth.coupling * (1.0 + 0.005 * mm()),
        from_y: x_scara,
    };
    (truth, believed)
}

fn machine(arm: &Arm) -> Scara {
    Scara::new(config(arm)).expect("valid config")
}

/// The machine with its shoulder joint kept within `limits` (rad), when given: a bed that covers part of the reach.
pub(crate) fn limited_machine(arm: &Arm, limits: Option<(f64, f64)>) -> Scara {
    Scara::new(ScaraParams {
        shoulder_limits: limits,
        ..config(arm)
    })
    .expect("valid config")
}

/// The crosses' centres as the G-code writes them: X of each vertical stroke, Y of each horizontal one.
fn written_centres(gcode: &str) -> Vec<[f64; 2]> {
    let field = |line: &str, key: char| -> f64 {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(key))
            .and_then(|v| v.parse().ok())
            .expect("a coordinate")
    };
    let prints: Vec<&str> = gcode.lines().filter(|l| l.starts_with("G1 X")).collect();
    prints
        .chunks(2)
        .map(|pair| [field(pair[1], 'X'), field(pair[0], 'Y')])
        .collect()
}

/// Angle difference folded into (−π, π].
fn angle_apart(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * PI);
    if d > PI { 2.0 * PI - d } else { d }
}

#[test]
fn listed_angles_are_the_ones_the_machine_commands() {
    let mut rng = StdRng::seed_from_u64(27);
    for k in 0..12 {
        let (_, believed) = random_arm(&mut rng, k % 2 == 1);
        let kin = machine(&believed);
        let pattern =
            scara::machine_pattern(&kin, 20, &PatternOptions::default()).expect("a pattern");
        assert_eq!(pattern.poses.len(), 20);
        let centres = written_centres(&pattern.gcode);
        assert_eq!(centres, pattern.centres);
        // The measurements file lists the same angles (to its 1e-10°) and the machine's frame.
        let file = scara::parse_measurement_file(&pattern.template.replace(",,", ",0,0"), "t")
            .expect("the template reads");
        assert_eq!(file.frame.map(|f| f.0), Some(kin.params().frame));
        for ((&(a, b), c), row) in pattern.poses.iter().zip(&centres).zip(&file.rows) {
            let mut motors = [0.0; 3];
            kin.inverse([c[0], c[1], 0.3], &mut motors)
                .expect("reachable");
            assert!(angle_apart(motors[0], a) < 1e-9 && (motors[1] - b).abs() < 1e-9);
            assert!((row.motor_a - a).abs() < 1e-9 && (row.motor_b - b).abs() < 1e-9);
            // This file's forward model puts the believed arm's nozzle at the cross centre.
            let p = believed.nozzle(a, b);
            assert!(
                (p[0] - c[0]).abs() < 1e-9 && (p[1] - c[1]).abs() < 1e-9,
                "arm {k}: {p:?} vs {c:?}"
            );
            // On the configured branch: the elbow joint's sign.
            let q2 = b - believed.zero_b - believed.coupling * (a - believed.zero_a);
            assert!(if believed.from_y { q2 < 0.0 } else { q2 > 0.0 }, "q2 {q2}");
        }
    }
}

/// What the person measuring records: where the arm as built puts each cross centre, with their noise.
fn measure(truth: &Arm, poses: &[(f64, f64)], sigma: f64, rng: &mut StdRng) -> Vec<Measurement> {
    let noise = Normal::new(0.0, sigma).expect("sigma");
    poses
        .iter()
        .enumerate()
        .map(|(i, &(a, b))| {
            let p = truth.nozzle(a, b);
            Measurement {
                motor_a: a,
                motor_b: b,
                x: p[0] + noise.sample(rng),
                y: p[1] + noise.sample(rng),
                line: i + 3,
            }
        })
        .collect()
}

fn geometry(arm: &Arm) -> ScaraGeometry {
    ScaraGeometry::from_array(arm.values())
}

/// The largest distance (mm) between where a part asks for the nozzle and where the arm as built puts it when the
/// machine is configured with `fitted`, over the workspace that configuration accepts (rings and directions about
/// the shoulder).
fn nozzle_error(truth: &Arm, fitted: &Arm, limits: Option<(f64, f64)>) -> f64 {
    let kin = limited_machine(fitted, limits);
    let (lo, hi) = ((fitted.l1 - fitted.l2).abs(), fitted.l1 + fitted.l2);
    let mut worst = 0.0f64;
    for ring in 1..12 {
        let rho = lo + (hi - lo) * ring as f64 / 12.0;
        for k in 0..36 {
            let d = fitted.direction(-PI + PI * k as f64 / 18.0);
            let p = [
                fitted.shoulder[0] + rho * d[0],
                fitted.shoulder[1] + rho * d[1],
                0.0,
            ];
            let mut motors = [0.0; 3];
            if kin.check_point(p).is_err() || kin.inverse(p, &mut motors).is_err() {
                continue;
            }
            let q = truth.nozzle(motors[0], motors[1]);
            worst = worst.max((q[0] - p[0]).hypot(q[1] - p[1]));
        }
    }
    worst
}

#[test]
fn fifty_random_arms_are_identified_from_the_default_pattern() {
    fifty_random_arms(None);
}

/// The same with the shoulder joint limited to 0…180° (a bed on one side of the shoulder): fewer poses to choose from.
#[test]
fn fifty_random_arms_on_half_a_turn_of_the_shoulder() {
    fifty_random_arms(Some((0.0, PI)));
}

/// 50 random arms (every other one X-SCARA-like) calibrated from the default pattern of their believed config (its
/// shoulder within `limits`): at least 48 within 0.02 mm / 0.02° / 0.02 % on every parameter, 90 % of the errors
/// within 2σ, the fits judged trustworthy, the corrected nozzle within 0.04 mm over the workspace.
fn fifty_random_arms(limits: Option<(f64, f64)>) {
    let mut rng = StdRng::seed_from_u64(2027);
    let (arms, mut within, mut covered, mut judged_ok) = (50, 0, 0, 0);
    let (mut worst, mut nozzle_worst) = ([0.0f64; 3], 0.0f64);
    for k in 0..arms {
        let (truth, believed) = random_arm(&mut rng, k % 2 == 1);
        let kin = limited_machine(&believed, limits);
        let pattern =
            scara::machine_pattern(&kin, scara::DEFAULT_POSES, &PatternOptions::default())
                .expect("a pattern");
        let data = measure(&truth, &pattern.poses, 0.02, &mut rng);
        let start = geometry(&believed);
        let frame = kin.params().frame;
        let fit = scara::identify_in_frame(&data, &start, frame).expect("a fit");
        let verdict = scara::judge(&data, &fit, &start, frame, 0.02);
        judged_ok += usize::from(verdict.trustworthy);
        let (got, want) = (fit.geometry.to_array(), truth.values());
        // The whole loop: the fitted values in the config, the nozzle where a part asks for it.
        let fitted = Arm {
            l1: got[0],
            l2: got[1],
            shoulder: [got[2], got[3]],
            zero_a: got[4],
            zero_b: got[5],
            coupling: got[6],
            from_y: truth.from_y,
        };
        nozzle_worst = nozzle_worst.max(nozzle_error(&truth, &fitted, limits));
        let error: Vec<f64> = (0..7).map(|i| got[i] - want[i]).collect();
        let scaled = [
            error[..4].iter().fold(0.0f64, |m, e| m.max(e.abs())) / 0.02,
            error[4..6]
                .iter()
                .fold(0.0f64, |m, e| m.max(e.abs().to_degrees()))
                / 0.02,
            (error[6] / want[6]).abs() / 2e-4,
        ];
        for (w, s) in worst.iter_mut().zip(scaled) {
            *w = w.max(s);
        }
        within += usize::from(scaled.iter().all(|s| *s <= 1.0));
        covered += (0..7)
            .filter(|&i| error[i].abs() <= 2.0 * fit.sigma[i])
            .count();
    }
    let coverage = covered as f64 / (7 * arms) as f64;
    println!(
        "SCARA default pattern ({} poses, shoulder limits {limits:?}), {arms} random arms (FEKT- and X-SCARA-like), 0.02 mm noise: {within} \
         within 0.02 mm / 0.02° / 0.02 %; worst error over bound: lengths/offsets {:.2}, zeros {:.2}, coupling \
         {:.2}; {:.1} % of errors within 2σ; {judged_ok} judged trustworthy; corrected, the nozzle within {nozzle_worst:.4} mm \
         over the workspace",
        scara::DEFAULT_POSES,
        worst[0],
        worst[1],
        worst[2],
        100.0 * coverage
    );
    assert!(within >= 48, "{within} of {arms} within bounds");
    assert!(coverage >= 0.9, "{coverage}");
    assert!(judged_ok >= 49, "{judged_ok} of {arms} judged trustworthy");
    assert!(nozzle_worst <= 0.04, "{nozzle_worst} mm");
}

/// Inputs that cannot be right are judged so: the angles of the other elbow branch (what the old pattern listed),
/// X-SCARA data read in the standard frame, one cross read 0.3 mm off, and four poses.
#[test]
fn fits_that_cannot_be_right_are_not_trustworthy() {
    let mut rng = StdRng::seed_from_u64(99);
    let (truth, believed) = random_arm(&mut rng, true);
    let kin = machine(&believed);
    let pattern = scara::machine_pattern(&kin, 20, &PatternOptions::default()).expect("a pattern");
    let start = geometry(&believed);
    let judge = |data: &[Measurement], frame: ScaraFrame| {
        let fit = scara::identify_in_frame(data, &start, frame).expect("a fit");
        scara::judge(data, &fit, &start, frame, 0.02)
    };
    let good = measure(&truth, &pattern.poses, 0.02, &mut rng);
    assert!(judge(&good, ScaraFrame::XScara).trustworthy);
    // The frame forgotten: refused, and the swap is the first cause named.
    let verdict = judge(&good, ScaraFrame::Standard);
    assert!(
        !verdict.trustworthy && verdict.causes[0].contains("swapped"),
        "{verdict:?}"
    );
    // One cross read 0.3 mm off: refused, that cross named first.
    let mut off = good.clone();
    off[6].x += 0.3;
    let verdict = judge(&off, ScaraFrame::XScara);
    assert!(!verdict.trustworthy, "{verdict:?}");
    assert_eq!(verdict.worst[0].line, off[6].line);
    assert!(
        verdict.causes[0].contains(&format!("line {}", off[6].line)),
        "{verdict:?}"
    );
    // The other branch's angles for the same cross centres (the elbow joint mirrored: q2 → −q2, q1 → q1 + 2β).
    let mirrored: Vec<(f64, f64)> = pattern
        .poses
        .iter()
        .map(|&(a, b)| {
            let q1 = a - believed.zero_a;
            let q2 = b - believed.zero_b - believed.coupling * q1;
            let beta = (believed.l2 * q2.sin()).atan2(believed.l1 + believed.l2 * q2.cos());
            let q1 = q1 + 2.0 * beta;
            (
                q1 + believed.zero_a,
                -q2 + believed.coupling * q1 + believed.zero_b,
            )
        })
        .collect();
    let wrong: Vec<Measurement> = good
        .iter()
        .zip(&mirrored)
        .map(|(m, &(a, b))| Measurement {
            motor_a: a,
            motor_b: b,
            ..*m
        })
        .collect();
    assert!(!judge(&wrong, ScaraFrame::XScara).trustworthy);
    // Four poses fit exactly enough, but leave one residual degree of freedom.
    let verdict = judge(&good[..4], ScaraFrame::XScara);
    assert!(!verdict.trustworthy && verdict.dof == 1, "{verdict:?}");
    assert!(verdict.problems[0].contains("residual degrees of freedom"));
}
