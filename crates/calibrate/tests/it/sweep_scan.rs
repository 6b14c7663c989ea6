//! The printer's continuous sweep (`calibrate::sweep`) on simulated machines (sim::hall): the ADC reports of
//! full bed revolutions at a series of arm readings, with step-quantised positions at each report's time, give
//! the simulated offsets back.

use calibrate::scan::{ScanParams, centre_from_detections};
use calibrate::sweep::{SweepParams, detect, pass_arms};
use sim::hall::{HallBedConfig, HallScanner, Ky024, SweepMotion};

/// The sim's KY-024 on a 5 V ADC, as the sweep's settings see it.
fn five_volt_params() -> SweepParams {
    let sensor = Ky024::default();
    SweepParams {
        adc: calibrate::sweep::HallAdc {
            reference: sensor.vref,
            sensitivity: sensor.sensitivity,
            saturation: sensor.saturation,
        },
        ..SweepParams::default()
    }
}

fn motion(params: &SweepParams) -> SweepMotion {
    SweepMotion {
        bed_speed: 0.5,
        bed_accel: 5.0,
        overlap: params.bed_overlap(),
        sample_time: 0.002,
    }
}

fn sweep_error(seed: u64) -> f64 {
    let cfg = HallBedConfig::default().random_offsets(2.0, seed);
    let (dx, dy) = (cfg.arm_zero_offset, cfg.arm_lateral_offset);
    let mut machine = HallScanner::new(cfg).expect("valid sim");
    let params = five_volt_params();
    let samples = machine
        .sweep(&pass_arms(&params).expect("passes"), motion(&params))
        .expect("sweep");
    let slots = detect(&params, &samples).expect("detections");
    let result =
        centre_from_detections(&ScanParams::default(), slots.near, slots.far).expect("fit");
    println!(
        "seed {seed}: dx {:+.4} (true {dx:+.4}), dy {:+.4} (true {dy:+.4}), σ {:.4} {:.4}, pairs {}",
        result.arm_zero_offset,
        result.arm_lateral_offset,
        result.sigma_scan[0],
        result.sigma_scan[1],
        result.pairs_used
    );
    (result.arm_zero_offset - dx).hypot(result.arm_lateral_offset - dy)
}

#[test]
fn sweeps_recover_the_offsets_within_5_microns() {
    let errors: Vec<f64> = (0..12).map(sweep_error).collect();
    println!("errors {errors:?}");
    assert!(errors.iter().all(|e| *e <= 0.005), "{errors:?}");
}
