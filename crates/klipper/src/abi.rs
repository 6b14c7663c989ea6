//! The two C structs of Klipper's step generator this library touches, laid out as in
//! `klippy/chelper/itersolve.h` and `trapq.h` (identical in Klipper, Kalico and the FEKT-SCARA fork).
//! The test suite compiles a C program against each host's headers and compares sizes and offsets.

use std::ffi::c_void;

/// `sk_calc_callback`: the stepper's position (its own unit) at `move_time` into move `m`.
pub type CalcPositionCallback =
    unsafe extern "C" fn(sk: *mut StepperKinematics, m: *mut Move, move_time: f64) -> f64;
/// `sk_post_callback`: called after steps were generated (Klipper's polar bed renormalises here).
pub type PostCallback = unsafe extern "C" fn(sk: *mut StepperKinematics);

/// `struct stepper_kinematics`. Klipper owns the fields after `commanded_pos` (trapq, step queue, flush times);
/// this library fills the callbacks and `active_flags` when it allocates one.
#[repr(C)]
#[derive(Debug)]
pub struct StepperKinematics {
    pub step_dist: f64,
    pub commanded_pos: f64,
    pub sc: *mut c_void,
    pub last_flush_time: f64,
    pub last_move_time: f64,
    pub tq: *mut c_void,
    pub active_flags: i32,
    pub gen_steps_pre_active: f64,
    pub gen_steps_post_active: f64,
    pub calc_position_cb: Option<CalcPositionCallback>,
    pub post_cb: Option<PostCallback>,
}

/// `AF_X`, `AF_Y`, `AF_Z`: which toolhead axes move this stepper (Klipper skips moves along other axes).
pub const AF_X: i32 = 1;
pub const AF_Y: i32 = 1 << 1;
pub const AF_Z: i32 = 1 << 2;

/// `struct move` up to the fields a position needs (Klipper's list node follows; never touched here).
#[repr(C)]
#[derive(Debug)]
pub struct Move {
    pub print_time: f64,
    pub move_t: f64,
    pub start_v: f64,
    pub half_accel: f64,
    pub start_pos: [f64; 3],
    pub axes_r: [f64; 3],
}

impl Move {
    /// The toolhead position at `move_time`, with `move_get_coord`'s arithmetic (so positions, and the step
    /// times found from them, are bit-identical to the host's own kinematics). `fused`: the host's C helper
    /// was compiled with fused multiply-adds (Kalico builds it with `-march=native`), so its products and sums
    /// round once; the Python side learns which the running host uses (`jointspace_polar_radius`).
    #[inline]
    pub fn coord(&self, move_time: f64, fused: bool) -> [f64; 3] {
        if fused {
            let distance = self.half_accel.mul_add(move_time, self.start_v) * move_time;
            return [
                self.axes_r[0].mul_add(distance, self.start_pos[0]),
                self.axes_r[1].mul_add(distance, self.start_pos[1]),
                self.axes_r[2].mul_add(distance, self.start_pos[2]),
            ];
        }
        let distance = (self.start_v + self.half_accel * move_time) * move_time;
        [
            self.start_pos[0] + self.axes_r[0] * distance,
            self.start_pos[1] + self.axes_r[1] * distance,
            self.start_pos[2] + self.axes_r[2] * distance,
        ]
    }
}
