//! The SCARA arms users come from, expressed as jointspace configs (README, "Coming from other firmware"): each
//! firmware's inverse kinematics is written here again from its documented formulas, not from our code, and the
//! machine built from the config must command the same motor angles over the arm's whole printing area.
//!
//! - Marlin `MORGAN_SCARA` (Marlin's `scara.cpp`): with `C2 = (|p−o|² − L1² − L2²)/(2·L1·L2)`, `S2 = √(1 − C2²)`,
//!   `θ = atan2(L1 + L2·C2, L2·S2) − atan2(x − ox, y − oy)`, `ψ = atan2(S2, C2)`, motors `A = θ`, `B = ψ + θ`.
//! - Marlin `MP_SCARA`: no offset; with `c = |p|`, `θ1 = atan2(y, x) + acos((c² + L1² − L2²)/(2·c·L1))`,
//!   `θ2 = atan2(y, x) − acos((c² + L2² − L1²)/(2·c·L2))`, motors `A = θ1`, `B = θ2`.
//! - X-SCARA (a Marlin fork; the FEKT-SCARA thesis' frame): angles from +Y turning towards +X, the elbow belt
//!   through the shoulder (`ECR` = 3): `A = θ1`, `B = θ2 + θ1/ECR` with `θ2` the elbow's bend; written here as the
//!   intersection of the circle of radius L1 about the shoulder with the circle of radius L2 about the nozzle.
//! - The FEKT-SCARA Klipper module (standard frame): `q2 = acos(C2)`, `q1 = atan2(v, u) − atan2(L2·sin q2,
//!   L1 + L2·cos q2)`, motors `a = q1`, `b = q2 + q1/ECR`.

use machine::Machine;

const STEPPERS: &str = "
[stepper_a]
step_pin: PF0
dir_pin: PF1
microsteps: 16
gear_ratio: 60:20
[stepper_b]
step_pin: PF6
dir_pin: PF7
microsteps: 16
gear_ratio: 60:20
[stepper_z]
step_pin: PL3
dir_pin: PL1
microsteps: 16
rotation_distance: 8
endstop_pin: ^PD3
position_endstop: 0
position_max: 150
";

/// A SCARA machine with `keys` in its `[printer]` section (no base protection and no singular band, so every pose
/// the firmware formula gives can be compared).
fn arm(keys: &str) -> Machine {
    let text = format!(
        "[printer]\nkinematics: scara\nmax_velocity: 100\nmax_accel: 1000\nbase_protection_radius: 0\n\
         singularity_margin: 0\n{keys}\n{STEPPERS}"
    );
    Machine::from_text(&text, "printer.cfg").unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// Our motor angles (rad) for the nozzle at (x, y).
fn motors(machine: &Machine, x: f64, y: f64) -> [f64; 2] {
    let mut m = [0.0; 3];
    machine
        .setup
        .kinematics
        .inverse([x, y, 0.0], &mut m)
        .unwrap_or_else(|e| panic!("({x}, {y}): {e}"));
    [m[0], m[1]]
}

/// Points on a polar grid about `centre`, at distances strictly between the arm's folded and stretched reach and
/// at angles (degrees, from +X) within `angles`.
fn grid(centre: (f64, f64), reach: (f64, f64), angles: (f64, f64)) -> Vec<(f64, f64)> {
    let mut points = Vec::new();
    for i in 1..40 {
        let r = reach.0 + (reach.1 - reach.0) * f64::from(i) / 40.0;
        for j in 0..=60 {
            let a = (angles.0 + (angles.1 - angles.0) * f64::from(j) / 60.0).to_radians();
            points.push((centre.0 + r * a.cos(), centre.1 + r * a.sin()));
        }
    }
    points
}

/// Every grid point gives the firmware's motor angles (degrees, from `firmware`) to 1e-9 rad.
fn assert_same_motors(
    name: &str,
    machine: &Machine,
    points: &[(f64, f64)],
    firmware: impl Fn(f64, f64) -> [f64; 2],
) {
    let mut worst = 0.0_f64;
    for &(x, y) in points {
        let theirs = firmware(x, y).map(f64::to_radians);
        let ours = motors(machine, x, y);
        for (a, b) in ours.iter().zip(theirs) {
            let difference = (a - b).abs();
            assert!(
                difference < 1e-9,
                "{name} at ({x:.3}, {y:.3}): ours {ours:?}, the firmware's {theirs:?}"
            );
            worst = worst.max(difference);
        }
    }
    println!(
        "{name}: {} points, largest difference {worst:.1e} rad",
        points.len()
    );
}

#[test]
fn marlin_morgan_scara_is_elbow_coupling_one_on_the_left_branch() {
    let (l1, l2, ox, oy) = (150.0, 130.0, 20.0, -10.0);
    let machine = arm(&format!(
        "link1_length: {l1}\nlink2_length: {l2}\noffset_x: {ox}\noffset_y: {oy}\nelbow_coupling: 1\nelbow: left"
    ));
    let morgan = |x: f64, y: f64| {
        let (sx, sy) = (x - ox, y - oy);
        let c2 = ((sx * sx + sy * sy) - (l1 * l1 + l2 * l2)) / (2.0 * l1 * l2);
        let s2 = (1.0 - c2 * c2).sqrt();
        let theta = (l1 + l2 * c2).atan2(l2 * s2) - sx.atan2(sy);
        let psi = s2.atan2(c2);
        [theta.to_degrees(), (psi + theta).to_degrees()]
    };
    // In front of the shoulder (Marlin's θ, a difference of two atan2, stays in (−π, π] there as ours does).
    let points = grid((ox, oy), (l1 - l2, l1 + l2), (5.0, 175.0));
    assert_same_motors("MORGAN_SCARA", &machine, &points, morgan);
}

#[test]
fn marlin_mp_scara_is_elbow_coupling_one_on_the_right_branch_without_offsets() {
    let (l1, l2) = (120.0, 120.0);
    let machine = arm(&format!(
        "link1_length: {l1}\nlink2_length: {l2}\noffset_x: 0\noffset_y: 0\nelbow_coupling: 1\nelbow: right"
    ));
    let mp = |x: f64, y: f64| {
        let c = x.hypot(y);
        let theta3 = y.atan2(x);
        let theta1 = theta3 + ((c * c + l1 * l1 - l2 * l2) / (2.0 * c * l1)).acos();
        let theta2 = theta3 - ((c * c + l2 * l2 - l1 * l1) / (2.0 * c * l2)).acos();
        [theta1.to_degrees(), theta2.to_degrees()]
    };
    // Where θ1 = θ3 + α stays below π (the shoulder's reading in (−π, π]).
    let points = grid((0.0, 0.0), (10.0, l1 + l2), (-150.0, 60.0));
    assert_same_motors("MP_SCARA", &machine, &points, mp);
}

/// X-SCARA's arm from its geometry: the elbow is where the circle of radius L1 about the shoulder meets the
/// circle of radius L2 about the nozzle, on the side `side` of the shoulder-to-nozzle line (+1: to its left seen
/// from above, x right and y up; −1: to its right); angles are measured from +Y turning towards +X.
fn xscara_joints(
    p: (f64, f64),
    shoulder: (f64, f64),
    (l1, l2): (f64, f64),
    side: f64,
) -> (f64, f64) {
    let (dx, dy) = (p.0 - shoulder.0, p.1 - shoulder.1);
    let d = dx.hypot(dy);
    let along = (d * d + l1 * l1 - l2 * l2) / (2.0 * d);
    let across = (l1 * l1 - along * along).max(0.0).sqrt() * side;
    let elbow = (
        shoulder.0 + (along * dx - across * dy) / d,
        shoulder.1 + (along * dy + across * dx) / d,
    );
    let from_y = |vx: f64, vy: f64| vx.atan2(vy);
    let theta1 = from_y(elbow.0 - shoulder.0, elbow.1 - shoulder.1);
    let distal = from_y(p.0 - elbow.0, p.1 - elbow.1);
    let mut theta2 = distal - theta1;
    if theta2 > std::f64::consts::PI {
        theta2 -= std::f64::consts::TAU;
    } else if theta2 <= -std::f64::consts::PI {
        theta2 += std::f64::consts::TAU;
    }
    (theta1, theta2)
}

#[test]
fn x_scara_is_the_xscara_frame_with_its_ecr() {
    let (l1, l2, ox, oy, ecr) = (98.0, 98.0, 0.0, -40.0, 3.0);
    for (elbow, side) in [("left", 1.0), ("right", -1.0)] {
        let machine = arm(&format!(
            "link1_length: {l1}\nlink2_length: {l2}\noffset_x: {ox}\noffset_y: {oy}\necr: {ecr}\n\
             frame: xscara\nelbow: {elbow}"
        ));
        let xscara = |x: f64, y: f64| {
            let (theta1, theta2) = xscara_joints((x, y), (ox, oy), (l1, l2), side);
            [theta1.to_degrees(), (theta2 + theta1 / ecr).to_degrees()]
        };
        // In front of the shoulder, towards +Y (X-SCARA's printing area).
        let points = grid((ox, oy), (5.0, l1 + l2), (30.0, 150.0));
        assert_same_motors(
            &format!("X-SCARA, {elbow} elbow"),
            &machine,
            &points,
            xscara,
        );
    }
}

#[test]
fn the_fekt_klipper_module_is_the_standard_frame_with_its_ecr() {
    let (l1, l2, ox, oy, ecr) = (100.0, 100.0, 0.0, 0.0, 3.0);
    let machine = arm(&format!(
        "link1_length: {l1}\nlink2_length: {l2}\noffset_x: {ox}\noffset_y: {oy}\necr: {ecr}"
    ));
    let fekt = |x: f64, y: f64| {
        let (u, v) = (x - ox, y - oy);
        let q2 = ((u * u + v * v - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)).acos();
        let q1 = v.atan2(u) - (l2 * q2.sin()).atan2(l1 + l2 * q2.cos());
        [q1.to_degrees(), (q2 + q1 / ecr).to_degrees()]
    };
    let points = grid((ox, oy), (5.0, l1 + l2), (10.0, 170.0));
    assert_same_motors("FEKT-SCARA module", &machine, &points, fekt);
}
