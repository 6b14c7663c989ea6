//! What each motor does along a planned move (its position, and its peak speed and acceleration from the
//! kinematics' Jacobian along the move's speed profile), and which limit holds the move below its requested speed.

use std::sync::Arc;

use kinematics::Kinematics;
use motion::kinematic_limits::MotorLimit;
use serde::Serialize;
use trapq::{Motion, TrapezoidMove};

/// Points along a move at which the motors' rates are read (the ends included).
const SAMPLES: usize = 9;
/// A move at this share of its requested speed or more runs at its speed.
const AT_SPEED: f64 = 0.97;
/// A motor at this share of its limit or more is the limit that holds the move.
const AT_LIMIT: f64 = 0.9;

/// Why a move runs at the speed it does: an index into [`Limits::labels`].
pub type Cause = u8;
/// At its requested speed (the feed, or the machine's `max_velocity`).
pub const AT_REQUESTED: Cause = 0;
/// Held by the machine's acceleration and corners (`max_accel`, `square_corner_velocity`): too short or too bent
/// to reach its speed.
pub const ACCELERATION: Cause = 1;
/// Held by another machine limit: Z speed, extrusion.
pub const OTHER: Cause = 2;
/// A polar bed turning in place on its centre.
pub const BED_TURN: Cause = 3;
/// Refused by the machine (not planned).
pub const REFUSED: Cause = 4;
/// The first motor limit's code: limit `i` of [`Limits::motor_limits`] is `FIRST_MOTOR + 2i` (its speed, or its step
/// rate when that is what caps the speed) and `FIRST_MOTOR + 2i + 1` (its acceleration).
pub const FIRST_MOTOR: Cause = 5;

/// The machine's motor limits as the page shows them.
#[derive(Debug, Clone, Serialize)]
pub struct MotorLimitView {
    pub motor: String,
    /// Index in the machine's motor order.
    pub index: usize,
    /// `mm` or `rad`.
    pub unit: &'static str,
    pub max_velocity: Option<f64>,
    pub max_accel: Option<f64>,
    /// The velocity limit is the motor's `max_step_rate` (times its step distance).
    pub step_rate: bool,
}

/// The causes' names, and the motors' limits they refer to.
#[derive(Debug, Clone, Serialize)]
pub struct Limits {
    pub labels: Vec<String>,
    pub motor_limits: Vec<MotorLimitView>,
}

impl Limits {
    /// The labels of the fixed causes and of each configured motor limit (`step_rates`: each motor's
    /// `max_step_rate` as a speed, where it has one).
    pub fn new(kin: &dyn Kinematics, limits: &[MotorLimit], step_rates: &[Option<f64>]) -> Limits {
        let mut labels: Vec<String> = [
            "at the requested speed",
            "acceleration and corners",
            "Z or extrusion limits",
            "bed turning on its centre",
            "refused by the machine",
        ]
        .map(String::from)
        .to_vec();
        let mut motor_limits = Vec::new();
        for l in limits {
            let motor = &kin.motors()[l.motor];
            let step_rate = match (step_rates.get(l.motor).copied().flatten(), l.max_velocity) {
                (Some(rate), Some(v)) => rate <= v,
                _ => false,
            };
            let speed = if step_rate { "step rate" } else { "speed" };
            labels.push(format!("{} {speed}", motor.name));
            labels.push(format!("{} acceleration", motor.name));
            motor_limits.push(MotorLimitView {
                motor: motor.name.clone(),
                index: l.motor,
                unit: match motor.unit {
                    kinematics::MotorUnit::Mm => "mm",
                    kinematics::MotorUnit::Rad => "rad",
                },
                max_velocity: l.max_velocity,
                max_accel: l.max_accel,
                step_rate,
            });
        }
        Limits {
            labels,
            motor_limits,
        }
    }
}

/// What the motors do on one move: the position at its end, each motor's peak speed and acceleration, and the
/// largest rate (motor units per mm) and change of rate (per mm²) along it, from which the planner caps a move.
#[derive(Debug, Clone, PartialEq)]
pub struct MotorPass {
    pub end: Vec<f64>,
    pub speed: Vec<f64>,
    pub accel: Vec<f64>,
    pub rate: Vec<f64>,
    pub curvature: Vec<f64>,
}

/// Follows the motors through the planned moves (angles unwrapped, so a bed's turns add up).
pub struct MotorProbe {
    kin: Arc<dyn Kinematics>,
    limits: Vec<MotorLimit>,
    /// Each motor's position after the last move.
    position: Vec<f64>,
    known: bool,
    rows: Vec<[f64; 3]>,
}

impl std::fmt::Debug for MotorProbe {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MotorProbe")
            .field("machine", &self.kin.name())
            .field("position", &self.position)
            .finish()
    }
}

/// Speed and tangential acceleration `s` mm into a move (its trapezoid profile).
fn profile(mv: &TrapezoidMove, s: f64) -> (f64, f64) {
    let accel_d = (mv.start_v + mv.cruise_v) * 0.5 * mv.accel_t;
    let cruise_d = mv.cruise_v * mv.cruise_t;
    if s < accel_d {
        (
            (mv.start_v * mv.start_v + 2.0 * mv.accel * s)
                .max(0.0)
                .sqrt(),
            mv.accel,
        )
    } else if s <= accel_d + cruise_d || mv.decel_t == 0.0 {
        (mv.cruise_v, 0.0)
    } else {
        let into = s - accel_d - cruise_d;
        let v2 = mv.cruise_v * mv.cruise_v - 2.0 * mv.accel * into;
        (v2.max(0.0).sqrt(), -mv.accel)
    }
}

impl MotorProbe {
    pub fn new(kin: Arc<dyn Kinematics>, limits: Vec<MotorLimit>) -> MotorProbe {
        let count = kin.motors().len();
        MotorProbe {
            kin,
            limits,
            position: vec![0.0; count],
            known: false,
            rows: vec![[0.0; 3]; count],
        }
    }

    /// The machine was declared at `xyz` (homing, a set position).
    pub fn place(&mut self, xyz: [f64; 3]) {
        let previous = self.position.clone();
        self.known = self
            .kin
            .inverse_near(xyz, &previous, &mut self.position)
            .is_ok();
    }

    /// The motors along `mv`.
    pub fn pass(&mut self, mv: &TrapezoidMove) -> MotorPass {
        let count = self.position.len();
        let mut speed = vec![0.0; count];
        let mut accel = vec![0.0; count];
        if mv.motion == Motion::BedTurn {
            if let Some(centre) = self.kin.rotation_centre() {
                self.position[centre.bed] += mv.distance();
                speed[centre.bed] = mv.cruise_v.abs();
                accel[centre.bed] = mv.accel.abs();
            }
            return self.result(speed, accel, Vec::new(), Vec::new());
        }
        let length = mv.distance();
        if !self.known {
            self.place(mv.start_pos);
        }
        let rates = self.rates_along(mv, length);
        let (mut most_rate, mut most_curvature) = (vec![0.0; count], vec![0.0; count]);
        for (k, (rate, curvature)) in rates.iter().enumerate() {
            let s = length * k as f64 / (SAMPLES - 1) as f64;
            let (v, a) = profile(mv, s);
            for m in 0..count {
                speed[m] = f64::max(speed[m], (rate[m] * v).abs());
                accel[m] = f64::max(accel[m], (rate[m] * a + curvature[m] * v * v).abs());
                most_rate[m] = f64::max(most_rate[m], rate[m].abs());
                most_curvature[m] = f64::max(most_curvature[m], curvature[m].abs());
            }
        }
        let previous = self.position.clone();
        let end = mv.end_pos();
        if self
            .kin
            .inverse_near(end, &previous, &mut self.position)
            .is_err()
        {
            // On a polar centre the bed keeps its angle: the arm is at its zero.
            self.known = false;
        }
        self.result(speed, accel, most_rate, most_curvature)
    }

    fn result(
        &self,
        speed: Vec<f64>,
        accel: Vec<f64>,
        rate: Vec<f64>,
        curvature: Vec<f64>,
    ) -> MotorPass {
        MotorPass {
            end: self.position.clone(),
            speed,
            accel,
            rate,
            curvature,
        }
    }

    /// Each motor's rate (motor units per mm along the move) and its change (per mm²) at the sample points; a
    /// point where the kinematics has no Jacobian (a polar centre) takes its neighbour's.
    fn rates_along(&mut self, mv: &TrapezoidMove, length: f64) -> Vec<(Vec<f64>, Vec<f64>)> {
        let count = self.position.len();
        let u = mv.axes_r;
        let mut rates: Vec<Option<Vec<f64>>> = Vec::with_capacity(SAMPLES);
        for k in 0..SAMPLES {
            let s = length * k as f64 / (SAMPLES - 1) as f64;
            let p = [0, 1, 2].map(|i| mv.start_pos[i] + u[i] * s);
            let rate = self.kin.jacobian(p, &mut self.rows).ok().map(|()| {
                self.rows
                    .iter()
                    .map(|r| r[0] * u[0] + r[1] * u[1] + r[2] * u[2])
                    .collect::<Vec<f64>>()
            });
            rates.push(rate.filter(|r| r.iter().all(|v| v.is_finite())));
        }
        let h = length / (SAMPLES - 1) as f64;
        let zero = vec![0.0; count];
        (0..SAMPLES)
            .map(|k| {
                let rate = rates[k].clone().unwrap_or_else(|| zero.clone());
                let before = k.checked_sub(1).and_then(|i| rates[i].as_ref());
                let after = rates.get(k + 1).and_then(|r| r.as_ref());
                let curvature = match (before, after) {
                    _ if h == 0.0 => zero.clone(),
                    (Some(b), Some(a)) => (0..count).map(|m| (a[m] - b[m]) / (2.0 * h)).collect(),
                    (None, Some(a)) => (0..count).map(|m| (a[m] - rate[m]) / h).collect(),
                    (Some(b), None) => (0..count).map(|m| (rate[m] - b[m]) / h).collect(),
                    (None, None) => zero.clone(),
                };
                (rate, curvature)
            })
            .collect()
    }

    /// Why `mv` (requested at `requested` mm/s) runs at its peak speed, given what its motors do: the lowest of
    /// the requested speed and the caps each motor limit puts on the move by the planner's rule (a speed limit over
    /// the largest rate; half an acceleration limit over the largest change of rate), when the move reaches it.
    pub fn cause(&self, mv: &TrapezoidMove, requested: f64, motors: &MotorPass) -> Cause {
        if mv.motion == Motion::BedTurn {
            return BED_TURN;
        }
        let mut lowest = (requested, AT_REQUESTED);
        for (i, l) in self.limits.iter().enumerate() {
            let code = FIRST_MOTOR + 2 * i as Cause;
            let rate = motors.rate.get(l.motor).copied().unwrap_or(0.0);
            let curvature = motors.curvature.get(l.motor).copied().unwrap_or(0.0);
            if let Some(max_v) = l.max_velocity
                && rate > 0.0
                && max_v / rate < lowest.0
            {
                lowest = (max_v / rate, code);
            }
            if let Some(max_a) = l.max_accel
                && curvature > 0.0
                && (0.5 * max_a / curvature).sqrt() < lowest.0
            {
                lowest = ((0.5 * max_a / curvature).sqrt(), code + 1);
            }
        }
        let reaches = if lowest.1 == AT_REQUESTED {
            AT_SPEED
        } else {
            AT_LIMIT
        };
        if mv.cruise_v >= reaches * lowest.0 {
            return lowest.1;
        }
        if mv.axes_r[2] != 0.0 {
            return OTHER;
        }
        ACCELERATION
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(start_v: f64, cruise_v: f64, accel: f64, times: [f64; 3]) -> TrapezoidMove {
        TrapezoidMove {
            print_time: 0.0,
            accel_t: times[0],
            cruise_t: times[1],
            decel_t: times[2],
            start_pos: [10.0, -20.0, 0.2],
            axes_r: [0.0, 1.0, 0.0],
            start_v,
            cruise_v,
            accel,
            motion: Motion::Travel,
        }
    }

    #[test]
    fn the_profile_accelerates_cruises_and_decelerates() {
        let mv = line(0.0, 10.0, 100.0, [0.1, 1.0, 0.1]);
        assert_eq!(profile(&mv, 0.0), (0.0, 100.0));
        assert_eq!(profile(&mv, 5.0), (10.0, 0.0));
        let (v, a) = profile(&mv, mv.distance());
        assert!(v.abs() < 1e-6 && a == -100.0, "{v} {a}");
    }

    #[test]
    fn a_polar_bed_near_the_centre_is_the_limit_that_holds_a_line() {
        let params = kinematics::MachineParams::Polar(kinematics::PolarParams::klipper_example());
        let kin: Arc<dyn Kinematics> = kinematics::build(&params).expect("machine").into();
        let bed = kin.rotation_centre().expect("a centre").bed;
        let limit = MotorLimit {
            motor: bed,
            max_velocity: Some(5.0),
            max_accel: None,
        };
        let mut probe = MotorProbe::new(Arc::clone(&kin), vec![limit]);
        // 40 mm along y, 10 mm beside the centre, at 50 mm/s: the bed turns at 5 rad/s where the line is nearest.
        let mv = line(50.0, 50.0, 1000.0, [0.0, 0.8, 0.0]);
        let pass = probe.pass(&mv);
        assert!((pass.speed[bed] - 5.0).abs() < 1e-6, "{:?}", pass.speed);
        assert_eq!(probe.cause(&mv, 200.0, &pass), FIRST_MOTOR);
        assert_eq!(probe.cause(&mv, 50.0, &pass), AT_REQUESTED);
        // The same line 60 mm away: the bed is far below its limit, so the corners held it.
        let mut far = mv;
        far.start_pos = [60.0, -20.0, 0.2];
        let pass = probe.pass(&far);
        assert_eq!(probe.cause(&far, 200.0, &pass), ACCELERATION);
    }
}
