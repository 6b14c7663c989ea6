//! `simulate --correct` on a SCARA calibrates as a user does: the believed machine's pattern (the one pattern
//! maker), printed by the machine as built, each cross measured with the calipers' noise and resolution. Checked
//! against the test's own forward model of the arm as built.

use rand::SeedableRng;
use rand::rngs::StdRng;
use sim::Machine;
use sim::crosses::{CALIPERS, print_and_measure};
use sim::scenario::{scara_config, scenario_configs};

/// The arm as built (FEKT-SCARA's 100/100 mm arm, shoulder at the origin, zeros at 0, built with a 100.5 mm
/// proximal link and ECR 3.2): where its nozzle is at motor angles (a, b), in the test's own terms.
fn built_nozzle(a: f64, b: f64) -> [f64; 2] {
    let (l1, l2, coupling) = (100.5, 100.0, 1.0 / 3.2);
    let shoulder = a;
    let elbow = b - coupling * shoulder;
    [
        l1 * shoulder.cos() + l2 * (shoulder + elbow).cos(),
        l1 * shoulder.sin() + l2 * (shoulder + elbow).sin(),
    ]
}

#[test]
fn the_crosses_are_measured_where_the_machine_as_built_printed_them() {
    let (believed, actual_cfg) =
        scenario_configs(&scara_config(), "link1_length: 100.5\necr: 3.2").expect("configs");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let measured = print_and_measure(&believed, &actual, CALIPERS, &mut StdRng::seed_from_u64(5))
        .expect("a measured pattern");
    // The default pattern of the believed machine, every cross measured.
    assert_eq!(measured.data.len(), calibrate::scara::DEFAULT_POSES);
    assert_eq!(measured.pattern.poses.len(), measured.data.len());
    let mut squares = 0.0;
    let mut farthest_from_written = 0.0f64;
    for ((m, &(a, b)), c) in measured
        .data
        .iter()
        .zip(&measured.pattern.poses)
        .zip(&measured.pattern.centres)
    {
        assert_eq!((m.motor_a, m.motor_b), (a, b));
        // Read to the calipers' 0.01 mm.
        for v in [m.x, m.y] {
            assert!((v * 100.0 - (v * 100.0).round()).abs() < 1e-6, "{v}");
        }
        let truth = built_nozzle(a, b);
        let miss = (m.x - truth[0]).hypot(m.y - truth[1]);
        // Noise (0.02 mm per coordinate), rounding and the joints' step quantisation: within 5σ.
        assert!(
            miss < 0.12,
            "cross {}: {miss} mm from the built arm's nozzle",
            m.line
        );
        squares += (m.x - truth[0]).powi(2) + (m.y - truth[1]).powi(2);
        farthest_from_written = farthest_from_written.max((m.x - c[0]).hypot(m.y - c[1]));
    }
    let rms = (squares / (2.0 * measured.data.len() as f64)).sqrt();
    println!(
        "measured crosses: rms {rms:.4} mm from the built arm's nozzle, up to {farthest_from_written:.3} mm from where the G-code put them"
    );
    // The noise stated (0.02 mm) is in the readings, and nothing much besides.
    assert!(rms > 0.01 && rms < 0.035, "{rms}");
    // The built arm puts the crosses millimetres from where the believed one meant them.
    assert!(farthest_from_written > 0.5, "{farthest_from_written}");
}
