//! `JOINTSPACE_SCAN_CENTRE`: in batch mode (no ADC data there) the command runs its sweep, arm pass by pass
//! across the magnet ring on both sides of the centre and a full bed revolution at each, then refuses to store
//! anything; its data path (ADC reports with the motors' readings at their times → detections → fit) is run
//! through the library's C functions the command calls, with reports from the simulated Hall bed (`sim::hall`,
//! whose true offsets the result must give back), and the detections file it writes is re-read by
//! `jointspace calibrate centre --scan`.

use std::ffi::{CStr, OsStr, c_char};

use jointspace_klipper::scan::HallScanSettings;
use jointspace_klipper::{jointspace_scan_centre, jointspace_scan_passes};
use sim::hall::{HallBedConfig, HallScanner, Ky024, SweepMotion};

use crate::engine::run_jointspace;
use crate::hosts::{Hosts, KLIPPER, workspace_root, write};

/// The settings `[jointspace] hall_*` gives for the simulated sensor (a KY-024 on a 5 V ADC).
fn settings(sensor: &Ky024) -> HallScanSettings {
    HallScanSettings {
        magnet_count: 16,
        ring_radius: 100.0,
        max_offset: 2.0,
        pass_pitch: 0.5,
        field_reach: 4.0,
        threshold: 0.010,
        adc_reference: sensor.vref,
        sensitivity: sensor.sensitivity,
        saturation: sensor.saturation,
        max_sigma: 0.01,
        sensor_alignment: 0.05,
    }
}

/// The passes through the C function.
fn passes(settings: &HallScanSettings) -> (Vec<f64>, f64) {
    let mut arms = vec![0.0; 512];
    let mut overlap = 0.0;
    let mut error = [0 as c_char; 256];
    // SAFETY: arms holds 512 doubles, error 256 bytes.
    let count = unsafe {
        jointspace_scan_passes(
            settings,
            arms.as_mut_ptr(),
            512,
            &mut overlap,
            error.as_mut_ptr(),
            256,
        )
    };
    assert!(count > 0, "passes: {count}");
    arms.truncate(count as usize);
    (arms, overlap)
}

/// What the command gets back from the library for a simulated printer's sweep: the return code, dx and dy,
/// the detections file and the report.
struct Outcome {
    rc: i32,
    result: [f64; 4],
    csv: String,
    report: String,
}

fn scan_simulated(cfg: HallBedConfig, settings: &HallScanSettings) -> Outcome {
    let (arms, overlap) = passes(settings);
    let mut machine = HallScanner::new(cfg).expect("sim");
    // The printer's pass at the scan's default speed (50 mm/s along the ring) and the ADC's 2 ms reports.
    let motion = SweepMotion {
        bed_speed: 0.5,
        bed_accel: 5.0,
        overlap,
        sample_time: 0.002,
    };
    let samples = machine.sweep(&arms, motion).expect("sweep");
    let rows: Vec<f64> = samples
        .iter()
        .flat_map(|s| [s.pass as f64, s.arm, s.bed, s.adc])
        .collect();
    let mut result = [0.0; 4];
    let mut csv = vec![0 as c_char; 1 << 16];
    let mut report = vec![0 as c_char; 1 << 13];
    // SAFETY: rows holds 4 · samples.len() doubles; result four; the buffers their lengths.
    let rc = unsafe {
        jointspace_scan_centre(
            settings,
            rows.as_ptr(),
            samples.len(),
            result.as_mut_ptr(),
            csv.as_mut_ptr(),
            csv.len(),
            report.as_mut_ptr(),
            report.len(),
        )
    };
    let text = |b: &[c_char]| {
        // SAFETY: the library NUL-terminates what it writes; the buffers start zeroed.
        unsafe { CStr::from_ptr(b.as_ptr()) }
            .to_string_lossy()
            .into_owned()
    };
    Outcome {
        rc,
        result,
        csv: text(&csv),
        report: text(&report),
    }
}

#[test]
fn simulated_sweeps_give_the_offsets_back_through_the_detections_file() {
    let sensor = Ky024::default();
    let settings = settings(&sensor);
    let dir = tempfile::tempdir().expect("temp dir");
    for seed in [3, 17, 41] {
        let cfg = HallBedConfig::default().random_offsets(2.0, seed);
        let truth = [cfg.arm_zero_offset, cfg.arm_lateral_offset];
        let outcome = scan_simulated(cfg, &settings);
        assert_eq!(outcome.rc, 0, "seed {seed}: {}", outcome.report);
        let error = (outcome.result[0] - truth[0]).hypot(outcome.result[1] - truth[1]);
        println!(
            "seed {seed}: dx {:+.4} dy {:+.4} (true {:+.4} {:+.4}), error {error:.4} mm; {}",
            outcome.result[0], outcome.result[1], truth[0], truth[1], outcome.report
        );
        assert!(error <= 0.005, "seed {seed}: error {error} mm");
        // The file the command writes, read by the command line as a user would.
        let file = write(dir.path(), &format!("scan-{seed}.csv"), &outcome.csv);
        let centre = dir.path().join(format!("centre-{seed}.json"));
        let output = run_jointspace([
            OsStr::new("calibrate"),
            OsStr::new("centre"),
            OsStr::new("--json"),
            OsStr::new("--scan"),
            file.as_os_str(),
            OsStr::new("-o"),
            centre.as_os_str(),
        ]);
        let json = String::from_utf8_lossy(&output.stdout);
        for (key, value) in [
            ("arm_zero_offset", truth[0]),
            ("arm_lateral_offset", truth[1]),
        ] {
            let read = json_number(&json, key);
            assert!(
                (read - value).abs() <= 0.005,
                "seed {seed}: {key} {read} vs {value}"
            );
        }
    }
}

fn json_number(json: &str, key: &str) -> f64 {
    let at = json.find(&format!("\"{key}\":")).expect(key) + key.len() + 3;
    let rest = json[at..].trim_start();
    let end = rest.find([',', '\n']).unwrap_or(rest.len());
    rest[..end].trim().parse().expect("number")
}

#[test]
fn bad_scans_are_refused_with_the_reason() {
    let sensor = Ky024::default();
    let missing = HallBedConfig {
        missing: vec![5],
        ..HallBedConfig::default()
    };
    let outcome = scan_simulated(missing, &settings(&sensor));
    assert_eq!(outcome.rc, -1);
    assert!(
        outcome.report.contains("15 magnets, the ring has 16"),
        "{}",
        outcome.report
    );
    // A 5 V sensor on a 3.3 V ADC: the output passes the ADC's reference at the magnets.
    let three_volt = Ky024 {
        vref: 3.3,
        ..sensor
    };
    let clipped = HallBedConfig {
        sensor: three_volt,
        magnet: sim::hall::MagnetSpec {
            remanence: 3.0,
            ..Default::default()
        },
        ..HallBedConfig::default()
    };
    let outcome = scan_simulated(clipped, &settings(&three_volt));
    assert_eq!(outcome.rc, -1);
    assert!(outcome.report.contains("saturates"), "{}", outcome.report);
    // A loose sensor: noise ten times the datasheet's scatters the pairs beyond hall_max_sigma.
    let noisy = HallBedConfig {
        sensor: Ky024 {
            noise: 8e-3,
            ..sensor
        },
        ..HallBedConfig::default()
    };
    let outcome = scan_simulated(noisy, &settings(&sensor));
    assert_eq!(outcome.rc, -1, "{}", outcome.report);
    println!("noisy: {}", outcome.report);
}

/// The polar example with an arm that passes the centre, and a Hall sensor on an analogue pin.
fn scan_config(dir: &std::path::Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(workspace_root().join("klipper/examples/polar.cfg"))
        .expect("example");
    let text = text
        .replace("position_max: 300\n", "position_max: 300\nposition_min: -120\n")
        .replace(
            "[jointspace]\n",
            "[jointspace]\nhall_pin: PK7\nhall_ring_radius: 100\nhall_max_offset: 1\nhall_field_reach: 3\n\
             hall_pass_pitch: 1\n",
        );
    write(dir, "printer.cfg", &text)
}

#[test]
fn batch_mode_runs_the_sweep_and_stores_nothing() {
    let Some(hosts) = Hosts::get("batch_mode_runs_the_sweep_and_stores_nothing") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = scan_config(dir.path());
    let gcode = write(
        dir.path(),
        "scan.gcode",
        "G28\nJOINTSPACE_SCAN_CENTRE\nG1 X50 Y10 F3000\nGET_POSITION\n",
    );
    let run = hosts.batch(KLIPPER, true, &config, &gcode, &dir.path().join("out"));
    // A refused command fails the batch run; everything after it still runs.
    assert!(!run.success, "a refused scan is an error");
    assert!(
        run.log
            .contains("centre scan refused, nothing stored (18 passes, 0 readings)")
            && run.log.contains("no sensor readings"),
        "{}",
        crate::hosts::tail(&run.log, 30)
    );
    assert!(!dir.path().join("jointspace-centre-scan.csv").exists());
    let steps = run.steps();
    let (arm, bed) = (&steps["stepper_arm"], &steps["stepper_bed"]);
    // The passes the library plans for these settings: the arm stops at each while the bed turns.
    let mut settings = settings(&Ky024::default());
    settings.max_offset = 1.0;
    settings.field_reach = 3.0;
    settings.pass_pitch = 1.0;
    let (arms, overlap) = passes(&settings);
    let stops = arm_stops(arm, bed);
    let turn_steps = 16000.0 * (1.0 + overlap / std::f64::consts::PI);
    let pass_stops: Vec<&(f64, i64)> = stops
        .iter()
        .filter(|(_, bed_steps)| (*bed_steps as f64).abs() > 0.9 * turn_steps)
        .collect();
    assert_eq!(pass_stops.len(), arms.len(), "{stops:?}");
    // Homing moves come before (their start is unknown in batch mode): the passes are compared by their
    // distances from the first, which covers both sides of the centre.
    let first = pass_stops[0].0;
    for ((position, bed_steps), planned) in pass_stops.iter().zip(&arms) {
        let (moved, planned_move) = (position - first, planned - arms[0]);
        assert!(
            (moved - planned_move).abs() <= 0.0125,
            "arm moved {moved} vs {planned_move}"
        );
        assert!(
            (bed_steps.abs() as f64 - turn_steps).abs() <= 1.0,
            "{bed_steps} vs {turn_steps}"
        );
    }
    // Back in Cartesian coordinates after the scan: the next move goes where it is sent.
    assert!(
        run.log.contains("toolhead: X:50.000000 Y:10.000000"),
        "{}",
        crate::hosts::tail(&run.log, 30)
    );
}

/// Where the arm rests between its moves (mm from where it started) and the net bed steps while it rests.
fn arm_stops(arm: &[(i64, i8)], bed: &[(i64, i8)]) -> Vec<(f64, i64)> {
    const ARM_STEP: f64 = 40.0 / 3200.0;
    const GAP: i64 = 16_000_000 / 10; // 0.1 s without an arm step: the arm rests
    let mut stops = Vec::new();
    let mut position = 0i64;
    let mut rest_from = i64::MIN;
    let net_bed = |from: i64, to: i64| -> i64 {
        bed.iter()
            .filter(|(c, _)| *c > from && *c < to)
            .map(|(_, d)| if *d == 1 { 1 } else { -1 })
            .sum()
    };
    for (clock, dir) in arm {
        if *clock - rest_from > GAP && rest_from != i64::MIN {
            stops.push((position, net_bed(rest_from, *clock)));
        }
        position += if *dir == 1 { 1 } else { -1 };
        rest_from = *clock;
    }
    stops.push((position, net_bed(rest_from, i64::MAX)));
    stops
        .into_iter()
        .map(|(p, b)| (p as f64 * ARM_STEP, b))
        .collect()
}
