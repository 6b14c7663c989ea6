//! Per-motor solvers that Klipper's itersolve calls for every trial time of every step.
//!
//! A solver is plain `Copy` data inside the allocated `struct stepper_kinematics` (no pointer back to the
//! machine, no allocation), so Klipper may call it on any thread, for several motors at once. It never panics
//! and never returns NaN: where the toolhead position has no motor position (the polar centre, out of reach),
//! the motor stays where it was commanded last.

use std::f64::consts::{PI, TAU};

use kinematics::fivebar::FivebarSide;
use kinematics::polar::PolarGeometry;
use kinematics::scara::ScaraGeometry;
use kinematics::{CENTRE_DIRECTION_RADIUS, RADIAL_ROUNDING, unwrap_near};

use crate::abi::{AF_X, AF_Y, AF_Z, Move, StepperKinematics};

/// How one motor's position follows the toolhead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Solver {
    /// `coeffs · p` (Cartesian axes, Z, and the joint-space homing moves).
    Linear { coeffs: [f64; 3] },
    /// Ideal polar arm: `√(x² + y²)` (Klipper's expression).
    PolarRadius,
    /// Ideal polar bed: `atan2(y, x)` unwrapped against the commanded angle (Klipper's expression).
    PolarAngle,
    /// Polar bed with the arm's zero and sideways offsets; `has_centre`: the nozzle reaches the point where its
    /// angle is undefined (the kinematics' `rotation_centre`).
    PolarBed {
        geometry: PolarGeometry,
        has_centre: bool,
    },
    /// Polar arm with the offsets.
    PolarArm(PolarGeometry),
    /// SCARA shoulder motor (`stepper_a`).
    ScaraShoulder(ScaraGeometry),
    /// SCARA elbow motor (`stepper_b`), coupled to the shoulder angle.
    ScaraElbow(ScaraGeometry),
    /// One base joint of a five-bar (`stepper_left`, `stepper_right`): its angle from the nozzle's position alone.
    FivebarJoint(FivebarSide),
}

impl Solver {
    /// The motor position at `move_time` into `m`, continuous with `commanded` (the last position stepped to).
    #[inline]
    pub fn position(&self, m: &Move, move_time: f64, commanded: f64, fused: bool) -> f64 {
        let p = m.coord(move_time, fused);
        let [x, y, _] = p;
        if self.is_bed_with_centre()
            && let Some(side) = radial_side_angle(m, x, y)
        {
            return side.map_or(commanded, |angle| unwrap_near(angle, commanded));
        }
        let position = match self {
            Solver::Linear { coeffs } => linear(coeffs, p),
            Solver::PolarRadius if fused => x.mul_add(x, y * y).sqrt(),
            Solver::PolarRadius => (x * x + y * y).sqrt(),
            Solver::PolarAngle if x == 0.0 && y == 0.0 => commanded,
            Solver::PolarAngle => unwrap_near(y.atan2(x), commanded),
            Solver::PolarBed { geometry: g, .. } => g
                .bed_and_arm(x, y)
                .map_or(commanded, |(bed, _)| unwrap_near(bed, commanded)),
            Solver::PolarArm(g) => g.bed_and_arm(x, y).map_or(commanded, |(_, arm)| arm),
            // Both SCARA motors are plain functions of the position, with the shoulder angle in (−π, π] as
            // the FEKT-SCARA module computes it: the elbow motor's `c·q1` term cannot be unwrapped from its
            // own reading, so the machine refuses moves that would take q1 through ±π instead.
            Solver::ScaraShoulder(g) => g
                .joints(x, y)
                .map_or(commanded, |j| g.motors_from_joints(j).0),
            Solver::ScaraElbow(g) => g
                .joints(x, y)
                .map_or(commanded, |j| g.motors_from_joints(j).1),
            // The side's closed form gives the angle in its window; the reading keeps its whole turns (a range
            // wider than a turn, or a homing reading outside the window, stays continuous).
            Solver::FivebarJoint(side) => side
                .motor(x, y)
                .map_or(commanded, |motor| unwrap_near(motor, commanded)),
        };
        if position.is_finite() {
            position
        } else {
            commanded
        }
    }

    /// A bed whose angle is undefined at one point the nozzle reaches: the centre (no sideways arm offset).
    #[inline]
    fn is_bed_with_centre(&self) -> bool {
        match self {
            Solver::PolarAngle => true,
            Solver::PolarBed { has_centre, .. } => *has_centre,
            _ => false,
        }
    }

    /// Which toolhead axes move this motor (`active_flags`).
    pub fn active_axes(&self) -> i32 {
        match self {
            Solver::Linear { coeffs } => [AF_X, AF_Y, AF_Z]
                .into_iter()
                .zip(coeffs)
                .filter(|(_, c)| **c != 0.0)
                .fold(0, |flags, (flag, _)| flags | flag),
            _ => AF_X | AF_Y,
        }
    }

    /// Whether the commanded position is an angle that may be renormalised into `[−π, π]` after stepping
    /// (a bed that turns without limit; its reading modulo a turn is all that matters).
    fn renormalises(&self) -> bool {
        matches!(self, Solver::PolarAngle | Solver::PolarBed { .. })
    }
}

/// The bed angle at `(x, y)` on move `m` near the polar centre: `Some(None)` where the bed holds its reading (within
/// rounding of the centre, where a move ends or starts on it; or at rest near it), `Some(Some(angle))` on a move
/// through the centre (within [`RADIAL_ROUNDING`]) within [`CENTRE_DIRECTION_RADIUS`] of it: the angle of the side the point is
/// on (before the centre: opposite to the direction of travel; past it: along it), `None` elsewhere (the point's own
/// angle is exact enough).
#[inline]
fn radial_side_angle(m: &Move, x: f64, y: f64) -> Option<Option<f64>> {
    let distance2 = x * x + y * y;
    // Written so that NaN (a move with a non-finite point) takes the plain path, which never returns NaN.
    if distance2.is_nan() || distance2 >= CENTRE_DIRECTION_RADIUS * CENTRE_DIRECTION_RADIUS {
        return None;
    }
    let [rx, ry, _] = m.axes_r;
    let r_xy = rx.hypot(ry);
    if distance2 <= RADIAL_ROUNDING * RADIAL_ROUNDING || r_xy == 0.0 {
        return Some(None);
    }
    let [sx, sy, _] = m.start_pos;
    if (sx * ry - sy * rx).abs() > RADIAL_ROUNDING * r_xy {
        return None;
    }
    Some(Some(if x * rx + y * ry < 0.0 {
        (-ry).atan2(-rx)
    } else {
        ry.atan2(rx)
    }))
}

/// A unit-vector motor (the common case) reads its axis exactly, as Klipper's cartesian kinematics does.
#[inline]
fn linear(coeffs: &[f64; 3], p: [f64; 3]) -> f64 {
    match coeffs {
        [1.0, 0.0, 0.0] => p[0],
        [0.0, 1.0, 0.0] => p[1],
        [0.0, 0.0, 1.0] => p[2],
        [a, b, c] => a * p[0] + b * p[1] + c * p[2],
    }
}

/// A `struct stepper_kinematics` followed by its solver. Klipper frees it with libc's `free`.
#[repr(C)]
#[derive(Debug)]
pub struct JointspaceStepper {
    pub sk: StepperKinematics,
    pub solver: Solver,
    /// The host's arithmetic (see [`Move::coord`]).
    pub fused: bool,
}

/// Allocates a stepper with `solver` (libc `calloc`, so Klipper's `free` releases it); null when out of memory.
pub fn allocate(solver: Solver, fused: bool) -> *mut StepperKinematics {
    // SAFETY: calloc returns zeroed memory of the requested size or null; zero is a valid value for every
    // field of `StepperKinematics` (null pointers, 0.0, None callbacks).
    let stepper = unsafe { libc::calloc(1, std::mem::size_of::<JointspaceStepper>()) }
        .cast::<JointspaceStepper>();
    if stepper.is_null() {
        return std::ptr::null_mut();
    }
    // SAFETY: `stepper` is non-null, aligned (calloc aligns for any type) and sized for a JointspaceStepper;
    // the fields are written in place, nothing is read first.
    unsafe {
        std::ptr::addr_of_mut!((*stepper).solver).write(solver);
        std::ptr::addr_of_mut!((*stepper).fused).write(fused);
        let sk = std::ptr::addr_of_mut!((*stepper).sk);
        (*sk).active_flags = solver.active_axes();
        (*sk).calc_position_cb = Some(calc_position);
        // Every solver has a post_cb: Klipper's input shaper, once it wrapped a solver with one, keeps calling the
        // wrapped solver's after the plug-in swaps a homing solver in under it (and back).
        (*sk).post_cb = Some(if solver.renormalises() {
            renormalise as _
        } else {
            keep as _
        });
        sk
    }
}

/// `calc_position_cb`.
unsafe extern "C" fn calc_position(
    sk: *mut StepperKinematics,
    m: *mut Move,
    move_time: f64,
) -> f64 {
    // SAFETY: Klipper calls this only with a stepper allocated by `allocate` (so `sk` is the first field of a
    // JointspaceStepper) and a live move; it writes neither while the callback runs on this stepper.
    let (stepper, m) = unsafe { (&*sk.cast::<JointspaceStepper>(), &*m) };
    let commanded = stepper.sk.commanded_pos;
    // A panic must not unwind into Klipper's C code, and Klipper must never read NaN: the motor then stays where it
    // was commanded. (A non-finite move reached NaN through `radial_side_angle`, whose `distance2 >= NEAR²` test
    // is false for NaN; found by the `klipper_abi` fuzz target.)
    crate::boundary::guarded(commanded, crate::boundary::NO_BUFFER, || {
        let position = stepper
            .solver
            .position(m, move_time, commanded, stepper.fused);
        if position.is_finite() {
            position
        } else {
            commanded
        }
    })
}

/// `post_cb` of a solver whose commanded position needs no fix-up.
unsafe extern "C" fn keep(_sk: *mut StepperKinematics) {}

/// `post_cb` of a bed that turns freely: keep the commanded angle within a turn, as Klipper's polar does.
unsafe extern "C" fn renormalise(sk: *mut StepperKinematics) {
    // SAFETY: called by Klipper on a stepper allocated by `allocate`, from the thread that owns it now.
    let commanded = unsafe { &mut (*sk).commanded_pos };
    if *commanded < -PI {
        *commanded += TAU;
    } else if *commanded > PI {
        *commanded -= TAU;
    }
}
