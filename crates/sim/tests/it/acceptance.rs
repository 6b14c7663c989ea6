//! The acceptance cases, with the numbers printed for the report.

use crate::common::{corpus_circle, polar_pair, polar_print};
use sim::scenario::{
    SCARA_CIRCLES, SCARA_SQUARES, closed_loop, scara_config, scara_coupling_loop, simulate,
    test_print_gcode,
};
use sim::{Machine, ReplayOptions};

fn print_summary(label: &str, s: &sim::Simulation) {
    let d = s.replay.deposited.summary();
    println!(
        "{label}: max path dev {:.4} mm, rms {:.4} mm, same-instant max {:.4} mm, model error max {:.4} mm",
        d.max_path_deviation, d.rms_path_deviation, d.max_time_error, d.max_model_error
    );
    for c in &s.circles {
        let e = c.ellipse.expect("ellipse");
        println!(
            "  circle L{} Ø {:.4} → {:.4}, roundness {:.4}, axes {:.4} × {:.4}, shift {:.4}",
            c.layer,
            c.intended_diameter,
            c.actual_diameter,
            c.roundness,
            2.0 * e.semi_major,
            2.0 * e.semi_minor,
            c.centre_shift()
        );
    }
    for q in &s.quads {
        println!(
            "  square L{} worst side error {:.4} mm, worst angle error {:.4}°",
            q.layer,
            q.worst_side_error(),
            q.worst_angle_error()
        );
    }
}

#[test]
fn polar_sideways_arm_offset_is_found_and_corrected() {
    let (believed, actual_cfg) = polar_pair("arm_lateral_offset: 1.0", "");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let gcode = corpus_circle().unwrap_or_else(|| polar_print().into_bytes());
    let run = closed_loop(
        &believed,
        &actual,
        || Ok(&gcode[..]),
        "circle",
        &ReplayOptions::default(),
        3,
    )
    .expect("closed loop");
    print_summary("polar 1 mm sideways, before", &run.before);
    print_summary("polar 1 mm sideways, after", &run.after);
    // Closed form: the nozzle sits at Rot(θ)·(r, dy) instead of Rot(θ)·(r, 0): exactly |dy| = 1 mm away.
    let before = run.before.replay.deposited;
    assert!(
        (before.max_model_error - 1.0).abs() < 1e-9,
        "{}",
        before.max_model_error
    );
    assert!((before.rms_model_error() - 1.0).abs() < 1e-9);
    assert!(before.max_path_deviation > 0.5);
    // A centred circle of radius R is printed with radius √(R² + dy²) (the offset arm line misses the
    // centre by dy), to within the bed's step resolution.
    assert!(!run.before.circles.is_empty());
    for c in &run.before.circles {
        let r = 0.5 * c.intended_diameter;
        if c.intended_centre[0].hypot(c.intended_centre[1]) < 0.1 {
            let expected = 2.0 * (r * r + 1.0).sqrt();
            assert!((c.actual_diameter - expected).abs() < 0.005, "{c:?}");
        }
    }
    // The scan measures the offset; after correction the print is within 0.02 mm.
    let dy = &run.correction.values[1];
    assert_eq!(dy.name, "arm_lateral_offset");
    assert!((dy.measured - 1.0).abs() < 0.01, "{dy:?}");
    let after = run.after.replay.deposited;
    assert!(
        after.max_path_deviation <= 0.02,
        "{}",
        after.max_path_deviation
    );
    assert!(after.max_model_error <= 0.02);
    for c in &run.after.circles {
        assert!(
            (c.actual_diameter - c.intended_diameter).abs() < 0.02,
            "{c:?}"
        );
        assert!(c.centre_shift() < 0.02, "{c:?}");
    }
}

#[test]
fn off_centre_features_change_size_and_shape_on_a_polar_printer() {
    // The centring thesis' claim: a sub-millimetre displacement deforms off-centre features.
    let (believed, actual_cfg) = polar_pair("arm_lateral_offset: 0.5", "");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let gcode = polar_print();
    let s = simulate(
        &believed,
        &actual,
        gcode.as_bytes(),
        "print",
        &ReplayOptions::default(),
    )
    .expect("sim");
    print_summary("polar 0.5 mm sideways, generated print", &s);
    let off_centre = s
        .circles
        .iter()
        .find(|c| c.intended_centre[0] > 10.0)
        .expect("off-centre circle");
    let e = off_centre.ellipse.expect("ellipse");
    assert!(2.0 * (e.semi_major - e.semi_minor) > 0.1, "{off_centre:?}");
    assert!(off_centre.centre_shift() > 0.3);
    let square = &s.quads[0];
    assert!(
        square.worst_side_error() > 0.1 && square.worst_angle_error() > 0.1,
        "{square:?}"
    );
}

#[test]
fn scara_wrong_ecr_and_arm_length_give_ovals_and_identification_fixes_them() {
    let run = scara_coupling_loop().expect("closed loop");
    print_summary("SCARA ECR 3.2 / L1 +0.5 mm, before", &run.before);
    print_summary("SCARA after identification", &run.after);
    assert_eq!(run.before.circles.len(), 2 * SCARA_CIRCLES.len());
    for c in &run.before.circles {
        let e = c.ellipse.expect("ellipse");
        assert!(
            2.0 * (e.semi_major - e.semi_minor) > 0.05,
            "not an oval: {c:?}"
        );
    }
    // The identification recovers the true geometry.
    let value = |name: &str| {
        run.correction
            .values
            .iter()
            .find(|v| v.name == name)
            .expect("parameter")
            .clone()
    };
    assert!((1.0 / value("elbow_coupling").measured - 3.2).abs() < 0.01);
    assert!((value("link1_length").measured - 100.5).abs() < 0.01);
    // After correction: the assembly error left is within 0.02 mm, and the path is as good as a perfect
    // machine's (whose own deviation is the step quantisation of a 9600-step/rev joint).
    let after = run.after.replay.deposited;
    assert!(after.max_model_error <= 0.02, "{}", after.max_model_error);
    let ideal = scara_ideal_baseline();
    println!(
        "SCARA perfect machine: max path dev {:.4} mm",
        ideal.max_path_deviation
    );
    assert!(after.max_path_deviation <= ideal.max_path_deviation + 0.02);
    for c in &run.after.circles {
        let e = c.ellipse.expect("ellipse");
        assert!(2.0 * (e.semi_major - e.semi_minor) < 0.02, "{c:?}");
        assert!(
            (c.actual_diameter - c.intended_diameter).abs() < 0.02,
            "{c:?}"
        );
    }
}

fn scara_ideal_baseline() -> sim::metrics::DeviationStats {
    let believed = config::MachineConfig::from_str(&scara_config(), "scara.cfg").expect("config");
    let actual = Machine::new(&believed.params, vec![]).expect("machine");
    let gcode = test_print_gcode(&SCARA_CIRCLES, &SCARA_SQUARES, 2, Some([0.0, 130.0, 0.5]));
    let s = simulate(
        &believed,
        &actual,
        gcode.as_bytes(),
        "scara",
        &ReplayOptions::default(),
    )
    .expect("sim");
    s.replay.deposited
}

#[test]
fn without_assembly_errors_the_path_matches_within_step_resolution() {
    let options = ReplayOptions {
        track_resolution: true,
        ..ReplayOptions::default()
    };
    let (believed, _) = polar_pair("", "");
    let actual = Machine::new(&believed.params, vec![]).expect("machine");
    let gcode = corpus_circle().unwrap_or_else(|| polar_print().into_bytes());
    let polar = simulate(&believed, &actual, &gcode[..], "circle", &options).expect("polar");
    let scara_cfg = config::MachineConfig::from_str(&scara_config(), "scara.cfg").expect("config");
    let scara_actual = Machine::new(&scara_cfg.params, vec![]).expect("machine");
    let scara_gcode = test_print_gcode(&SCARA_CIRCLES, &SCARA_SQUARES, 1, Some([0.0, 130.0, 0.5]));
    let scara = simulate(
        &scara_cfg,
        &scara_actual,
        scara_gcode.as_bytes(),
        "scara",
        &options,
    )
    .expect("scara");
    for (name, s) in [("polar", &polar), ("SCARA", &scara)] {
        let all = s.replay.all;
        let ratio = s.replay.worst_resolution_ratio.expect("tracked");
        println!(
            "{name} perfect machine: max same-instant error {:.4} mm = {ratio:.3} × local step resolution, max path dev {:.4} mm",
            all.max_time_error, s.replay.deposited.max_path_deviation
        );
        // Step resolution bound: every motor is within one step of its ideal position at all times.
        assert!(ratio <= 1.0, "{name}: {ratio}");
        // True and believed machine agree exactly at every motor state.
        assert_eq!(all.max_model_error, 0.0);
        // Z: within one Z step (8 mm / 3200).
        assert!(all.max_z_error <= 8.0 / 3200.0 + 1e-12);
    }
    // Polar, printing (r ≤ 83 mm): at most a bed step there (16000 steps/rev: 0.033 mm) plus an arm step
    // (0.0125 mm). Travel out to the arm's endstop at 300 mm is coarser and is covered by the ratio above.
    let bound = std::f64::consts::TAU / 16000.0 * 83.0 + 0.0125;
    let printing = polar.replay.deposited.max_time_error;
    assert!(printing <= bound, "{printing}");
}

#[test]
fn results_do_not_depend_on_the_chunk_size() {
    // Tiny chunks make the merge horizon bite constantly (held-back steps, Z resting mid-step).
    let (believed, actual_cfg) =
        polar_pair("arm_lateral_offset: 0.3", "backlash_stepper_arm: 0.02");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let gcode = polar_print();
    let run = |chunk_pieces| {
        let options = ReplayOptions {
            chunk_pieces,
            ..ReplayOptions::default()
        };
        simulate(&believed, &actual, gcode.as_bytes(), "p", &options).expect("sim")
    };
    let (big, small) = (run(100_000), run(7));
    assert_eq!(big.replay.all, small.replay.all);
    assert_eq!(big.replay.path, small.replay.path);
    assert_eq!(big.replay.steps, small.replay.steps);
}

#[test]
fn polar_zero_and_lateral_offsets_together_are_corrected() {
    let (believed, actual_cfg) = polar_pair("arm_zero_offset: 0.4\narm_lateral_offset: -0.6", "");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let gcode = polar_print();
    let run = closed_loop(
        &believed,
        &actual,
        || Ok(gcode.as_bytes()),
        "p",
        &ReplayOptions::default(),
        5,
    )
    .expect("closed loop");
    print_summary("polar dx 0.4 dy -0.6, before", &run.before);
    print_summary("polar dx 0.4 dy -0.6, after", &run.after);
    // A zero offset dx makes every radius dx longer: circles about the centre grow by 2·dx.
    let centred = run
        .before
        .circles
        .iter()
        .find(|c| c.intended_centre[0].hypot(c.intended_centre[1]) < 0.1);
    let c = centred.expect("centred circle");
    let r = 0.5 * c.intended_diameter;
    let expected = 2.0 * ((r + 0.4) * (r + 0.4) + 0.36).sqrt();
    assert!(
        (c.actual_diameter - expected).abs() < 0.005,
        "{c:?} vs {expected}"
    );
    let after = run.after.replay.deposited;
    assert!(
        after.max_path_deviation <= 0.02,
        "{}",
        after.max_path_deviation
    );
    for q in &run.after.quads {
        assert!(
            q.worst_side_error() < 0.02 && q.worst_angle_error() < 0.05,
            "{q:?}"
        );
    }
}

#[test]
fn scara_joint_zero_and_shoulder_position_errors_are_identified() {
    let believed = config::MachineConfig::from_str(&scara_config(), "scara.cfg").expect("config");
    let actual_text = sim::scenario::with_keys(
        &scara_config(),
        "printer",
        "offset_x: 0.4\noffset_y: -0.3\nshoulder_zero: 0.3\nelbow_zero: -0.2",
    );
    let actual_cfg = config::MachineConfig::from_str(&actual_text, "actual.cfg").expect("actual");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let gcode = test_print_gcode(&SCARA_CIRCLES, &SCARA_SQUARES, 1, Some([0.0, 130.0, 0.5]));
    let run = closed_loop(
        &believed,
        &actual,
        || Ok(gcode.as_bytes()),
        "s",
        &ReplayOptions::default(),
        9,
    )
    .expect("closed loop");
    print_summary(
        "SCARA zeros 0.3°/-0.2°, shoulder (0.4, -0.3), before",
        &run.before,
    );
    print_summary("SCARA zeros/shoulder, after", &run.after);
    assert!(run.before.replay.deposited.max_model_error > 0.5);
    assert!(run.after.replay.deposited.max_model_error <= 0.02);
}

#[test]
fn results_do_not_depend_on_how_much_path_is_kept() {
    let (believed, actual_cfg) = polar_pair("arm_lateral_offset: 0.3\narm_zero_offset: -0.2", "");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let gcode = polar_print();
    let full = simulate(
        &believed,
        &actual,
        gcode.as_bytes(),
        "p",
        &ReplayOptions::default(),
    )
    .expect("sim");
    let small = ReplayOptions {
        max_points: 2000,
        ..ReplayOptions::default()
    };
    let thin = simulate(&believed, &actual, gcode.as_bytes(), "p", &small).expect("sim");
    assert!(thin.replay.path.len() < 2000);
    assert_eq!(full.replay.deposited, thin.replay.deposited);
    assert_eq!(full.replay.layers, thin.replay.layers);
    // Every deposited sample's deviation is carried by a kept deposited point.
    for s in [&full, &thin] {
        let kept_max = s
            .replay
            .path
            .iter()
            .filter(|p| p.deposited)
            .map(|p| p.deviation)
            .fold(0.0, f64::max);
        assert_eq!(kept_max, s.replay.deposited.max_path_deviation);
    }
}
