//! The SCARA's and the five-bar's calibration pattern as a user gets it: the pattern `calibrate scara-pattern` or
//! `calibrate fivebar-pattern` writes for the believed machine (`calibrate::scara::machine_pattern`,
//! `calibrate::fivebar::machine_pattern`, the one pattern maker of each), printed by the machine as built (its step
//! streams replayed on the true geometry and motor model), each cross centre measured where its two printed strokes
//! cross, with the measuring method's noise and reading resolution.

use crate::error::SimulationError;
use crate::machine::Machine;
use crate::metrics::PathPoint;
use crate::replay::ReplayOptions;
use crate::simulation::simulate;
use calibrate::scara::{Measurement, Pattern, PatternOptions, machine_pattern};
use config::MachineConfig;
use kinematics::fivebar::Fivebar;
use kinematics::scara::Scara;
use rand::Rng;
use rand_distr::{Distribution, Normal};

/// How the simulated user measures the printed crosses: calipers from two bed edges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measuring {
    /// Noise of one reading (mm, 1σ per coordinate).
    pub noise: f64,
    /// What the instrument reads to (mm): each coordinate is rounded to it.
    pub resolution: f64,
}

/// Calipers: the measuring method `calibrate scara` assumes by default (0.02 mm), read to 0.01 mm.
pub const CALIPERS: Measuring = Measuring {
    noise: 0.02,
    resolution: 0.01,
};

/// The crosses as measured, with the pattern they come from.
#[derive(Debug, Clone)]
pub struct MeasuredPattern {
    pub pattern: Pattern,
    pub data: Vec<Measurement>,
}

/// Print the default pattern of the believed machine on `actual` and measure its crosses.
pub fn print_and_measure(
    believed: &MachineConfig,
    actual: &Machine,
    measuring: Measuring,
    rng: &mut impl Rng,
) -> Result<MeasuredPattern, SimulationError> {
    let (machine, options) = believed_machine(believed)?;
    let scara = Scara::of(machine.setup.kinematics.as_ref()).ok_or_else(|| {
        SimulationError::Calibration("the believed machine is not a SCARA".into())
    })?;
    let pattern =
        machine_pattern(scara, calibrate::scara::DEFAULT_POSES, &options).map_err(pattern_error)?;
    let printed = Printed::of(&pattern.gcode, &pattern.poses, &pattern.centres, &options);
    let data = measure_printed(believed, actual, &printed, measuring, rng)?;
    Ok(MeasuredPattern { pattern, data })
}

/// A pattern to print: its G-code, each cross's motor readings and centre as written, the crosses' half size.
#[derive(Debug, Clone, Copy)]
pub struct Printed<'a> {
    pub gcode: &'a str,
    pub poses: &'a [(f64, f64)],
    pub centres: &'a [[f64; 2]],
    pub half: f64,
}

impl<'a> Printed<'a> {
    fn of(
        gcode: &'a str,
        poses: &'a [(f64, f64)],
        centres: &'a [[f64; 2]],
        options: &PatternOptions,
    ) -> Self {
        Printed {
            gcode,
            poses,
            centres,
            half: options.cross_size / 2.0,
        }
    }
}

/// The believed machine, built as every front-end builds it, and the default pattern options from where its `G28`
/// leaves the nozzle.
fn believed_machine(
    believed: &MachineConfig,
) -> Result<(::machine::Machine, PatternOptions), SimulationError> {
    let machine = ::machine::Machine::from_config(believed.clone(), "believed machine")?;
    let options = PatternOptions {
        home: machine.setup.home_position,
        ..PatternOptions::default()
    };
    Ok((machine, options))
}

fn pattern_error(e: impl std::fmt::Display) -> SimulationError {
    SimulationError::Calibration(format!("calibration pattern: {e}"))
}

/// The five-bar's default pattern of the believed machine printed on `actual`, its crosses measured: the pattern
/// and the measurements.
pub fn print_and_measure_fivebar(
    believed: &MachineConfig,
    actual: &Machine,
    measuring: Measuring,
    rng: &mut impl Rng,
) -> Result<(calibrate::fivebar::Pattern, Vec<Measurement>), SimulationError> {
    let (machine, options) = believed_machine(believed)?;
    let kin = Fivebar::of(machine.setup.kinematics.as_ref()).ok_or_else(|| {
        SimulationError::Calibration("the believed machine is not a five-bar".into())
    })?;
    let pattern =
        calibrate::fivebar::machine_pattern(kin, calibrate::fivebar::DEFAULT_POSES, &options)
            .map_err(pattern_error)?;
    let printed = Printed::of(&pattern.gcode, &pattern.poses, &pattern.centres, &options);
    let data = measure_printed(believed, actual, &printed, measuring, rng)?;
    Ok((pattern, data))
}

/// Print `printed` planned for the believed machine on `actual` and measure each cross where its strokes cross.
pub fn measure_printed(
    believed: &MachineConfig,
    actual: &Machine,
    printed: &Printed,
    measuring: Measuring,
    rng: &mut impl Rng,
) -> Result<Vec<Measurement>, SimulationError> {
    let run = simulate(
        believed,
        actual,
        printed.gcode.as_bytes(),
        "calibration-pattern.gcode",
        &ReplayOptions::default(),
    )?;
    let noise = Normal::new(0.0, measuring.noise)
        .map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let mut read = |v: f64| round_to(v + noise.sample(rng), measuring.resolution);
    let mut data = Vec::with_capacity(printed.poses.len());
    for (i, (&(a, b), &c)) in printed.poses.iter().zip(printed.centres).enumerate() {
        let at = printed_centre(&run.replay.path, c, printed.half).ok_or_else(|| {
            SimulationError::Calibration(format!(
                "cross {} at X{:.3} Y{:.3} was not printed whole",
                i + 1,
                c[0],
                c[1]
            ))
        })?;
        data.push(Measurement {
            motor_a: a,
            motor_b: b,
            x: read(at[0]),
            y: read(at[1]),
            line: i + 1,
        });
    }
    Ok(data)
}

fn round_to(v: f64, step: f64) -> f64 {
    if step > 0.0 {
        (v / step).round() * step
    } else {
        v
    }
}

/// Where the printed strokes of the cross at `centre` (arms `half` long each way, along X and along Y as
/// written) cross: a straight line through each stroke's deposited points as printed, intersected.
pub fn printed_centre(path: &[PathPoint], centre: [f64; 2], half: f64) -> Option<[f64; 2]> {
    let on = |along: usize| {
        let across = 1 - along;
        path.iter()
            .filter(|p| p.deposited)
            .filter(|p| (p.intended[across] - centre[across]).abs() < 1e-3)
            .filter(|p| (p.intended[along] - centre[along]).abs() <= half + 1e-3)
            .map(|p| [p.actual[0], p.actual[1]])
            .collect::<Vec<_>>()
    };
    let x_stroke = line_through(&on(0))?;
    let y_stroke = line_through(&on(1))?;
    intersect(x_stroke, y_stroke)
}

/// The least-squares line through `points` (a point on it and its unit direction), if they span a length.
fn line_through(points: &[[f64; 2]]) -> Option<([f64; 2], [f64; 2])> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let m = [
        points.iter().map(|p| p[0]).sum::<f64>() / n,
        points.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - m[0], p[1] - m[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    // The principal axis of the scatter.
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    (sxx + syy > 1.0).then_some((m, [angle.cos(), angle.sin()]))
}

fn intersect(a: ([f64; 2], [f64; 2]), b: ([f64; 2], [f64; 2])) -> Option<[f64; 2]> {
    let ((p, u), (q, v)) = (a, b);
    let det = u[0] * v[1] - u[1] * v[0];
    if det.abs() < 1e-6 {
        return None;
    }
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    let t = (dx * v[1] - dy * v[0]) / det;
    Some([p[0] + t * u[0], p[1] + t * u[1]])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(intended: [f64; 2], actual: [f64; 2]) -> PathPoint {
        PathPoint {
            time: 0.0,
            intended: [intended[0], intended[1], 0.3],
            actual: [actual[0], actual[1], 0.3],
            deviation: 0.0,
            deposited: true,
            layer: 0,
        }
    }

    /// A cross printed shifted by (0.3, −0.2) and turned by 1°: its centre is where the shifted, turned strokes
    /// cross, computed here from the rigid motion itself.
    #[test]
    fn a_moved_cross_is_found_where_it_was_printed() {
        let (c, turn, shift) = ([40.0, 120.0], 1f64.to_radians(), [0.3, -0.2]);
        let moved = |p: [f64; 2]| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            [
                c[0] + dx * turn.cos() - dy * turn.sin() + shift[0],
                c[1] + dx * turn.sin() + dy * turn.cos() + shift[1],
            ]
        };
        let mut path = Vec::new();
        for k in 0..=60 {
            let s = -3.0 + 0.1 * f64::from(k);
            for p in [[c[0] + s, c[1]], [c[0], c[1] + s]] {
                path.push(point(p, moved(p)));
            }
        }
        let found = printed_centre(&path, c, 3.0).expect("a centre");
        let want = [c[0] + shift[0], c[1] + shift[1]];
        assert!(
            (found[0] - want[0]).hypot(found[1] - want[1]) < 1e-9,
            "{found:?}"
        );
        assert!(printed_centre(&path, [0.0, 0.0], 3.0).is_none());
    }

    #[test]
    fn readings_round_to_the_resolution() {
        assert!((round_to(1.234_56, 0.01) - 1.23).abs() < 1e-12);
        assert_eq!(round_to(1.5, 0.0), 1.5);
    }
}
