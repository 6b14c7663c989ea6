//! The two C structs of Klipper's step generator this library touches, laid out as in
//! `klippy/chelper/itersolve.h` and `trapq.h` (identical in Klipper, Kalico and the FEKT-SCARA fork).
//! [`layout`] describes them as this library was built; the plug-in compares that, at load, with the layout the
//! running host's own headers give, and the test suite with a C program compiled against each host's headers.

use std::ffi::{CString, c_void};
use std::sync::OnceLock;

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

/// The size of a field, named by a projection (Rust has no `size_of` for a field by name).
fn field_size<S, F>(_: fn(&S) -> &F) -> usize {
    std::mem::size_of::<F>()
}

/// `name offset size` lines, one per listed field of `$t`.
macro_rules! field_lines {
    ($t:ty; $($f:ident),+) => {
        [$(format!(
            "{} {} {}\n",
            stringify!($f),
            std::mem::offset_of!($t, $f),
            field_size(|s: &$t| &s.$f)
        )),+].concat()
    };
}

/// Klipper's struct `name` ("stepper_kinematics" or "move") as this library was built for it, as text: a
/// `size N` line for the struct the library allocates (so the host's fields must be exactly these), then
/// `field offset size` per field. `struct move` has no size line: the library reads its leading fields through the
/// host's pointer and never sizes it. `None` for another name.
pub fn layout(name: &str) -> Option<&'static CString> {
    static LAYOUTS: OnceLock<[CString; 2]> = OnceLock::new();
    let [stepper_kinematics, moves] = LAYOUTS.get_or_init(|| {
        let sk = format!("size {}\n", std::mem::size_of::<StepperKinematics>())
            + &field_lines!(StepperKinematics; step_dist, commanded_pos, sc, last_flush_time, last_move_time, tq,
                active_flags, gen_steps_pre_active, gen_steps_post_active, calc_position_cb, post_cb);
        let m = field_lines!(Move; print_time, move_t, start_v, half_accel, start_pos, axes_r);
        [sk, m].map(|text| CString::new(text).unwrap_or_default())
    });
    match name {
        "stepper_kinematics" => Some(stepper_kinematics),
        "move" => Some(moves),
        _ => None,
    }
}
