//! The five-bar (parallel) SCARA against geometry written here again: the elbows as circle–circle intersections
//! (not our code), FK∘IK and IK∘FK round trips in every working mode, the Jacobian against finite differences of the
//! independent inverse, the singular curves against the Jacobian's determinant, and whole-segment checks against
//! dense sampling.

use std::f64::consts::{PI, TAU};

use kinematics::fivebar::{Fivebar, LEFT, RIGHT};
use kinematics::workspace::area_for;
use kinematics::{FivebarArm, FivebarParams, Kinematics, MachineParams, ReachError, Turn, Vec3};
use proptest::prelude::*;

pub(crate) const MODES: [(Turn, Turn); 4] = [
    (Turn::Ccw, Turn::Ccw),
    (Turn::Cw, Turn::Ccw),
    (Turn::Ccw, Turn::Cw),
    (Turn::Cw, Turn::Cw),
];

pub(crate) fn machine(left: Turn, right: Turn, distal: Turn, margin: f64) -> Fivebar {
    let mut p = FivebarParams::example();
    (p.left.turn, p.right.turn, p.distal_turn) = (left, right, distal);
    p.singularity_margin = margin;
    Fivebar::new(p).expect("valid")
}

/// The two intersections of the circles about `c0` (radius `r0`) and `c1` (radius `r1`), if they meet.
fn circles(c0: [f64; 2], r0: f64, c1: [f64; 2], r1: f64) -> Option<[[f64; 2]; 2]> {
    let (dx, dy) = (c1[0] - c0[0], c1[1] - c0[1]);
    let d = (dx * dx + dy * dy).sqrt();
    if d == 0.0 || d > r0 + r1 || d < (r0 - r1).abs() {
        return None;
    }
    let a = (r0 * r0 - r1 * r1 + d * d) / (2.0 * d);
    let h = (r0 * r0 - a * a).max(0.0).sqrt();
    let (mx, my) = (c0[0] + a * dx / d, c0[1] + a * dy / d);
    Some([
        [mx + h * dy / d, my - h * dx / d],
        [mx - h * dy / d, my + h * dx / d],
    ])
}

/// Sign of the turn `a → b → c` (counter-clockwise positive).
pub(crate) fn turn(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
}

pub(crate) fn sign(t: Turn) -> f64 {
    if t == Turn::Ccw { 1.0 } else { -1.0 }
}

/// The independent inverse: each elbow the intersection of its proximal and distal circles turning the configured
/// way; `None` where a side cannot reach or the distal links turn the other way.
fn independent(p: &FivebarParams, n: [f64; 2]) -> Option<([f64; 2], [[f64; 2]; 2])> {
    let (angles, [el, er]) = either_distal_turn(p, n)?;
    (turn(el, n, er) * sign(p.distal_turn) > 0.0).then_some((angles, [el, er]))
}

/// The elbows alone, whichever way the distal links turn.
pub(crate) fn either_distal_turn(
    p: &FivebarParams,
    n: [f64; 2],
) -> Option<([f64; 2], [[f64; 2]; 2])> {
    let elbow = |arm: &FivebarArm| {
        let both = circles(arm.base, arm.proximal, n, arm.distal)?;
        both.into_iter()
            .find(|e| turn(arm.base, *e, n) * sign(arm.turn) > 0.0)
    };
    let (el, er) = (elbow(&p.left)?, elbow(&p.right)?);
    let angle = |arm: &FivebarArm, e: [f64; 2]| (e[1] - arm.base[1]).atan2(e[0] - arm.base[0]);
    Some(([angle(&p.left, el), angle(&p.right, er)], [el, er]))
}

fn angle_apart(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(TAU);
    d.min(TAU - d)
}

/// Every 2 mm over the box of both arms' reach, in all eight working modes: our inverse agrees with the independent
/// one (same points reachable, same angles) and the forward kinematics return the point.
#[test]
fn every_working_mode_round_trips_over_the_whole_workspace() {
    let (mut points, mut worst_fk, mut worst_ik, mut worst_near) = (0usize, 0.0f64, 0.0f64, 0.0f64);
    for (left, right) in MODES {
        for distal in [Turn::Cw, Turn::Ccw] {
            let kin = machine(left, right, distal, 0.0);
            let (b, _) = area_for(&MachineParams::Fivebar(kin.params().clone())).expect("area");
            let (nx, ny) = (
                ((b.x_max - b.x_min) / 2.0) as usize,
                ((b.y_max - b.y_min) / 2.0) as usize,
            );
            let mut in_mode = 0;
            for ix in 0..nx {
                for iy in 0..ny {
                    let p = [
                        b.x_min + 1.0 + 2.0 * ix as f64,
                        b.y_min + 1.0 + 2.0 * iy as f64,
                        3.0,
                    ];
                    let mut m = [0.0; 3];
                    let ours = kin.inverse(p, &mut m);
                    let theirs = independent(kin.params(), [p[0], p[1]]);
                    let Some((angles, _)) = theirs else {
                        assert!(ours.is_err(), "{left:?} {right:?} {distal:?} {p:?}: {m:?}");
                        continue;
                    };
                    ours.unwrap_or_else(|e| {
                        panic!("{p:?} reachable in the independent inverse: {e}")
                    });
                    for side in [LEFT, RIGHT] {
                        worst_ik = worst_ik.max(angle_apart(m[side], angles[side]));
                    }
                    let q = kin.forward(&m).expect("forward");
                    let error = (q[0] - p[0]).hypot(q[1] - p[1]).max((q[2] - p[2]).abs());
                    // Beside the parallel singularity the nozzle moves as the square root of the joints' rounding.
                    let pose = kin.pose(p[0], p[1]).expect("pose");
                    if pose.parallel_sin > 1e-3 {
                        worst_fk = worst_fk.max(error);
                    } else {
                        worst_near = worst_near.max(error);
                    }
                    in_mode += 1;
                }
            }
            eprintln!("five-bar {left:?} {right:?} distal {distal:?}: {in_mode} points");
            assert!(
                in_mode > 400,
                "{left:?} {right:?} {distal:?}: {in_mode} points"
            );
            points += in_mode;
        }
    }
    eprintln!(
        "five-bar grid: {points} points, FK∘IK error {worst_fk:e} mm ({worst_near:e} mm within |sin| 1e-3 of the \
         parallel singularity), IK vs independent {worst_ik:e} rad"
    );
    assert!(
        worst_fk < 1e-9 && worst_near < 1e-7 && worst_ik < 1e-12,
        "{worst_fk} {worst_near} {worst_ik}"
    );
}

fn random_fivebar() -> impl Strategy<Value = FivebarParams> {
    let arm = |x: std::ops::Range<f64>| {
        (
            x,
            -20.0..20.0f64,
            60.0..200.0f64,
            80.0..250.0f64,
            any::<bool>(),
            -1.0..1.0f64,
        )
    };
    (arm(-80.0..-10.0), arm(10.0..80.0), any::<bool>()).prop_map(|(l, r, distal)| {
        let make = |(x, y, p, d, ccw, zero): (f64, f64, f64, f64, bool, f64), old: FivebarArm| {
            FivebarArm {
                base: [x, y],
                proximal: p,
                distal: d,
                turn: if ccw { Turn::Ccw } else { Turn::Cw },
                zero,
                ..old
            }
        };
        let example = FivebarParams::example();
        FivebarParams {
            left: make(l, example.left.clone()),
            right: make(r, example.right.clone()),
            distal_turn: if distal { Turn::Cw } else { Turn::Ccw },
            singularity_margin: 0.0,
            ..example
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Random machines in random modes: wherever the independent inverse finds the pose, ours finds the same one and
    /// the forward kinematics return the point; wherever it finds none, ours refuses (never NaN).
    #[test]
    fn random_machines_round_trip(params in random_fivebar(), x in -400.0..400.0f64, y in -400.0..400.0f64) {
        let kin = Fivebar::new(params.clone()).expect("valid");
        let mut m = [0.0; 3];
        let ours = kin.inverse([x, y, 1.0], &mut m);
        match independent(&params, [x, y]) {
            Some((angles, _)) => {
                prop_assert!(ours.is_ok(), "{:?}", ours);
                for side in [LEFT, RIGHT] {
                    let zero = [params.left.zero, params.right.zero][side];
                    prop_assert!(angle_apart(m[side] - zero, angles[side]) < 1e-11);
                }
                let q = kin.forward(&m).expect("forward");
                prop_assert!((q[0] - x).hypot(q[1] - y) < 1e-8, "{:?} vs {:?}", q, (x, y));
            }
            None => {
                prop_assert!(ours.is_err() || near_singular(&kin, [x, y]), "{:?}", m);
            }
        }
        prop_assert!(m.iter().all(|v| v.is_finite()));
    }

    /// IK∘FK: random joint angles give a nozzle (or a refusal), and the inverse of that nozzle gives the angles back.
    #[test]
    fn joint_angles_round_trip(params in random_fivebar(), a in -PI..PI, b in -PI..PI) {
        let kin = Fivebar::new(params.clone()).expect("valid");
        let motors = [a + params.left.zero, b + params.right.zero, 0.0];
        let Ok(p) = kin.forward(&motors) else { return Ok(()); };
        let mut m = [0.0; 3];
        // The pose the angles make must be in the working mode: each arm turning the configured way.
        let in_mode = [(&params.left, a), (&params.right, b)].iter().all(|(arm, t)| {
            let e = [arm.base[0] + arm.proximal * t.cos(), arm.base[1] + arm.proximal * t.sin()];
            turn(arm.base, e, [p[0], p[1]]) * sign(arm.turn) > 0.0
        });
        if !in_mode {
            return Ok(());
        }
        if let Ok(pose) = kin.pose(p[0], p[1]) {
            // Away from the special poses, where the angles are well conditioned.
            if pose.arm_sin[0] > 1e-3 && pose.arm_sin[1] > 1e-3 && pose.parallel_sin > 1e-3 {
                kin.inverse(p, &mut m).expect("inverse");
                prop_assert!(angle_apart(m[0], motors[0]) < 1e-8 && angle_apart(m[1], motors[1]) < 1e-8);
            }
        }
    }
}

/// Within rounding of a special pose, where the two inverses may decide differently.
fn near_singular(kin: &Fivebar, n: [f64; 2]) -> bool {
    kin.pose(n[0], n[1])
        .is_ok_and(|p| p.parallel_sin < 1e-9 || p.arm_sin.iter().any(|s| *s < 1e-6))
}

/// The joint Jacobian from central differences of the independent inverse (the distal links turning either way).
fn numeric_jacobian(p: &FivebarParams, n: [f64; 2]) -> Option<[[f64; 2]; 2]> {
    let h = 1e-6;
    let at = |dx: f64, dy: f64| either_distal_turn(p, [n[0] + dx, n[1] + dy]).map(|(a, _)| a);
    let (xp, xm, yp, ym) = (at(h, 0.0)?, at(-h, 0.0)?, at(0.0, h)?, at(0.0, -h)?);
    let d = |a: f64, b: f64| {
        let diff = (a - b + PI).rem_euclid(TAU) - PI;
        diff / (2.0 * h)
    };
    Some([
        [d(xp[0], xm[0]), d(yp[0], ym[0])],
        [d(xp[1], xm[1]), d(yp[1], ym[1])],
    ])
}

/// The Jacobian matches finite differences, and its determinant is where the special poses are:
/// `|det J|·P_L·P_R·sin_L·sin_R = |sin parallel|` — zero on the parallel singularity, unbounded on a serial one.
#[test]
fn jacobian_and_its_determinant_mark_the_singular_curves() {
    let kin = machine(Turn::Cw, Turn::Ccw, Turn::Cw, 0.0);
    let (mut checked, mut worst) = (0, 0.0f64);
    let mut rows = [[0.0; 3]; 3];
    for ix in 0..60 {
        for iy in 0..60 {
            let n = [-290.0 + 10.0 * ix as f64, 5.0 + 6.0 * iy as f64];
            let Some(numeric) = numeric_jacobian(kin.params(), n) else {
                continue;
            };
            let Ok(pose) = kin.pose(n[0], n[1]) else {
                continue;
            };
            if pose.arm_sin.iter().any(|s| *s < 0.05) || pose.parallel_sin < 1e-3 {
                continue;
            }
            kin.jacobian([n[0], n[1], 0.0], &mut rows).expect("regular");
            for k in 0..2 {
                for j in 0..2 {
                    let scale = rows[k][j].abs().max(1e-3);
                    worst = worst.max((rows[k][j] - numeric[k][j]).abs() / scale);
                }
            }
            let det = rows[0][0] * rows[1][1] - rows[0][1] * rows[1][0];
            let identity = det.abs() * 150.0 * 150.0 * pose.arm_sin[0] * pose.arm_sin[1];
            assert!(
                (identity - pose.parallel_sin).abs() < 1e-9,
                "{n:?}: {identity} vs {}",
                pose.parallel_sin
            );
            checked += 1;
        }
    }
    eprintln!("five-bar Jacobian: {checked} points, largest relative difference {worst:e}");
    assert!(checked > 1000 && worst < 1e-5, "{checked} {worst}");
}

/// A straight line across the parallel singularity: the independent Jacobian's determinant changes sign where our
/// segment check (margin 0) refuses it, and with a margin it is refused where `|sin|` falls to the margin.
#[test]
fn the_parallel_singularity_is_refused_where_the_determinant_vanishes() {
    let kin = machine(Turn::Cw, Turn::Ccw, Turn::Cw, 0.0);
    // Beyond the curve the distal links turn the other way: the same elbows, the other assembly.
    let det = |n: [f64; 2]| {
        let j = numeric_jacobian(kin.params(), n)?;
        Some(j[0][0] * j[1][1] - j[0][1] * j[1][0])
    };
    // Upwards along x = 0 below the bases: the elbows spread until the distal links are in line (at y ≈ −58).
    let (a, b): (Vec3, Vec3) = ([0.0, -150.0, 0.0], [0.0, -10.0, 0.0]);
    let err = kin
        .check_segment(a, b)
        .expect_err("crosses the parallel singularity");
    assert!(
        matches!(
            err.reason,
            ReachError::ParallelSingular { .. } | ReachError::BranchImpossible { .. }
        ),
        "{err}"
    );
    let y_err = a[1] + (b[1] - a[1]) * err.t;
    let (mut lo, mut hi) = (a[1], y_err + 1.0);
    let d_lo = det([0.0, lo]).expect("det");
    assert!(d_lo.abs() > 1e-6 && det([0.0, hi]).expect("det").signum() != d_lo.signum());
    while hi - lo > 1e-9 {
        let mid = 0.5 * (lo + hi);
        if det([0.0, mid]).expect("det").signum() == d_lo.signum() {
            lo = mid
        } else {
            hi = mid
        }
    }
    assert!(
        (lo - y_err).abs() < 1e-5,
        "determinant vanishes at y = {lo}, refused at {y_err}"
    );
    // With a margin: refused where |sin| between the distal links reaches it.
    let kin = machine(Turn::Cw, Turn::Ccw, Turn::Cw, 0.1);
    let err = kin.check_segment(a, b).expect_err("enters the band");
    assert!(
        matches!(err.reason, ReachError::ParallelSingular { .. }),
        "{err}"
    );
    let at = kin.pose(0.0, a[1] + (b[1] - a[1]) * err.t).expect("pose");
    assert!((at.parallel_sin - 0.1).abs() < 1e-6, "{}", at.parallel_sin);
}

/// Where the dense check of points says a segment fails (a point refused, or resting in a serial band between
/// ends that do not), the segment check refuses it at the same place, and it refuses nothing dense sampling
/// accepts unless the refused point is truly refused.
#[test]
fn segment_checks_agree_with_dense_sampling() {
    let mut p = FivebarParams::example();
    p.singularity_margin = 0.1;
    p.left.stepper.position_min = Some(60f64.to_radians());
    p.left.stepper.position_max = Some(200f64.to_radians());
    p.right.stepper.position_min = Some(-20f64.to_radians());
    p.right.stepper.position_max = Some(120f64.to_radians());
    let kin = Fivebar::new(p).expect("valid");
    let fails = |q: Vec3| kin.check_point(q).is_err() || kin.rests_at(q);
    let mut seed = 7u64;
    let mut next = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut checked, mut refused) = (0, 0);
    while checked < 600 {
        // Every other segment about the bases, where the holes, the folded bands and the parallel band are.
        let near = checked % 2 == 0;
        let (w, h) = if near { (150.0, 120.0) } else { (300.0, 275.0) };
        let y0 = if near { 0.0 } else { 75.0 };
        let a = [w * (2.0 * next() - 1.0), y0 + h * (2.0 * next() - 1.0), 0.0];
        let b = [w * (2.0 * next() - 1.0), y0 + h * (2.0 * next() - 1.0), 0.0];
        if fails(a) || fails(b) {
            continue;
        }
        checked += 1;
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        let n = (length / 0.01).ceil() as usize;
        let dense = (1..n)
            .map(|i| i as f64 / n as f64)
            .find(|&t| fails(lerp(a, b, t)));
        match (dense, kin.check_segment(a, b)) {
            (None, Ok(())) => {}
            (Some(t), Err(e)) => {
                refused += 1;
                assert!(
                    e.t <= t + 1e-9 && e.t >= t - 1.0 / n as f64 - 1e-9,
                    "{a:?} {b:?}: {} vs {t}",
                    e.t
                );
            }
            (None, Err(e)) => {
                // A graze between dense samples: the refused point is refused.
                assert!(
                    fails(lerp(a, b, e.t)),
                    "{a:?} {b:?}: refused at {} ({})",
                    e.t,
                    e.reason
                );
                refused += 1;
            }
            (Some(t), Ok(())) => panic!("{a:?} → {b:?} fails at {t} but was accepted"),
        }
    }
    eprintln!("five-bar segments: {checked} checked against 0.01 mm sampling, {refused} refused");
    assert!((20..580).contains(&refused), "{refused}");
}

fn lerp(a: Vec3, b: Vec3, t: f64) -> Vec3 {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * t)
}

/// A serial band behaves as the SCARA's: a path may end in it (the planner brings the arm to rest there) and start
/// from it, not cross it between its ends; a point beyond reach is an arm-reach error, never NaN.
#[test]
fn serial_bands_rest_and_reach_errors() {
    let kin = machine(Turn::Cw, Turn::Ccw, Turn::Cw, 0.1);
    let (inner, outer) = kin.band(LEFT);
    // Radially out from the left base towards its full stretch, staying in the right arm's comfortable range.
    let dir = [0.4f64, 0.84f64.sqrt()];
    let at = |r: f64| [-50.0 + r * dir[0], r * dir[1], 0.0];
    let (a, b) = (at(250.0), at(outer + 0.3));
    assert!(kin.rests_at(b) && !kin.rests_at(a));
    assert_eq!(kin.check_segment(a, b), Ok(()));
    assert_eq!(kin.check_segment(b, a), Ok(()));
    assert!(inner < outer);
    // Straight at the base joint into the folded band (the closest approach is the end itself): resting there is
    // allowed both ways; going on through the band and out of it is not.
    let (c, d) = (at(120.0), at(0.5 * (50.0 + inner)));
    assert!(kin.rests_at(d) && !kin.rests_at(c));
    assert_eq!(kin.check_segment(c, d), Ok(()));
    assert_eq!(kin.check_segment(d, c), Ok(()));
    let through = [-50.0 - 60.0 * dir[0], -60.0 * dir[1], 0.0];
    assert!(kin.check_segment(c, through).is_err());
    let mut m = [0.0; 3];
    assert!(matches!(
        kin.inverse([0.0, 600.0, 0.0], &mut m),
        Err(ReachError::ArmReach { arm: "left", .. })
    ));
    assert!(matches!(
        kin.inverse([f64::NAN, 0.0, 0.0], &mut m),
        Err(ReachError::NotFinite)
    ));
    // Motor angles that leave the elbows too far apart for shorter distal links.
    let mut short = kin.params().clone();
    (short.left.distal, short.right.distal) = (100.0, 100.0);
    let short = Fivebar::new(short).expect("valid");
    assert!(matches!(
        short.forward(&[PI, 0.0, 0.0]),
        Err(ReachError::ElbowsApart { .. })
    ));
}
