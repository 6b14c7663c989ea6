//! SCARA identification on simulated measurements around the FEKT-SCARA geometry: recovery accuracy,
//! the analytic Jacobian against finite differences, non-identifiable pose sets, pose suggestion, the model
//! against `kinematics::scara`.

use calibrate::scara::{self, Measurement, ScaraError, ScaraGeometry};
use kinematics::{ElbowBranch, Kinematics, ScaraFrame, ScaraParams, StepperParams};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Candidate poses a FEKT-like arm can take: shoulder −30…210°, elbow joint 15…140° (clear of the 60 mm base
/// protection radius and of the straight-arm singularity), as motor angles for coupling `c`.
fn candidates(c: f64) -> Vec<(f64, f64)> {
    scara::pose_grid(
        (-30f64.to_radians(), 210f64.to_radians()),
        (15f64.to_radians(), 140f64.to_radians()),
        13,
        11,
    )
    .into_iter()
    .map(|(a, q2)| (a, q2 + c * a))
    .collect()
}

fn random_machine(rng: &mut StdRng) -> ScaraGeometry {
    let nominal = ScaraGeometry::fekt();
    ScaraGeometry {
        link1_length: 100.0 + rng.random_range(-1.0..1.0),
        link2_length: 100.0 + rng.random_range(-1.0..1.0),
        offset_x: rng.random_range(-2.0..2.0),
        offset_y: rng.random_range(-2.0..2.0),
        shoulder_zero: rng.random_range(-1.0f64..1.0).to_radians(),
        elbow_zero: rng.random_range(-1.0f64..1.0).to_radians(),
        elbow_coupling: nominal.elbow_coupling * (1.0 + rng.random_range(-0.03..0.03)),
    }
}

fn measure(
    truth: &ScaraGeometry,
    poses: &[(f64, f64)],
    sigma: f64,
    rng: &mut StdRng,
) -> Vec<Measurement> {
    let noise = Normal::new(0.0, sigma).expect("sigma");
    poses
        .iter()
        .map(|&(a, b)| {
            let p = truth.forward(a, b);
            Measurement {
                motor_a: a,
                motor_b: b,
                x: p[0] + noise.sample(rng),
                y: p[1] + noise.sample(rng),
                line: 0,
            }
        })
        .collect()
}

#[test]
fn twenty_poses_recover_random_fekt_machines() {
    let nominal = ScaraGeometry::fekt();
    let poses = scara::suggest_poses(&nominal, &[], &candidates(nominal.elbow_coupling), 20);
    assert_eq!(poses.len(), 20);
    let cond = scara::analyse_poses(&nominal, &poses).condition_number;
    let mut rng = StdRng::seed_from_u64(42);
    let mut worst = [0.0f64; 4]; // lengths+offsets mm, zeros deg, coupling relative, rms
    let machines = 50;
    for _ in 0..machines {
        let truth = random_machine(&mut rng);
        let data = measure(&truth, &poses, 0.02, &mut rng);
        let fit = scara::identify(&data, &nominal).expect("identify");
        let (g, t) = (fit.geometry.to_array(), truth.to_array());
        for k in 0..4 {
            worst[0] = worst[0].max((g[k] - t[k]).abs());
        }
        for k in 4..6 {
            worst[1] = worst[1].max((g[k] - t[k]).abs().to_degrees());
        }
        worst[2] = worst[2].max(((g[6] - t[6]) / t[6]).abs());
        worst[3] = worst[3].max(fit.rms);
        // The reported σ is of the right size: each error within 4σ.
        for k in 0..7 {
            assert!(
                (g[k] - t[k]).abs() <= 4.0 * fit.sigma[k] + 1e-9,
                "{} error {} σ {}",
                scara::PARAM_NAMES[k],
                g[k] - t[k],
                fit.sigma[k]
            );
        }
    }
    println!(
        "SCARA, {machines} machines, 20 D-optimal poses (cond {cond:.1}), 0.02 mm noise: worst length/offset error {:.4} mm, \
         zeros {:.4}°, coupling {:.3}%, rms {:.4} mm",
        worst[0],
        worst[1],
        worst[2] * 100.0,
        worst[3]
    );
    assert!(
        worst[0] <= 0.02 && worst[1] <= 0.02 && worst[2] <= 0.005,
        "{worst:?}"
    );
}

#[test]
fn analytic_jacobian_matches_finite_differences() {
    let mut rng = StdRng::seed_from_u64(5);
    for _ in 0..20 {
        let g = random_machine(&mut rng);
        let (a, b) = (rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
        let analytic = g.parameter_jacobian(a, b);
        let base = g.to_array();
        for k in 0..7 {
            let h = 1e-6 * base[k].abs().max(1.0);
            let (mut up, mut dn) = (base, base);
            up[k] += h;
            dn[k] -= h;
            let (pu, pd) = (
                ScaraGeometry::from_array(up).forward(a, b),
                ScaraGeometry::from_array(dn).forward(a, b),
            );
            for axis in 0..2 {
                let numeric = (pu[axis] - pd[axis]) / (2.0 * h);
                assert!(
                    (numeric - analytic[axis][k]).abs() < 1e-5,
                    "param {k} axis {axis}: {numeric} vs {}",
                    analytic[axis][k]
                );
            }
        }
    }
}

#[test]
fn a_joint_that_never_moves_is_reported() {
    let nominal = ScaraGeometry::fekt();
    let mut rng = StdRng::seed_from_u64(9);
    // Shoulder fixed at 40°, only the elbow moves.
    let poses: Vec<(f64, f64)> = (0..20)
        .map(|k| (40f64.to_radians(), (20.0 + 6.0 * k as f64).to_radians()))
        .collect();
    let report = scara::analyse_poses(&nominal, &poses);
    assert!(!report.is_identifiable());
    assert!(report.condition_number.is_infinite());
    assert_eq!(report.unidentifiable.len(), 3, "{}", report.describe());
    let named: Vec<&str> = report
        .unidentifiable
        .iter()
        .flatten()
        .map(|(n, _)| n.as_str())
        .collect();
    assert!(named.contains(&"link1_length") && named.contains(&"elbow_coupling"));
    let data = measure(&nominal, &poses, 0.02, &mut rng);
    assert!(matches!(
        scara::identify(&data, &nominal),
        Err(ScaraError::Unidentifiable(_))
    ));
    // Elbow joint fixed at 70° (the elbow motor follows the coupling): the arm is rigid, so only its total
    // reach is seen and L1, L2 and the two zeros mix in two combinations.
    let rigid: Vec<(f64, f64)> = (0..20)
        .map(|k| {
            let a = (-20.0 + 10.0 * k as f64).to_radians();
            (a, 70f64.to_radians() + nominal.elbow_coupling * a)
        })
        .collect();
    let report = scara::analyse_poses(&nominal, &rigid);
    assert_eq!(report.unidentifiable.len(), 2, "{}", report.describe());
    let named: Vec<&str> = report
        .unidentifiable
        .iter()
        .flatten()
        .map(|(n, _)| n.as_str())
        .collect();
    assert!(named.contains(&"link1_length") && named.contains(&"link2_length"));
    // Suggested poses repair the set.
    let extra = scara::suggest_poses(&nominal, &poses, &candidates(nominal.elbow_coupling), 4);
    let mut better = poses.clone();
    better.extend(extra);
    let repaired = scara::analyse_poses(&nominal, &better);
    assert!(
        repaired.is_identifiable() && repaired.condition_number < 1e4,
        "{}",
        repaired.condition_number
    );
}

#[test]
fn d_optimal_poses_beat_a_cluster() {
    let nominal = ScaraGeometry::fekt();
    // 20 poses crowded in a 10° × 10° patch: identifiable in principle, badly conditioned.
    let cluster: Vec<(f64, f64)> = scara::pose_grid(
        (80f64.to_radians(), 90f64.to_radians()),
        (90f64.to_radians(), 100f64.to_radians()),
        5,
        4,
    );
    let chosen = scara::suggest_poses(&nominal, &[], &candidates(nominal.elbow_coupling), 20);
    let (bad, good) = (
        scara::analyse_poses(&nominal, &cluster),
        scara::analyse_poses(&nominal, &chosen),
    );
    println!(
        "condition number: 10° cluster {:.0}, D-optimal {:.1}",
        bad.condition_number, good.condition_number
    );
    assert!(good.condition_number * 20.0 < bad.condition_number);
}

#[test]
fn model_agrees_with_kinematics_scara() {
    let stepper = |name: &str| StepperParams {
        name: name.into(),
        step_distance: 1e-4,
        position_min: None,
        position_max: None,
    };
    let mut rng = StdRng::seed_from_u64(11);
    for _ in 0..20 {
        let g = random_machine(&mut rng);
        let params = ScaraParams {
            shoulder_stepper: stepper("stepper_a"),
            elbow_stepper: stepper("stepper_b"),
            z: stepper("stepper_z"),
            link1_length: g.link1_length,
            link2_length: g.link2_length,
            offset_x: g.offset_x,
            offset_y: g.offset_y,
            elbow_coupling: g.elbow_coupling,
            ecr: None,
            elbow: ElbowBranch::Left,
            frame: ScaraFrame::Standard,
            shoulder_zero: g.shoulder_zero,
            elbow_zero: g.elbow_zero,
            shoulder_limits: None,
            elbow_limits: None,
            base_protection_radius: 0.0,
            singularity_margin: 0.0,
        };
        let kin = kinematics::scara::Scara::new(params).expect("valid params");
        let (a, b) = (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
        let p = kin.forward(&[a, b, 0.0]).expect("forward");
        let q = g.forward(a, b);
        assert!((p[0] - q[0]).abs() < 1e-9 && (p[1] - q[1]).abs() < 1e-9);
    }
}
