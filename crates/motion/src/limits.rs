//! Velocity and acceleration limits of the toolhead, as Klipper's `[printer]` section and
//! `SET_VELOCITY_LIMIT`/`M204` define them.

/// The limits that `SET_VELOCITY_LIMIT` and `M204` may change while printing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityLimits {
    pub max_velocity: f64,
    pub max_accel: f64,
    pub square_corner_velocity: f64,
    pub minimum_cruise_ratio: f64,
}

impl VelocityLimits {
    /// Distance (mm) the path may deviate from a corner: Klipper derives it from the square-corner velocity
    /// so that a 90° corner is taken at exactly that speed.
    pub fn junction_deviation(&self) -> f64 {
        let scv2 = self.square_corner_velocity * self.square_corner_velocity;
        scv2 * (2f64.sqrt() - 1.0) / self.max_accel
    }

    /// The acceleration used by the minimum-cruise-ratio track of the lookahead.
    pub fn mcr_pseudo_accel(&self) -> f64 {
        self.max_accel * (1.0 - self.minimum_cruise_ratio)
    }
}

/// Limits on the extruder, from `[extruder]` (Klipper's defaults already resolved).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtruderLimits {
    /// Largest filament-per-path ratio an extruding move may have (max cross-section / filament area).
    pub max_extrude_ratio: f64,
    /// Filament cross-section (mm²), for error messages.
    pub filament_area: f64,
    pub nozzle_diameter: f64,
    /// Speed and acceleration limits of extrude-only moves and retractions (mm/s, mm/s² of filament).
    pub max_e_velocity: f64,
    pub max_e_accel: f64,
    /// Longest extrude-only move allowed (mm of filament).
    pub max_e_distance: f64,
    /// Largest instantaneous change of extruder velocity at a corner (mm/s).
    pub instantaneous_corner_velocity: f64,
}

/// How a polar bed turns in place at its centre, where a path that meets the centre changes the bed angle
/// (half a revolution for a path straight through it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentreTurn {
    /// The rotation centre (mm).
    pub centre: [f64; 2],
    /// A path this close to the centre (mm) is planned through it (the kinematics' `RotationCentre::tolerance`).
    pub tolerance: f64,
    /// Angular speed and acceleration of the turn (rad/s, rad/s²).
    pub max_velocity: f64,
    pub max_accel: f64,
}

/// Everything the planner needs to know about the machine, fixed for a run.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannerConfig {
    /// Limits at start; commands may change them later.
    pub limits: VelocityLimits,
    /// Z speed limits (applied to moves with Z motion, scaled by the Z share of the move).
    pub max_z_velocity: f64,
    pub max_z_accel: f64,
    /// Apply `max_z_velocity`/`max_z_accel`. Klipper's cartesian and polar kinematics do; the FEKT-SCARA
    /// module does not.
    pub apply_z_limits: bool,
    /// `None`: the machine has no extruder and any E motion is an error.
    pub extruder: Option<ExtruderLimits>,
    /// Arc segment length of `[gcode_arcs]` (mm).
    pub arc_resolution: f64,
    /// Print time of the first move (Klipper's `BUFFER_TIME_START`).
    pub buffer_time_start: f64,
    /// Delay between the end of step generation and a restart (Klipper's `kin_flush_delay`).
    pub kin_flush_delay: f64,
    /// Print time up to which steps count as generated before the first move. Klipper: 0. The FEKT-SCARA
    /// Kalico fork flushes step generation at `buffer_time_start` on `SET_KINEMATIC_POSITION`, so its first move
    /// starts one `kin_flush_delay` later; set this to `buffer_time_start` to reproduce it.
    pub initial_step_gen_time: f64,
    /// Reproduce Klipper's batch mode (`klippy.py -i`): its background flusher plans all queued moves to a
    /// stop whenever step generation catches up with them, at points set by 4096-byte input blocks and by the
    /// first second of print time. Off: moves are planned by the lookahead alone (what a live printer does
    /// when fed fast enough). Needed only to compare with Klipper's batch output.
    pub klipper_batch_flush: bool,
    /// Whose lookahead planning to reproduce (they differ in how high short moves peak).
    pub lookahead: LookaheadRule,
    /// Motor speed/acceleration limits (polar bed, SCARA joints, step rates); empty: Klipper's behaviour.
    pub kinematic_limits: Vec<crate::kinematic_limits::MotorLimit>,
    /// Polar machines: moves through the centre stop there while the bed turns half a revolution. `None`:
    /// such moves are refused (as Klipper, which fails on them).
    pub centre_turn: Option<CentreTurn>,
    /// Skip moves whose segment is unreachable (reported as warnings) instead of stopping with an error.
    pub skip_unreachable: bool,
    /// Klipper's own polar rule (`polar.py`, the plug-in's `centre_slowdown: klipper`): a whole move is slowed,
    /// speed and acceleration scaled from `max_velocity` and `max_accel`, so that the bed turns no faster than this
    /// (rad/s) at the move's closest approach to X0 Y0. `None`: not applied (jointspace's exact rule is
    /// `kinematic_limits`).
    pub klipper_centre_rule: Option<f64>,
}

/// The Klipper-family host whose planning to reproduce (for comparisons with its batch-mode output).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Host {
    /// Klipper: Z speed limits apply, the first move starts at `buffer_time_start`.
    #[default]
    Klipper,
    /// The FEKT-SCARA Kalico fork: no Z speed limits (its SCARA module applies none), and the first move starts one
    /// `kin_flush_delay` after the start buffer (it flushes step generation on `SET_KINEMATIC_POSITION`).
    KalicoFekt,
}

/// Whose lookahead to reproduce where the hosts differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LookaheadRule {
    /// Klipper's: a peak is set by the minimum-cruise-ratio track alone, and a move that cannot accelerate takes
    /// its cruise speed from the move before it.
    #[default]
    Klipper,
    /// Kalico's (and the FEKT-SCARA fork's, which predate Klipper's change): a peak is also capped by that move's
    /// own cruise limit, moves that cannot accelerate wait for the next peak found further back, and a lazy flush
    /// releases only the moves before the last peak.
    Kalico,
}

impl PlannerConfig {
    /// Plan as `host` does where hosts differ.
    pub fn behave_as(&mut self, host: Host) {
        let fekt = host == Host::KalicoFekt;
        self.apply_z_limits = !fekt;
        self.lookahead = if fekt {
            LookaheadRule::Kalico
        } else {
            LookaheadRule::Klipper
        };
        self.initial_step_gen_time = if fekt { self.buffer_time_start } else { 0.0 };
    }

    /// Klipper's defaults around the given velocity limits, with an extruder-less, Z-limited machine.
    pub fn klipper(limits: VelocityLimits) -> Self {
        PlannerConfig {
            limits,
            max_z_velocity: limits.max_velocity,
            max_z_accel: limits.max_accel,
            apply_z_limits: true,
            extruder: None,
            arc_resolution: 1.0,
            buffer_time_start: 0.25,
            kin_flush_delay: 0.001,
            initial_step_gen_time: 0.0,
            klipper_batch_flush: false,
            lookahead: LookaheadRule::Klipper,
            skip_unreachable: false,
            kinematic_limits: Vec::new(),
            centre_turn: None,
            klipper_centre_rule: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_corner_is_taken_at_square_corner_velocity() {
        let limits = VelocityLimits {
            max_velocity: 300.0,
            max_accel: 3000.0,
            square_corner_velocity: 5.0,
            minimum_cruise_ratio: 0.5,
        };
        // For a 90° corner: sin(θ/2) = √½, R = jd·sin/(1−sin), v² = R·accel must equal scv².
        let s = 0.5f64.sqrt();
        let v2 = limits.junction_deviation() * s / (1.0 - s) * limits.max_accel;
        assert!((v2 - 25.0).abs() < 1e-9, "{v2}");
        assert_eq!(limits.mcr_pseudo_accel(), 1500.0);
    }
}
