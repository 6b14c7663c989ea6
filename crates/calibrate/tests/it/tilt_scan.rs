//! A tilted Hall sensor, and its tilt removed by a second scan at another height. The bed here is the test's own
//! physical model, not `sim::hall`: point dipoles (Ø3×5 mm N35-like magnets, axial, pole up) read along a sensor
//! axis tilted by `α`, the motors quantised to their steps, the sensor noisy.

use calibrate::scan::{
    CentreResult, HardwareError, ScanHardware, ScanParams, remove_tilt, scan_centre,
};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::f64::consts::TAU;

/// μ0/4π (T·m/A).
const MU0_4PI: f64 = 1e-7;
/// A Ø3×5 mm magnet of 1.2 T remanence: moment Br·V/μ0 (A·m²).
const MOMENT: f64 =
    1.2 * (std::f64::consts::PI * 1.5e-3 * 1.5e-3 * 5e-3) / (4e-7 * std::f64::consts::PI);

struct DipoleBed {
    /// Magnet centres in the bed's frame (mm).
    magnets: Vec<[f64; 2]>,
    /// True arm offsets along and across the arm (mm).
    offset: [f64; 2],
    /// Sensor above the magnets' centres (mm).
    height: f64,
    /// The sensor's axis (unit, machine frame: x along the arm, z up).
    axis: [f64; 3],
    arm_steps: i64,
    bed_steps: i64,
    noise: Normal<f64>,
    rng: StdRng,
}

const ARM_STEPS_PER_MM: f64 = 80.0;
const BED_STEPS_PER_REV: f64 = 16000.0;

impl DipoleBed {
    /// A ring of 16 magnets on 100 mm (each placed within 0.1 mm), the arm at `offset`, the sensor `tilt_deg`
    /// from vertical towards `towards_deg` (0: along the arm), `height` mm above the magnets' centres.
    fn new(seed: u64, offset: [f64; 2], tilt_deg: f64, towards_deg: f64, height: f64) -> Self {
        let mut rng = StdRng::seed_from_u64(seed);
        let magnets = (0..16)
            .map(|k| {
                let a = TAU * f64::from(k) / 16.0;
                [
                    100.0 * a.cos() + rng.random_range(-0.1..0.1),
                    100.0 * a.sin() + rng.random_range(-0.1..0.1),
                ]
            })
            .collect();
        let (t, d) = (tilt_deg.to_radians(), towards_deg.to_radians());
        DipoleBed {
            magnets,
            offset,
            height,
            axis: [t.sin() * d.cos(), t.sin() * d.sin(), t.cos()],
            arm_steps: 0,
            bed_steps: 0,
            noise: Normal::new(0.0, 0.05e-3).expect("noise"),
            rng,
        }
    }

    fn arm(&self) -> f64 {
        self.arm_steps as f64 / ARM_STEPS_PER_MM
    }

    fn bed(&self) -> f64 {
        self.bed_steps as f64 * TAU / BED_STEPS_PER_REV
    }

    /// The field along the sensor's axis (T): each dipole's B = μ0/4π·(3(m·r̂)r̂ − m)/|r|³.
    fn field(&self) -> f64 {
        let sensor = [self.arm() + self.offset[0], self.offset[1]];
        let (s, c) = self.bed().sin_cos();
        let mut along = 0.0;
        for m in &self.magnets {
            // The bed point p under the sensor is Rot(θ)·sensor, so a magnet sits at Rot(−θ)·m.
            let at = [c * m[0] + s * m[1], -s * m[0] + c * m[1]];
            let r = [
                (sensor[0] - at[0]) * 1e-3,
                (sensor[1] - at[1]) * 1e-3,
                self.height * 1e-3,
            ];
            let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            let mz = r[2] / len;
            let b: Vec<f64> = (0..3)
                .map(|k| {
                    let unit = r[k] / len;
                    let pole = if k == 2 { 1.0 } else { 0.0 };
                    MU0_4PI * MOMENT * (3.0 * mz * unit - pole) / len.powi(3)
                })
                .collect();
            along += (0..3).map(|k| b[k] * self.axis[k]).sum::<f64>();
        }
        along
    }
}

impl ScanHardware for DipoleBed {
    fn move_arm(&mut self, r: f64) -> Result<(), HardwareError> {
        self.arm_steps = (r * ARM_STEPS_PER_MM).round() as i64;
        Ok(())
    }

    fn turn_bed(&mut self, theta: f64) -> Result<(), HardwareError> {
        self.bed_steps = (theta / TAU * BED_STEPS_PER_REV).round() as i64;
        Ok(())
    }

    fn read_sensor(&mut self) -> Result<f64, HardwareError> {
        Ok(self.field() + self.noise.sample(&mut self.rng))
    }

    fn position(&self) -> (f64, f64) {
        (self.arm(), self.bed())
    }
}

/// The scan at the working height (the sensor 3 mm above the magnets' top faces: 5.5 mm from their centres) and
/// again with the nozzle raised `raise` mm.
fn two_scans(
    seed: u64,
    offset: [f64; 2],
    tilt: f64,
    towards: f64,
    raise: f64,
) -> (CentreResult, CentreResult) {
    let params = ScanParams::default();
    let mut low = DipoleBed::new(seed, offset, tilt, towards, 5.5);
    let lower = scan_centre(&mut low, &params).expect("the lower scan");
    let mut high = DipoleBed::new(seed, offset, tilt, towards, 5.5 + raise);
    let upper = scan_centre(&mut high, &params).expect("the raised scan");
    (lower, upper)
}

fn miss(d: [f64; 2], truth: [f64; 2]) -> f64 {
    (d[0] - truth[0]).hypot(d[1] - truth[1])
}

/// 2° of tilt in eight directions, random offsets up to 2 mm: one scan is biased by the dipole's h·tan α / 4
/// (0.048 mm at 5.5 mm), the tilt removed from two scans 1.5 mm apart leaves at most 0.02 mm, and the tilt found
/// is the one built in.
#[test]
fn a_two_degree_tilt_is_removed_by_a_second_scan_higher_up() {
    let mut rng = StdRng::seed_from_u64(27);
    let (mut worst_one, mut worst_two, mut worst_tilt) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..8u32 {
        let offset = [rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0)];
        let towards = 45.0 * f64::from(k);
        let (low, high) = two_scans(k.into(), offset, 2.0, towards, 1.5);
        let one = miss([low.arm_zero_offset, low.arm_lateral_offset], offset);
        let fixed = remove_tilt(&low, &high, 1.5).expect("tilt removed");
        let two = miss([fixed.arm_zero_offset, fixed.arm_lateral_offset], offset);
        println!(
            "tilt towards {towards:>3}°: one scan off by {one:.4} mm, two scans {two:.4} mm (σ {:.4}, {:.4}); \
             distance {:.2} mm, tilt {:.2}°",
            fixed.sigma_scan[0], fixed.sigma_scan[1], fixed.distance, fixed.tilt_deg
        );
        assert!(one > 0.035, "the tilt should bias one scan: {one}");
        (worst_one, worst_two) = (worst_one.max(one), worst_two.max(two));
        worst_tilt = worst_tilt.max((fixed.tilt_deg - 2.0).abs());
        assert!((fixed.distance - 5.5).abs() < 0.5, "{}", fixed.distance);
    }
    println!(
        "worst: one scan {worst_one:.4} mm, two scans {worst_two:.4} mm, tilt off by {worst_tilt:.2}°"
    );
    assert!(worst_two <= 0.02, "{worst_two}");
    assert!(worst_tilt < 0.5, "{worst_tilt}");
}

/// An upright sensor: the second scan changes nothing beyond its noise.
#[test]
fn an_upright_sensor_keeps_its_offsets() {
    let truth = [0.7, -1.2];
    let (low, high) = two_scans(3, truth, 0.0, 0.0, 1.5);
    let fixed = remove_tilt(&low, &high, 1.5).expect("tilt removed");
    let two = miss([fixed.arm_zero_offset, fixed.arm_lateral_offset], truth);
    assert!(
        two <= 0.01 && fixed.tilt_deg < 0.3,
        "{two} mm, {}°",
        fixed.tilt_deg
    );
}

/// Scans given the wrong way round (the raised one first) or a raise that is not a length are refused.
#[test]
fn scans_in_the_wrong_order_are_refused() {
    let (low, high) = two_scans(4, [0.5, 0.5], 2.0, 90.0, 1.5);
    let err = remove_tilt(&high, &low, 1.5)
        .expect_err("refused")
        .to_string();
    assert!(err.contains("not weaker"), "{err}");
    assert!(remove_tilt(&low, &high, 0.0).is_err());
    assert!(remove_tilt(&low, &high, f64::NAN).is_err());
}
