//! Whole-segment checks: problems between reachable end points are found, at the right place.

use kinematics::polar::Polar;
use kinematics::scara::Scara;
use kinematics::{Kinematics, ReachError, ScaraParams};

use crate::machines::{fekt_params, polar_params};

#[test]
fn scara_move_through_the_base_radius() {
    let scara = Scara::new(fekt_params()).expect("valid");
    let (a, b) = ([-100.0, 40.0, 1.0], [100.0, 40.0, 1.0]);
    assert!(
        scara.check_point(a).is_ok() && scara.check_point(b).is_ok(),
        "end points are reachable"
    );
    let err = scara
        .check_segment(a, b)
        .expect_err("middle is 40 mm from the shoulder");
    // Reported where the segment enters the 60 mm circle: x = −√(60² − 40²).
    let entry = (100.0 - (60.0f64 * 60.0 - 40.0 * 40.0).sqrt()) / 200.0;
    assert!((err.t - entry).abs() < 1e-8, "t = {}", err.t);
    assert!(matches!(err.reason, ReachError::InsideMinimumRadius { min, .. } if min == 60.0));
    assert!(
        scara
            .check_segment([-100.0, 80.0, 1.0], [100.0, 80.0, 1.0])
            .is_ok()
    );
}

#[test]
fn scara_segment_into_the_singular_band_ends_at_rest() {
    let params = ScaraParams {
        singularity_margin: 0.1,
        ..fekt_params()
    };
    let scara = Scara::new(params).expect("valid");
    // Radial move outwards: ends at ρ = 199.9 where cos q2 = 0.998, |sin q2| = 0.063 < 0.1. From rest the joints
    // move at finite speed however close to straight the arm is, so the move is allowed and the arm rests there
    // (the planner stops it: `rests_at`); the band begins at `max_radius`.
    let (a, b) = ([0.0, 120.0, 0.0], [0.0, 199.9, 0.0]);
    assert_eq!(scara.check_segment(a, b), Ok(()));
    assert_eq!(scara.check_segment(b, a), Ok(()));
    assert!(scara.rests_at(b) && !scara.rests_at(a));
    let edge = scara.max_radius();
    assert!(scara.rests_at([0.0, edge + 1e-6, 0.0]) && !scara.rests_at([0.0, edge - 1e-6, 0.0]));
}

#[test]
fn scara_shoulder_limit_crossed_mid_segment() {
    // q1 ≤ 10°: q1 grows from 1.2° at (120, 100) to 19.3° at (20, 100); the first crossing is reported.
    let limit = 10f64.to_radians();
    let params = ScaraParams {
        shoulder_limits: Some((-1.0, limit)),
        ..fekt_params()
    };
    let scara = Scara::new(params).expect("valid");
    let (a, b) = ([120.0, 100.0, 0.0], [20.0, 100.0, 0.0]);
    let q1_a = scara.joints(a[0], a[1]).expect("ok").q1;
    assert!(q1_a < limit);
    let err = scara.check_segment(a, b).expect_err("limit crossed");
    assert!(matches!(err.reason, ReachError::JointLimit { .. }), "{err}");
    // At the reported t the shoulder angle is at the limit (bisection to 1e-9 of the segment).
    let x = a[0] + (b[0] - a[0]) * err.t;
    let q1 = scara.joints(x, 100.0).expect("ok").q1;
    assert!(err.t > 0.0 && err.t < 1.0);
    assert!((q1 - limit).abs() < 1e-6, "q1 = {q1}");
}

#[test]
fn polar_move_through_the_centre() {
    let polar = Polar::new(polar_params(0.0, 0.0)).expect("valid");
    let err = polar
        .check_segment([-20.0, -10.0, 1.0], [40.0, 20.0, 1.0])
        .expect_err("through (0,0)");
    assert!((err.t - 1.0 / 3.0).abs() < 1e-12);
    assert!(matches!(err.reason, ReachError::AtCentre { .. }));
    assert!(
        polar
            .check_segment([-20.0, -9.95, 1.0], [40.0, 20.0, 1.0])
            .is_ok(),
        "misses the centre"
    );
}

#[test]
fn polar_move_past_a_lateral_offset_hole_and_out_of_the_bed() {
    let polar = Polar::new(polar_params(0.0, 2.0)).expect("valid");
    let err = polar
        .check_segment([-50.0, 1.0, 1.0], [50.0, 1.0, 1.0])
        .expect_err("passes 1 mm from centre");
    assert!(matches!(err.reason, ReachError::InsideMinimumRadius { .. }));
    let err = polar
        .check_segment([0.0, 100.0, 1.0], [0.0, 301.0, 1.0])
        .expect_err("beyond the bed");
    assert!(matches!(err.reason, ReachError::JointLimit { .. }));
    // arm = √(ρ² − dy²) reaches 300 at ρ = √(300² + 2²).
    let rim = (300.0f64 * 300.0 + 4.0).sqrt();
    assert!(
        (100.0 + 201.0 * err.t - rim).abs() < 1e-6,
        "leaves the bed at t = {}",
        err.t
    );
}
