//! Property tests over random machines: FK∘IK and IK∘FK round trips, Jacobian against finite differences,
//! the right error kinds for unreachable points, and never NaN.

use std::f64::consts::PI;

use kinematics::polar::Polar;
use kinematics::scara::Scara;
use kinematics::{ElbowBranch, Kinematics, ReachError, ScaraFrame, ScaraParams, Vec3};
use proptest::prelude::*;

use crate::machines::{fekt_params, polar_params};

fn random_scara() -> impl Strategy<Value = ScaraParams> {
    (
        (
            50.0..200.0f64,
            50.0..200.0f64,
            -50.0..50.0f64,
            -50.0..50.0f64,
        ),
        (
            -1.0..1.0f64,
            any::<bool>(),
            any::<bool>(),
            -1.0..1.0f64,
            -1.0..1.0f64,
        ),
    )
        .prop_map(
            |((l1, l2, ox, oy), (c, right, xscara, zero_a, zero_b))| ScaraParams {
                link1_length: l1,
                link2_length: l2,
                offset_x: ox,
                offset_y: oy,
                elbow_coupling: c,
                ecr: None,
                elbow: if right {
                    ElbowBranch::Right
                } else {
                    ElbowBranch::Left
                },
                frame: if xscara {
                    ScaraFrame::XScara
                } else {
                    ScaraFrame::Standard
                },
                shoulder_zero: zero_a,
                elbow_zero: zero_b,
                base_protection_radius: 0.0,
                ..fekt_params()
            },
        )
}

fn random_polar() -> impl Strategy<Value = Polar> {
    (
        prop_oneof![Just(0.0), -5.0..5.0f64],
        prop_oneof![Just(0.0), -5.0..5.0f64],
    )
        .prop_map(|(dx, dy)| Polar::new(polar_params(dx, dy)).expect("valid polar"))
}

/// A point at distance `rho` from `centre` in direction `angle`.
fn around(centre: [f64; 2], rho: f64, angle: f64, z: f64) -> Vec3 {
    [
        centre[0] + rho * angle.cos(),
        centre[1] + rho * angle.sin(),
        z,
    ]
}

fn assert_close(a: Vec3, b: Vec3, tol: f64) {
    for i in 0..3 {
        assert!((a[i] - b[i]).abs() <= tol, "{a:?} vs {b:?}");
    }
}

/// Central finite differences of the inverse, with angles unwrapped near the centre value.
fn finite_difference_rows(kin: &dyn Kinematics, p: Vec3) -> Vec<Vec3> {
    let n = kin.motors().len();
    let mut centre = vec![0.0; n];
    kin.inverse(p, &mut centre).expect("reachable");
    let h = 1e-6;
    let mut rows = vec![[0.0; 3]; n];
    for j in 0..3 {
        let (mut plus, mut minus) = (p, p);
        plus[j] += h;
        minus[j] -= h;
        let (mut mp, mut mm) = (vec![0.0; n], vec![0.0; n]);
        kin.inverse_near(plus, &centre, &mut mp).expect("reachable");
        kin.inverse_near(minus, &centre, &mut mm)
            .expect("reachable");
        for i in 0..n {
            rows[i][j] = (mp[i] - mm[i]) / (2.0 * h);
        }
    }
    rows
}

fn assert_jacobian_matches(kin: &dyn Kinematics, p: Vec3) {
    let mut rows = vec![[0.0; 3]; kin.motors().len()];
    kin.jacobian(p, &mut rows).expect("regular point");
    let fd = finite_difference_rows(kin, p);
    for (row, fd_row) in rows.iter().zip(&fd) {
        for j in 0..3 {
            let scale = 1.0 + fd_row[j].abs();
            assert!(
                (row[j] - fd_row[j]).abs() <= 1e-5 * scale,
                "jacobian {rows:?} vs fd {fd:?} at {p:?}"
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn scara_forward_of_inverse_is_identity(params in random_scara(), f in 0.02..0.98f64, angle in -PI..PI, z in 0.0..100.0f64) {
        let scara = Scara::new(params.clone()).expect("valid");
        let (l1, l2) = (params.link1_length, params.link2_length);
        let rho = (l1 - l2).abs() + f * (l1 + l2 - (l1 - l2).abs());
        let p = around(scara.shoulder(), rho, angle, z);
        let mut m = [0.0; 3];
        scara.inverse(p, &mut m).expect("inside the annulus");
        assert_close(scara.forward(&m).expect("finite"), p, 1e-9);
    }

    #[test]
    fn scara_inverse_of_forward_recovers_the_joints(params in random_scara(), q1 in -3.0..3.0f64, q2 in 0.05..(PI - 0.05)) {
        let scara = Scara::new(params.clone()).expect("valid");
        let q2 = if params.elbow == ElbowBranch::Right { -q2 } else { q2 };
        let motors = [q1 + params.shoulder_zero, q2 + params.elbow_coupling * q1 + params.elbow_zero, 3.0];
        let p = scara.forward(&motors).expect("finite");
        let mut back = [0.0; 3];
        scara.inverse_near(p, &motors, &mut back).expect("reachable");
        for i in 0..3 {
            prop_assert!((back[i] - motors[i]).abs() < 1e-9, "{back:?} vs {motors:?}");
        }
    }

    #[test]
    fn scara_jacobian_matches_finite_differences(params in random_scara(), f in 0.1..0.9f64, angle in -PI..PI) {
        let scara = Scara::new(params.clone()).expect("valid");
        let (l1, l2) = (params.link1_length, params.link2_length);
        let rho = (l1 - l2).abs() + f * (l1 + l2 - (l1 - l2).abs());
        assert_jacobian_matches(&scara, around(scara.shoulder(), rho, angle, 1.0));
    }

    #[test]
    fn scara_unreachable_points_give_the_right_error(params in random_scara(), extra in 0.001..500.0f64, angle in -PI..PI, inner in 0.0..0.999f64) {
        let scara = Scara::new(params.clone()).expect("valid");
        let (l1, l2) = (params.link1_length, params.link2_length);
        let mut m = [0.0; 3];
        let far = around(scara.shoulder(), l1 + l2 + extra, angle, 0.0);
        let refused = matches!(scara.inverse(far, &mut m), Err(ReachError::OutOfReach { .. }));
        prop_assert!(refused);
        if (l1 - l2).abs() > 1.0 {
            let near = around(scara.shoulder(), inner * ((l1 - l2).abs() - 0.001), angle, 0.0);
            let refused = matches!(scara.inverse(near, &mut m), Err(ReachError::InsideMinimumRadius { .. }));
        prop_assert!(refused);
        }
    }

    #[test]
    fn polar_forward_of_inverse_is_identity(polar in random_polar(), f in 0.0..1.0f64, angle in -PI..PI, z in 0.0..100.0f64) {
        let dy = polar.params().arm_lateral_offset.abs();
        let rho = dy + 0.01 + f * 290.0;
        let p = around([0.0, 0.0], rho, angle, z);
        let mut m = [0.0; 3];
        polar.inverse(p, &mut m).expect("reachable");
        assert_close(polar.forward(&m).expect("finite"), p, 1e-9);
    }

    #[test]
    fn polar_inverse_of_forward_recovers_the_motors(polar in random_polar(), bed in -20.0..20.0f64, extension in 0.5..290.0f64) {
        // The arm must reach past the centre line: dx + r > 0.
        let arm = extension - polar.params().arm_zero_offset;
        let motors = [bed, arm, 7.0];
        let p = polar.forward(&motors).expect("finite");
        let mut back = [0.0; 3];
        polar.inverse_near(p, &motors, &mut back).expect("reachable");
        for i in 0..3 {
            prop_assert!((back[i] - motors[i]).abs() < 1e-9, "{back:?} vs {motors:?}");
        }
    }

    #[test]
    fn polar_jacobian_matches_finite_differences(polar in random_polar(), f in 0.0..1.0f64, angle in -PI..PI) {
        let rho = polar.params().arm_lateral_offset.abs() + 5.0 + f * 280.0;
        assert_jacobian_matches(&polar, around([0.0, 0.0], rho, angle, 1.0));
    }

    #[test]
    fn polar_points_inside_the_lateral_offset_are_refused(dy in 0.1..5.0f64, f in 0.0..0.999f64, angle in -PI..PI) {
        let polar = Polar::new(polar_params(0.3, dy)).expect("valid");
        let mut m = [0.0; 3];
        let p = around([0.0, 0.0], f * dy, angle, 0.0);
        let refused = matches!(polar.inverse(p, &mut m), Err(ReachError::InsideMinimumRadius { .. }));
        prop_assert!(refused);
    }

    #[test]
    fn nothing_ever_returns_nan(params in random_scara(), polar in random_polar(), x in -1e6..1e6f64, y in -1e6..1e6f64, scale in prop_oneof![Just(1e-3), Just(1.0), Just(1e3)]) {
        let scara = Scara::new(params).expect("valid");
        let p = [x * scale * 1e-3, y * scale * 1e-3, 0.0];
        for kin in [&scara as &dyn Kinematics, &polar] {
            let mut m = [0.0; 3];
            if kin.inverse(p, &mut m).is_ok() {
                prop_assert!(m.iter().all(|v| v.is_finite()), "{m:?} at {p:?}");
            }
            let mut rows = [[0.0; 3]; 3];
            if kin.jacobian(p, &mut rows).is_ok() {
                prop_assert!(rows.iter().flatten().all(|v| v.is_finite()));
            }
            let _ = kin.check_segment(p, [0.0, 0.0, 0.0]);
        }
        let mut m = [0.0; 3];
        prop_assert_eq!(scara.inverse([f64::NAN, 0.0, 0.0], &mut m), Err(ReachError::NotFinite));
    }
}
