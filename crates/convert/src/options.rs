//! Conversion options: output axes, tolerance, units, feed convention, extrusion mode, decimals.

use kinematics::MotorUnit;

/// Largest radius (mm) assumed when bounding how far rounding a written angle moves the nozzle.
const MAX_RADIUS_FOR_ROUNDING: f64 = 1000.0;

/// Which motor axes the output G-code drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Target {
    /// Polar firmware: radius (the `stepper_arm` motor, mm) and bed angle (the `stepper_bed` motor), Z, E.
    #[default]
    Cylindrical,
    /// Raw motor positions: the machine's first two non-Z motors in its own order (SCARA: motor a, motor b;
    /// polar: bed, arm), Z, E.
    Joints,
}

/// Unit in which rotary axes are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AngleUnit {
    #[default]
    Degrees,
    Radians,
}

/// How the output's `F` words make each segment take its time: its Cartesian time, or longer where a motor speed
/// limit needs it ([`ConvertOptions::motor_limits`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FeedMode {
    /// `F` in output-axis units per minute: `F = motor-space length of the segment / segment time`, where the
    /// motor-space length is `√(Δa² + Δb² + Δz²)` in written units (an angle in degrees or radians counts as
    /// that many mm). Extrude-only moves keep the requested E speed. For firmware that interprets F in its
    /// own axis units (Marlin POLAR/SCARA with segmentation off, RRF with feed in joint units).
    #[default]
    MotorSpace,
    /// Inverse time: a `G93` before the first move, then every motion line has `F = 1 / minutes` for that
    /// segment, and `G94` restores units-per-minute at the end.
    InverseTime,
}

/// How the output writes E.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Extrusion {
    /// `M83`: each line carries the E delta of its segment.
    #[default]
    Relative,
    /// `M82`: each line carries the absolute E; input `G92 E` resets are written through.
    Absolute,
}

/// The firmware that reads the output: how its mode lines act (verification replays the output this way).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Firmware {
    /// Marlin: `G90`/`G91` set every axis, E included; `M82`/`M83` set E alone.
    #[default]
    Marlin,
    /// RepRapFirmware: `G90`/`G91` set X Y Z only; `M82`/`M83` set E.
    Rrf,
    /// Klipper: E is relative while `G91` or `M83` is in force (`G90` gives E back its `M82`/`M83` mode).
    Klipper,
}

impl Firmware {
    pub fn name(self) -> &'static str {
        match self {
            Firmware::Marlin => "Marlin",
            Firmware::Rrf => "RepRapFirmware",
            Firmware::Klipper => "Klipper",
        }
    }
}

/// The positioning and extrusion modes of a firmware reading G-code line by line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeState {
    firmware: Firmware,
    /// `G91` in force (X Y Z relative).
    relative_axes: bool,
    /// The E flag: Marlin's and RRF's E mode; Klipper's `M83` (E is then also relative under `G91`).
    relative_e_flag: bool,
}

impl ModeState {
    /// Power-on state: everything absolute.
    pub fn new(firmware: Firmware) -> Self {
        ModeState {
            firmware,
            relative_axes: false,
            relative_e_flag: false,
        }
    }

    /// Applies `G90` (`relative` false) or `G91`.
    pub fn axes_mode(&mut self, relative: bool) {
        self.relative_axes = relative;
        if self.firmware == Firmware::Marlin {
            self.relative_e_flag = relative;
        }
    }

    /// Applies `M82` (`relative` false) or `M83`.
    pub fn extrusion_mode(&mut self, relative: bool) {
        self.relative_e_flag = relative;
    }

    pub fn relative_axes(&self) -> bool {
        self.relative_axes
    }

    pub fn relative_e(&self) -> bool {
        match self.firmware {
            Firmware::Klipper => self.relative_axes || self.relative_e_flag,
            Firmware::Marlin | Firmware::Rrf => self.relative_e_flag,
        }
    }
}

/// How a move is cut into segments that are straight in motor space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Segmentation {
    /// Bounded Cartesian chord error: the nozzle stays within `tolerance` mm of the intended path when the
    /// firmware interpolates linearly in motor space between written points.
    Adaptive { tolerance: f64 },
    /// Firmware-style fixed rule (for comparison): `n = round(time · segments_per_second)`, at most
    /// `length / min_length`, at least 1 (Marlin: 200/s or 180/s polar, 0.5 mm; RRF: 100/s, 0.2 mm).
    Fixed {
        segments_per_second: f64,
        min_length: f64,
    },
}

impl Segmentation {
    pub const DEFAULT_TOLERANCE: f64 = 0.005;
    pub const MARLIN: Segmentation = Segmentation::Fixed {
        segments_per_second: 200.0,
        min_length: 0.5,
    };
    pub const MARLIN_POLAR: Segmentation = Segmentation::Fixed {
        segments_per_second: 180.0,
        min_length: 0.5,
    };
    pub const RRF: Segmentation = Segmentation::Fixed {
        segments_per_second: 100.0,
        min_length: 0.2,
    };
}

impl Default for Segmentation {
    fn default() -> Self {
        Segmentation::Adaptive {
            tolerance: Self::DEFAULT_TOLERANCE,
        }
    }
}

/// Digits after the decimal point in the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decimals {
    /// Linear axes (mm): radius, Z, Cartesian X/Y.
    pub linear: u8,
    /// Rotary axes (in the chosen angle unit).
    pub angle: u8,
    pub extrusion: u8,
}

impl Default for Decimals {
    /// 4 / 6 / 5: rounding moves the nozzle by < 0.0001 mm at 300 mm radius, far below the tolerance.
    fn default() -> Self {
        Decimals {
            linear: 4,
            angle: 6,
            extrusion: 5,
        }
    }
}

/// A motor's speed and acceleration limits (the config's `max_angular_velocity` / `max_joint_velocity` and
/// `max_step_rate` × step distance; `max_angular_accel` / `max_joint_accel`), in the motor's unit per second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorLimit {
    /// The motor's index in the machine's [`kinematics::Kinematics::motors`].
    pub motor: usize,
    /// mm/s or rad/s.
    pub max_velocity: Option<f64>,
    /// mm/s² or rad/s² (not applied: the firmware plans acceleration on the written feeds itself).
    pub max_accel: Option<f64>,
}

/// All options of a conversion.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvertOptions {
    pub target: Target,
    pub segmentation: Segmentation,
    /// Letters of the two planar output axes; `None` = `X`, `Y` (polar: X = radius, Y = angle, as Marlin
    /// POLAR and RRF expect; SCARA: X = a, Y = b). The centring thesis writes `R`, `T`.
    pub axis_letters: Option<[char; 2]>,
    pub angle_unit: AngleUnit,
    pub feed: FeedMode,
    pub extrusion: Extrusion,
    pub decimals: Decimals,
    /// Angular speed (rad/s) of the rotate-in-place move at the polar centre.
    pub flip_speed: f64,
    /// Part placement: the input's XY is scaled about the origin by `scale_xy`, then shifted by
    /// `translate` (mm), before conversion. Z and E are not changed.
    pub scale_xy: f64,
    pub translate: [f64; 2],
    /// Where the machine is (Cartesian X Y Z, mm) at the start of the input and after a `G28`: the config's
    /// homing pose. `None`: unknown; then a move that needs a coordinate the input has not set is refused
    /// (nothing is invented).
    pub home: Option<[f64; 3]>,
    /// The firmware that reads the output (verification replays its mode lines this way).
    pub firmware: Firmware,
    /// Motor speed limits: every written segment takes at least each limited motor's travel over its
    /// speed limit (see [`crate::limits`]). Empty: segments take their Cartesian time.
    pub motor_limits: Vec<MotorLimit>,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions {
            target: Target::default(),
            segmentation: Segmentation::default(),
            axis_letters: None,
            angle_unit: AngleUnit::default(),
            feed: FeedMode::default(),
            extrusion: Extrusion::default(),
            decimals: Decimals::default(),
            flip_speed: std::f64::consts::TAU,
            scale_xy: 1.0,
            translate: [0.0, 0.0],
            home: None,
            firmware: Firmware::default(),
            motor_limits: Vec::new(),
        }
    }
}

impl ConvertOptions {
    pub fn letters(&self) -> [char; 2] {
        self.axis_letters.unwrap_or(['X', 'Y'])
    }

    /// Written units per internal unit (mm or rad) of an output axis.
    pub fn axis_scale(&self, unit: MotorUnit) -> f64 {
        match (unit, self.angle_unit) {
            (MotorUnit::Rad, AngleUnit::Degrees) => 180.0 / std::f64::consts::PI,
            _ => 1.0,
        }
    }

    pub fn axis_decimals(&self, unit: MotorUnit) -> u8 {
        match unit {
            MotorUnit::Rad => self.decimals.angle,
            MotorUnit::Mm => self.decimals.linear,
        }
    }

    /// Worst nozzle displacement (mm) caused by rounding the two written planar axes (radii up to 1 m).
    pub fn rounding_budget(&self, units: [MotorUnit; 2]) -> f64 {
        let per_axis = units.map(|unit| {
            let half_unit =
                0.5 / 10f64.powi(i32::from(self.axis_decimals(unit))) / self.axis_scale(unit);
            if unit == MotorUnit::Rad {
                half_unit * MAX_RADIUS_FOR_ROUNDING
            } else {
                half_unit
            }
        });
        (per_axis[0] * per_axis[0] + per_axis[1] * per_axis[1]).sqrt()
    }

    /// An input XY point placed on the machine (see [`ConvertOptions::translate`]).
    pub fn place(&self, xy: [f64; 2]) -> [f64; 2] {
        [
            xy[0] * self.scale_xy + self.translate[0],
            xy[1] * self.scale_xy + self.translate[1],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_firmware_reads_mode_lines_its_own_way() {
        // E relative after each sequence of mode lines: (Marlin, RRF, Klipper).
        let cases: [(&[&str], [bool; 3]); 6] = [
            (&[], [false, false, false]),
            (&["M83"], [true, true, true]),
            (&["G91"], [true, false, true]),
            (&["M83", "G90"], [false, true, true]),
            (&["M82", "G91", "G90"], [false, false, false]),
            (&["G91", "M82"], [false, false, true]),
        ];
        for (lines, expected) in cases {
            for (firmware, relative) in [Firmware::Marlin, Firmware::Rrf, Firmware::Klipper]
                .into_iter()
                .zip(expected)
            {
                let mut modes = ModeState::new(firmware);
                for line in lines {
                    match *line {
                        "G90" => modes.axes_mode(false),
                        "G91" => modes.axes_mode(true),
                        "M82" => modes.extrusion_mode(false),
                        _ => modes.extrusion_mode(true),
                    }
                }
                assert_eq!(modes.relative_e(), relative, "{firmware:?} after {lines:?}");
            }
        }
    }

    #[test]
    fn default_rounding_is_far_below_the_default_tolerance() {
        let budget = ConvertOptions::default().rounding_budget([MotorUnit::Mm, MotorUnit::Rad]);
        // 4 decimals of mm (0.5e-4) and 6 of a degree at 1 m (8.7e-6).
        assert!((budget - 0.5e-4f64.hypot(0.5e-6f64.to_radians() * 1000.0)).abs() < 1e-12);
        assert!(budget < Segmentation::DEFAULT_TOLERANCE / 50.0);
    }

    #[test]
    fn placement_scales_then_translates() {
        let options = ConvertOptions {
            scale_xy: 0.5,
            translate: [1.0, 130.0],
            ..ConvertOptions::default()
        };
        assert_eq!(options.place([10.0, -4.0]), [6.0, 128.0]);
    }
}
