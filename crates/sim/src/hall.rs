//! Simulated polar printer for the centre scan: a bed with magnets (placement errors), the true arm zero and
//! lateral offsets, a KY-024 Hall sensor (49E linear IC, 10-bit ADC, noise, saturation) and step-quantised
//! arm and bed motors. Implements `calibrate::scan::ScanHardware`; deterministic for a given seed.
//!
//! Field model: each magnet is an axially magnetised cylinder. On its axis the exact formula
//! `Bz = (Br/2)[(z+L)/√(R²+(z+L)²) − z/√(R²+z²)]` is used; off axis that value is multiplied by the
//! dipole's radial profile `(2h²−ρ²)/(h²+ρ²)^{5/2} / (2/h³)` with `h` measured from the magnet's centre.
//! The result is exact on the axis and has the dipole's shape off it (within ~2% beyond 3 mm; the shape is
//! symmetric about the magnet axis, which is what the peaking relies on). Fields of all magnets add.

use calibrate::circle::Point;
use calibrate::scan::{HardwareError, ScanHardware};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::f64::consts::TAU;

/// An axially magnetised cylindrical magnet (mm, T).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagnetSpec {
    pub diameter: f64,
    pub length: f64,
    /// Remanence Br (T).
    pub remanence: f64,
}

impl Default for MagnetSpec {
    /// Ø3×5 mm, Br 1.2 T (N35–N42), as on the thesis' bed.
    fn default() -> Self {
        Self {
            diameter: 3.0,
            length: 5.0,
            remanence: 1.2,
        }
    }
}

impl MagnetSpec {
    /// Exact on-axis field at distance `z` (mm) from the magnet's face (T).
    pub fn on_axis(&self, z: f64) -> f64 {
        let r = 0.5 * self.diameter;
        let l = self.length;
        0.5 * self.remanence
            * ((z + l) / (r * r + (z + l).powi(2)).sqrt() - z / (r * r + z * z).sqrt())
    }

    /// Field along the axis direction at horizontal distance `rho` from the axis, `z` above the face (T).
    pub fn bz(&self, rho: f64, z: f64) -> f64 {
        let h = z + 0.5 * self.length;
        let h2 = h * h;
        let rho2 = rho * rho;
        let shape = (2.0 * h2 - rho2) / (h2 + rho2).powf(2.5) * h * h2 / 2.0;
        self.on_axis(z) * shape
    }
}

/// KY-024 board: 49E-class linear Hall IC read by an ADC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ky024 {
    /// Supply (V); the output rests at `vcc/2`.
    pub vcc: f64,
    /// Sensitivity (V/T); 1.6 mV/G = 16 V/T.
    pub sensitivity: f64,
    /// Field where the output saturates (T).
    pub saturation: f64,
    /// Gaussian noise on the field (T, 1σ).
    pub noise: f64,
    pub adc_bits: u32,
    /// ADC reference (V).
    pub vref: f64,
}

impl Default for Ky024 {
    /// 5 V, 1.6 mV/G, ±100 mT, 0.15 mT noise, 10-bit ADC at 5 V (one code ≈ 0.3 mT).
    fn default() -> Self {
        Self {
            vcc: 5.0,
            sensitivity: 16.0,
            saturation: 0.1,
            noise: 0.15e-3,
            adc_bits: 10,
            vref: 5.0,
        }
    }
}

impl Ky024 {
    pub fn max_code(&self) -> f64 {
        f64::from((1u32 << self.adc_bits) - 1)
    }

    /// Field → ADC code (noise added by the caller).
    pub fn code(&self, field: f64) -> u32 {
        let b = field.clamp(-self.saturation, self.saturation);
        let v = (0.5 * self.vcc + self.sensitivity * b).clamp(0.0, self.vref);
        (v / self.vref * self.max_code()).round() as u32
    }

    /// ADC code → field estimate with the nominal calibration (T).
    pub fn field(&self, code: u32) -> f64 {
        (f64::from(code) / self.max_code() * self.vref - 0.5 * self.vcc) / self.sensitivity
    }

    /// Field change of one ADC code (T).
    pub fn adc_step(&self) -> f64 {
        self.vref / self.max_code() / self.sensitivity
    }
}

/// Everything that defines a simulated scan machine.
#[derive(Debug, Clone, PartialEq)]
pub struct HallBedConfig {
    pub magnet_count: usize,
    /// Nominal ring radius (mm).
    pub ring_radius: f64,
    /// 1σ placement error of each magnet, per coordinate (mm).
    pub placement_sigma: f64,
    /// Magnets left out (indices), e.g. one that fell off.
    pub missing: Vec<usize>,
    pub magnet: MagnetSpec,
    /// Sensor above the magnets' top faces (mm).
    pub sensor_height: f64,
    /// Where the sensor really reads relative to the nozzle, along and across the arm (mm): its mounting
    /// offset plus, for a tilt α, `h · tan(α) / 4` (a dipole's peak, `h` from the magnet's centre). A scan measures
    /// the sensor, so this adds to the `dx`, `dy` it finds.
    pub sensor_offset: [f64; 2],
    pub sensor: Ky024,
    /// True `dx` (arm zero along the arm, mm) and `dy` (lateral, mm).
    pub arm_zero_offset: f64,
    pub arm_lateral_offset: f64,
    /// Arm: 200 full steps · 16 microsteps / 40 mm rotation distance = 80 steps/mm.
    pub arm_steps_per_mm: f64,
    /// Bed: 200 · 16 · 80/16 gearing = 16000 steps/rev.
    pub bed_steps_per_rev: f64,
    /// Microsteps per full step (both motors).
    pub microsteps: u32,
    /// Microstep positioning error: amplitude of a sinusoid over the 4-full-step electrical cycle, as a
    /// fraction of one full step (0 = ideal driver; TMC-class drivers are a few percent).
    pub microstep_error: f64,
    pub arm_min: f64,
    pub arm_max: f64,
    pub seed: u64,
}

impl Default for HallBedConfig {
    fn default() -> Self {
        Self {
            magnet_count: 16,
            ring_radius: 100.0,
            placement_sigma: 0.1,
            missing: Vec::new(),
            magnet: MagnetSpec::default(),
            sensor_height: 3.0,
            sensor_offset: [0.0, 0.0],
            sensor: Ky024::default(),
            arm_zero_offset: 0.0,
            arm_lateral_offset: 0.0,
            arm_steps_per_mm: 80.0,
            bed_steps_per_rev: 16000.0,
            microsteps: 16,
            microstep_error: 0.0,
            arm_min: -115.0,
            arm_max: 120.0,
            seed: 1,
        }
    }
}

impl HallBedConfig {
    /// A random machine: offsets uniform in ±`max_offset` (mm) each, the rest as given.
    pub fn random_offsets(self, max_offset: f64, seed: u64) -> Self {
        let mut rng = StdRng::seed_from_u64(seed ^ 0x005E_ED0F_F5E7_u64);
        Self {
            arm_zero_offset: rng.random_range(-max_offset..=max_offset),
            arm_lateral_offset: rng.random_range(-max_offset..=max_offset),
            seed,
            ..self
        }
    }
}

/// The simulated machine; positions are kept as whole steps.
#[derive(Debug, Clone)]
pub struct HallScanner {
    cfg: HallBedConfig,
    magnets: Vec<Point>,
    rng: StdRng,
    noise: Normal<f64>,
    arm_steps: i64,
    bed_steps: i64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    #[error("invalid simulation parameter: {0}")]
    InvalidParams(String),
}

impl HallScanner {
    pub fn new(cfg: HallBedConfig) -> Result<Self, SimError> {
        let bad = |m: &str| SimError::InvalidParams(m.to_string());
        if !(cfg.placement_sigma >= 0.0 && cfg.sensor.noise >= 0.0) {
            return Err(bad("placement_sigma and sensor noise must be ≥ 0"));
        }
        if !(cfg.arm_steps_per_mm > 0.0 && cfg.bed_steps_per_rev > 0.0 && cfg.sensor_height > 0.0) {
            return Err(bad("step resolutions and sensor height must be > 0"));
        }
        if cfg.microsteps == 0 || !(cfg.microstep_error.is_finite() && cfg.microstep_error >= 0.0) {
            return Err(bad("microsteps must be ≥ 1 and microstep_error ≥ 0"));
        }
        let mut rng = StdRng::seed_from_u64(cfg.seed);
        let place = Normal::new(0.0, cfg.placement_sigma).map_err(|e| bad(&e.to_string()))?;
        let noise = Normal::new(0.0, cfg.sensor.noise).map_err(|e| bad(&e.to_string()))?;
        let n = cfg.magnet_count;
        let mut magnets = Vec::with_capacity(n);
        for k in 0..n {
            let a = k as f64 * TAU / n as f64;
            let p = [
                cfg.ring_radius * a.cos() + place.sample(&mut rng),
                cfg.ring_radius * a.sin() + place.sample(&mut rng),
            ];
            if !cfg.missing.contains(&k) {
                magnets.push(p);
            }
        }
        let arm_steps = (cfg.arm_max * cfg.arm_steps_per_mm).floor() as i64;
        Ok(Self {
            cfg,
            magnets,
            rng,
            noise,
            arm_steps,
            bed_steps: 0,
        })
    }

    /// True magnet positions in the bed frame (mm).
    pub fn magnets(&self) -> &[Point] {
        &self.magnets
    }

    pub fn config(&self) -> &HallBedConfig {
        &self.cfg
    }

    fn arm(&self) -> f64 {
        self.arm_steps as f64 / self.cfg.arm_steps_per_mm
    }

    fn bed(&self) -> f64 {
        self.bed_steps as f64 * TAU / self.cfg.bed_steps_per_rev
    }

    /// Positioning error of a motor at `steps` microsteps, in units of one microstep.
    fn microstep_error(&self, steps: i64) -> f64 {
        let per_cycle = 4.0 * f64::from(self.cfg.microsteps);
        let phase = (steps as f64).rem_euclid(per_cycle) / per_cycle * TAU;
        self.cfg.microstep_error * f64::from(self.cfg.microsteps) * phase.sin()
    }

    /// Where the arm really is (mm from its zero), including the driver's microstep error.
    fn true_arm(&self) -> f64 {
        (self.arm_steps as f64 + self.microstep_error(self.arm_steps)) / self.cfg.arm_steps_per_mm
    }

    /// Where the bed really is (rad from its declared zero), including the microstep error.
    fn true_bed(&self) -> f64 {
        (self.bed_steps as f64 + self.microstep_error(self.bed_steps)) * TAU
            / self.cfg.bed_steps_per_rev
    }

    /// Noise-free field at the sensor for the current motor positions (T).
    pub fn true_field(&self) -> f64 {
        let sensor = [
            self.true_arm() + self.cfg.arm_zero_offset + self.cfg.sensor_offset[0],
            self.cfg.arm_lateral_offset + self.cfg.sensor_offset[1],
        ];
        // The bed reading θ has the kinematics' sign: bed point p is under machine point Rot(−θ)·p.
        let (s, c) = (-self.true_bed()).sin_cos();
        self.magnets
            .iter()
            .map(|m| {
                let world = [c * m[0] - s * m[1], s * m[0] + c * m[1]];
                let rho = (world[0] - sensor[0]).hypot(world[1] - sensor[1]);
                self.cfg.magnet.bz(rho, self.cfg.sensor_height)
            })
            .sum()
    }
}

/// How the simulated printer runs a continuous sweep (`calibrate::sweep`): each pass turns the bed from
/// `-overlap` to `TAU + overlap` (alternating direction) with a trapezoidal speed profile while the ADC reports
/// every `sample_time`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepMotion {
    /// Bed speed (rad/s) and acceleration (rad/s²).
    pub bed_speed: f64,
    pub bed_accel: f64,
    /// Extra turn at both ends of a pass (rad), for the speed ramps.
    pub overlap: f64,
    /// Time between ADC reports (s).
    pub sample_time: f64,
}

impl HallScanner {
    /// The ADC code of one noisy reading.
    fn noisy_code(&mut self) -> u32 {
        let b = self.true_field() + self.noise.sample(&mut self.rng);
        self.cfg.sensor.code(b)
    }

    /// One ADC report as Klipper hands it on: the code as a fraction of full scale.
    pub fn read_adc(&mut self) -> f64 {
        f64::from(self.noisy_code()) / self.cfg.sensor.max_code()
    }

    /// Runs a sweep pass by pass: the ADC reports at a steady rate from the start (one clock for the whole
    /// sweep), and each report carries the motors' step-quantised readings at its time, as a printer's stepper
    /// position history gives them.
    pub fn sweep(
        &mut self,
        arms: &[f64],
        motion: SweepMotion,
    ) -> Result<Vec<calibrate::sweep::SweepSample>, HardwareError> {
        let turn = TAU + 2.0 * motion.overlap;
        let duration = calibrate::scan::trapezoid_time(turn, motion.bed_speed, motion.bed_accel);
        let mut samples = Vec::new();
        let mut clock = 0.0;
        for (pass, &arm) in arms.iter().enumerate() {
            self.move_arm(arm)?;
            let (from, sign) = if pass % 2 == 0 {
                (-motion.overlap, 1.0)
            } else {
                (TAU + motion.overlap, -1.0)
            };
            let start = clock;
            let mut k = (start / motion.sample_time).ceil();
            while k * motion.sample_time <= start + duration {
                let t = k * motion.sample_time - start;
                let travelled = trapezoid_position(t, turn, motion.bed_speed, motion.bed_accel);
                self.turn_bed(from + sign * travelled)?;
                let (arm, bed) = self.position();
                let adc = self.read_adc();
                samples.push(calibrate::sweep::SweepSample {
                    pass,
                    arm,
                    bed,
                    adc,
                });
                k += 1.0;
            }
            // The arm's move to the next pass takes some time too.
            clock = start + duration + 0.5;
        }
        Ok(samples)
    }
}

/// Distance travelled at time `t` of a rest-to-rest trapezoidal move of length `d`.
fn trapezoid_position(t: f64, d: f64, v: f64, a: f64) -> f64 {
    let v = v.min((d * a).sqrt());
    let ramp = v / a;
    let total = calibrate::scan::trapezoid_time(d, v, a);
    if t <= ramp {
        0.5 * a * t * t
    } else if t >= total - ramp {
        let left = (total - t).max(0.0);
        d - 0.5 * a * left * left
    } else {
        0.5 * a * ramp * ramp + v * (t - ramp)
    }
}

impl ScanHardware for HallScanner {
    fn move_arm(&mut self, r: f64) -> Result<(), HardwareError> {
        if !r.is_finite() || r < self.cfg.arm_min || r > self.cfg.arm_max {
            return Err(HardwareError(format!(
                "arm target {r} mm outside [{}, {}]",
                self.cfg.arm_min, self.cfg.arm_max
            )));
        }
        self.arm_steps = (r * self.cfg.arm_steps_per_mm).round() as i64;
        Ok(())
    }

    fn turn_bed(&mut self, theta: f64) -> Result<(), HardwareError> {
        if !theta.is_finite() {
            return Err(HardwareError(format!("bed target {theta} is not finite")));
        }
        self.bed_steps = (theta / TAU * self.cfg.bed_steps_per_rev).round() as i64;
        Ok(())
    }

    fn read_sensor(&mut self) -> Result<f64, HardwareError> {
        let code = self.noisy_code();
        Ok(self.cfg.sensor.field(code))
    }

    fn position(&self) -> (f64, f64) {
        (self.arm(), self.bed())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_axis_field_matches_reference_numbers() {
        // REFERENCE.md §4: Ø5×5 mm, Br 1.2 T: 112 mT at 3 mm, 45 mT at 5 mm.
        let m = MagnetSpec {
            diameter: 5.0,
            length: 5.0,
            remanence: 1.2,
        };
        assert!((m.on_axis(3.0) - 0.112).abs() < 0.001);
        assert!((m.on_axis(5.0) - 0.045).abs() < 0.001);
        assert_eq!(m.bz(0.0, 3.0), m.on_axis(3.0));
    }

    #[test]
    fn off_axis_shape_follows_the_dipole() {
        let m = MagnetSpec::default();
        let z = 3.0;
        let h = z + 2.5;
        // Sign change at ρ = √2·h; field falls monotonically before it.
        assert!(m.bz(2f64.sqrt() * h, z).abs() < 1e-12);
        assert!(m.bz(1.0, z) < m.bz(0.0, z) && m.bz(2.0, z) < m.bz(1.0, z));
        // Half maximum near ρ ≈ 0.5·h.
        let half = m.bz(0.5 * h, z) / m.bz(0.0, z);
        assert!((half - 0.5).abs() < 0.1, "{half}");
    }

    #[test]
    fn ky024_adc_step_is_about_0_3_mt() {
        let s = Ky024::default();
        assert!((s.adc_step() - 0.000_305).abs() < 0.000_01);
        assert_eq!(s.code(0.5), s.code(0.1));
        assert!((s.field(s.code(0.05)) - 0.05).abs() <= s.adc_step());
    }

    #[test]
    fn motors_quantise_to_steps() {
        let mut m = HallScanner::new(HallBedConfig::default()).expect("sim");
        m.move_arm(10.004).expect("arm");
        m.turn_bed(0.001).expect("bed");
        let (r, t) = m.position();
        assert!((r - 10.0).abs() < 1e-12);
        assert!((t - 3.0 * TAU / 16000.0).abs() < 1e-12);
        assert!(m.move_arm(500.0).is_err());
    }

    #[test]
    fn microstep_error_follows_the_electrical_cycle() {
        let cfg = HallBedConfig {
            microstep_error: 0.05,
            ..HallBedConfig::default()
        };
        let mut m = HallScanner::new(cfg).expect("sim");
        // A quarter electrical cycle (one full step = 16 microsteps = 0.2 mm): error peaks at 5% of 0.2 mm.
        m.move_arm(0.2).expect("arm");
        assert!((m.true_arm() - 0.21).abs() < 1e-12);
        m.move_arm(0.4).expect("arm");
        assert!((m.true_arm() - 0.4).abs() < 1e-12);
        assert_eq!(m.position().0, 0.4);
    }
}
