//! `libjointspace_klipper.so`: jointspace's kinematics inside Klipper and Kalico.
//!
//! Klipper generates steps by asking a per-stepper `struct stepper_kinematics` for the motor position at trial
//! times (`klippy/chelper/itersolve.c`); this library allocates such structs with its own callbacks (the
//! `kinematics` crate's geometry, plain data, reentrant, no allocation), and answers the plain questions the
//! Python kinematics class (`klipper/jointspace_klipper/jointspace_kinematics.py`) asks: forward kinematics, whether a whole move can be made
//! and how fast, the pose to report. Klipper's itersolve and step compression do the rest.
//!
//! The C interface is declared in `klipper/jointspace_klipper/jointspace.h`. Conventions: functions return 0 on success and a
//! negative number on failure, with the reason written into a caller's buffer; nothing here panics across the
//! boundary (an `extern "C"` function would abort the host rather than unwind: every entry point runs its work
//! through [`guarded`], which turns a panic into the function's failure value), and no function returns NaN.
//! Coordinates, speeds and accelerations are checked at the boundary ([`usable_move`]): a non-finite or absurd
//! value is refused with its reason before any geometry sees it.

// The C interface is this crate's whole job: `unsafe` is allowed here and nowhere else in the workspace, and every
// block says why it is sound.
#![allow(unsafe_code)]

pub mod abi;
pub mod boundary;
pub mod identity;
pub mod machine;
pub mod pieces;
pub mod scan;
pub mod stepper;

use std::ffi::{CStr, c_char, c_int};
use std::ptr;

use abi::StepperKinematics;
use boundary::{NO_BUFFER, guarded, read3, usable_move, usable_point, write_message};
use machine::{Machine, MoveVerdict};
use stepper::{Solver, allocate};

/// The verdict as Klipper may apply it: caps only for a move requested at a positive speed and acceleration (else
/// the segment alone is checked), and then positive and finite — Klipper divides by them, so a move whose motor
/// limits allow it no speed at all is refused, with the caps that say so.
fn positive_caps(verdict: MoveVerdict, speed: f64, accel: f64) -> Result<MoveVerdict, String> {
    if !(speed > 0.0 && accel > 0.0) {
        return Ok(MoveVerdict {
            caps: None,
            ..verdict
        });
    }
    match verdict.caps {
        Some((v, a)) if !(v > 0.0 && v.is_finite() && a > 0.0 && a.is_finite()) => Err(format!(
            "the motor limits allow no speed along this move (cap {v:e} mm/s, {a:e} mm/s²): it keeps within \
             rounding of a pose the joints cannot be evaluated at"
        )),
        _ => Ok(verdict),
    }
}

/// The machine behind a handle, or `None` for null.
fn machine<'a>(m: *const Machine) -> Option<&'a Machine> {
    // SAFETY: a non-null handle comes from `jointspace_machine_new` and lives until `jointspace_machine_free`.
    unsafe { m.as_ref() }
}

/// Klipper's `struct stepper_kinematics` or `struct move` (`name` without `struct`) as this library was built for
/// it ([`abi::layout`]: `size N` for the struct it allocates, then `field offset size` lines); null for another
/// name. The plug-in compares it with the running host's own `itersolve.h` and `trapq.h` and refuses a mismatch.
///
/// # Safety
/// `name` is a NUL-terminated string (or null).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_struct_layout(name: *const c_char) -> *const c_char {
    guarded(ptr::null(), NO_BUFFER, || {
        if name.is_null() {
            return ptr::null();
        }
        // SAFETY: per the contract, a NUL-terminated string.
        let name = unsafe { CStr::from_ptr(name) }.to_string_lossy();
        abi::layout(&name).map_or(ptr::null(), |text| text.as_ptr())
    })
}

/// Builds a machine from printer.cfg text (its `[printer]` and stepper sections) whose solvers compute positions
/// with the host's arithmetic (`fused_arithmetic`: see [`jointspace_polar_radius`]). Null on failure, with the
/// reason in `error`.
///
/// # Safety
/// `config_text` is a NUL-terminated string; `error` holds `error_len` bytes (or is null).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_machine_new(
    config_text: *const c_char,
    fused_arithmetic: c_int,
    error: *mut c_char,
    error_len: usize,
) -> *mut Machine {
    guarded(ptr::null_mut(), (error, error_len), || {
        if config_text.is_null() {
            write_message("no config text", error, error_len);
            return ptr::null_mut();
        }
        // SAFETY: per the contract, a NUL-terminated string.
        let text = unsafe { CStr::from_ptr(config_text) }.to_string_lossy();
        boxed_machine(
            Machine::from_config_text(&text, fused_arithmetic != 0),
            error,
            error_len,
        )
    })
}

/// Builds a machine from the printer.cfg file at `path` (with its includes and SAVE_CONFIG block, as the
/// `jointspace` command line reads it), so that a config error names the owner's file, line and column; otherwise
/// as [`jointspace_machine_new`].
///
/// # Safety
/// `path` is a NUL-terminated string; `error` holds `error_len` bytes (or is null).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_machine_new_from_file(
    path: *const c_char,
    fused_arithmetic: c_int,
    error: *mut c_char,
    error_len: usize,
) -> *mut Machine {
    guarded(ptr::null_mut(), (error, error_len), || {
        if path.is_null() {
            write_message("no config file", error, error_len);
            return ptr::null_mut();
        }
        // SAFETY: per the contract, a NUL-terminated string.
        let path = unsafe { CStr::from_ptr(path) }.to_string_lossy();
        let machine =
            Machine::from_config_file(std::path::Path::new(path.as_ref()), fused_arithmetic != 0);
        boxed_machine(machine, error, error_len)
    })
}

/// The machine on the heap for the caller, or null with the reason in `error`.
fn boxed_machine(
    machine: Result<Machine, String>,
    error: *mut c_char,
    error_len: usize,
) -> *mut Machine {
    match machine {
        Ok(m) => Box::into_raw(Box::new(m)),
        Err(e) => {
            write_message(&e, error, error_len);
            ptr::null_mut()
        }
    }
}

/// Frees a machine (null is ignored).
///
/// # Safety
/// `m` comes from `jointspace_machine_new` and is not used afterwards.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_machine_free(m: *mut Machine) {
    guarded((), NO_BUFFER, || {
        if !m.is_null() {
            // SAFETY: per the contract, the box made by jointspace_machine_new, freed once.
            drop(unsafe { Box::from_raw(m) });
        }
    })
}

/// `section key` lines of every config key the machine read (valid while the machine lives).
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_machine_read_keys(m: *const Machine) -> *const c_char {
    guarded(c"".as_ptr(), NO_BUFFER, || {
        machine(m).map_or(c"".as_ptr(), |m| m.read_keys().as_ptr())
    })
}

/// The value the machine was built with for the `[printer]` key `key` (a polar arm's `arm_zero_offset`,
/// `arm_lateral_offset`; a SCARA's `link1_length`, `link2_length`, `offset_x`, `offset_y`; `max_z_velocity`,
/// `max_z_accel`) into `value`: 0, or −1 when the machine has no such key. The plug-in asks here instead of reading
/// the key a second time.
///
/// # Safety
/// `key` is a NUL-terminated string; `value` points to a double.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_machine_value(
    m: *const Machine,
    key: *const c_char,
    value: *mut f64,
) -> c_int {
    guarded(-1, NO_BUFFER, || {
        if key.is_null() || value.is_null() {
            return -1;
        }
        // SAFETY: per the contract (null is refused).
        let key = unsafe { CStr::from_ptr(key) }.to_string_lossy();
        match machine(m).and_then(|m| m.printer_value(&key)) {
            Some(v) => {
                // SAFETY: value points to a double (null is refused).
                unsafe { *value = v };
                0
            }
            None => -1,
        }
    })
}

/// Number of motors of the machine (the order of every motor array below).
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_motor_count(m: *const Machine) -> c_int {
    guarded(0, NO_BUFFER, || {
        machine(m).map_or(0, |m| m.motor_names().len() as c_int)
    })
}

/// The config section of motor `index` (valid while the machine lives), or null.
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_motor_name(m: *const Machine, index: c_int) -> *const c_char {
    guarded(ptr::null(), NO_BUFFER, || {
        machine(m)
            .and_then(|m| m.motor_names().get(usize::try_from(index).ok()?))
            .map_or(ptr::null(), |n| n.as_ptr())
    })
}

/// Allocates the step-time solver of the stepper configured in section `name` (libc memory: Klipper frees it
/// with `free`). Null if `name` is not one of the machine's motors or memory ran out.
///
/// # Safety
/// `name` is a NUL-terminated string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_stepper_alloc(
    m: *const Machine,
    name: *const c_char,
) -> *mut StepperKinematics {
    guarded(ptr::null_mut(), NO_BUFFER, || {
        if name.is_null() {
            return ptr::null_mut();
        }
        // SAFETY: per the contract.
        let name = unsafe { CStr::from_ptr(name) }.to_string_lossy();
        match machine(m).and_then(|m| m.solver(&name)) {
            Some(solver) => allocate(solver, machine(m).is_some_and(Machine::fused)),
            None => ptr::null_mut(),
        }
    })
}

/// Allocates a solver whose position is `cx·x + cy·y + cz·z` of the toolhead position: the joint-space homing
/// moves, where the toolhead's coordinates stand for joint readings. Null if a coefficient is not finite.
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_linear_stepper_alloc(
    cx: f64,
    cy: f64,
    cz: f64,
    fused_arithmetic: c_int,
) -> *mut StepperKinematics {
    guarded(ptr::null_mut(), NO_BUFFER, || {
        if ![cx, cy, cz].iter().all(|c| c.is_finite()) {
            return ptr::null_mut();
        }
        let solver = Solver::Linear {
            coeffs: [cx, cy, cz],
        };
        allocate(solver, fused_arithmetic != 0)
    })
}

/// The ideal polar arm's position at `move_time` into `m` (`√(x² + y²)`), in plain or fused arithmetic. The
/// Python side compares it with the host's own polar solver on sample moves to learn which arithmetic the host's
/// C helper was compiled with, so every solver here reproduces the host's positions to the bit. 0 for a null move
/// (or if the computation failed).
///
/// # Safety
/// `m` points to a `struct move` (its first ten doubles are read).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_polar_radius(
    m: *const abi::Move,
    move_time: f64,
    fused_arithmetic: c_int,
) -> f64 {
    guarded(0.0, NO_BUFFER, || {
        // SAFETY: per the contract (null is refused).
        let Some(m) = (unsafe { m.as_ref() }) else {
            return 0.0;
        };
        Solver::PolarRadius.position(m, move_time, 0.0, fused_arithmetic != 0)
    })
}

/// Toolhead position `xyz[3]` of motor positions `motors[motor_count]`. 0, or −1 with the reason (also when the position
/// would not be finite).
///
/// # Safety
/// `motors` holds the machine's motor count of doubles, `xyz` three; `error` holds `error_len` bytes or is null.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_forward(
    m: *const Machine,
    motors: *const f64,
    xyz: *mut f64,
    error: *mut c_char,
    error_len: usize,
) -> c_int {
    guarded(-1, (error, error_len), || {
        let Some(m) = machine(m) else { return -1 };
        let n = m.motor_names().len();
        // SAFETY: per the contract, n doubles.
        let motors = unsafe { std::slice::from_raw_parts(motors, n) };
        match m.kinematics().forward(motors) {
            Ok(p) if p.iter().any(|v| !v.is_finite()) => {
                write_message(
                    &format!("no finite position for motors at {motors:?}"),
                    error,
                    error_len,
                );
                -1
            }
            Ok(p) => {
                // SAFETY: xyz holds three doubles.
                unsafe { ptr::copy_nonoverlapping(p.as_ptr(), xyz, 3) };
                0
            }
            Err(e) => {
                write_message(&e.to_string(), error, error_len);
                -1
            }
        }
    })
}

/// Motor positions `motors[motor_count]` of toolhead position `xyz[3]`, angles nearest `previous` (may be null).
/// 0, or −1 with the reason (a coordinate that is not finite or beyond [`MAX_COORDINATE`] among them).
///
/// # Safety
/// `xyz` holds three doubles, `previous` (if not null) and `motors` the motor count; `error` as above.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_inverse(
    m: *const Machine,
    xyz: *const f64,
    previous: *const f64,
    motors: *mut f64,
    error: *mut c_char,
    error_len: usize,
) -> c_int {
    guarded(-1, (error, error_len), || {
        let Some(m) = machine(m) else { return -1 };
        let n = m.motor_names().len();
        // SAFETY: per the contract.
        let (p, out) = unsafe { (read3(xyz), std::slice::from_raw_parts_mut(motors, n)) };
        if let Err(e) = usable_point(p) {
            write_message(&e, error, error_len);
            return -1;
        }
        let result = if previous.is_null() {
            m.kinematics().inverse(p, out)
        } else {
            // SAFETY: per the contract, n doubles.
            let previous = unsafe { std::slice::from_raw_parts(previous, n) };
            m.kinematics().inverse_near(p, previous, out)
        };
        match result {
            Ok(()) if out.iter().all(|v| v.is_finite()) => 0,
            Ok(()) => {
                write_message(
                    &format!("no finite motor position for {p:?}"),
                    error,
                    error_len,
                );
                -1
            }
            Err(e) => {
                write_message(&e.to_string(), error, error_len);
                -1
            }
        }
    })
}

/// Checks the straight move `start → end` requested at `speed` (mm/s) and `accel` (mm/s²): the whole segment
/// against reach, the polar centre, singular poses and joint limits, and the motor limits (bed angular speed and
/// acceleration, joint speeds, step rates) over its whole length. Returns −1 when it cannot be made (the reason in
/// `error`), else flags: 1 when the move must be slowed (`limits[0]` cruise speed, `limits[1]` acceleration), 2 when
/// it ends at a pose the arm may only rest at (it must end at rest). A coordinate that is not finite or beyond
/// [`MAX_COORDINATE`], or a speed or acceleration that is not finite, is refused (speed or acceleration ≤ 0 checks
/// the segment only). Caps are always positive and finite: a move its motor limits would allow no speed is refused.
///
/// # Safety
/// `limits` holds two doubles; `error` holds `error_len` bytes or is null.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // scalars, so the Python side calls without building arrays per move
pub unsafe extern "C" fn jointspace_check_move(
    m: *const Machine,
    start_x: f64,
    start_y: f64,
    start_z: f64,
    end_x: f64,
    end_y: f64,
    end_z: f64,
    speed: f64,
    accel: f64,
    limits: *mut f64,
    error: *mut c_char,
    error_len: usize,
) -> c_int {
    guarded(-1, (error, error_len), || {
        let Some(m) = machine(m) else { return -1 };
        let (start, end) = ([start_x, start_y, start_z], [end_x, end_y, end_z]);
        let verdict = usable_move(start, end, speed, accel)
            .and_then(|()| m.check_move(start, end, speed, accel))
            .and_then(|v| positive_caps(v, speed, accel));
        match verdict {
            Ok(MoveVerdict { caps, ends_at_rest }) => {
                if let Some((speed, accel)) = caps {
                    // SAFETY: limits holds two doubles.
                    unsafe {
                        *limits = speed;
                        *limits.add(1) = accel;
                    }
                }
                c_int::from(caps.is_some()) | (c_int::from(ends_at_rest) << 1)
            }
            Err(e) => {
                write_message(&e, error, error_len);
                -1
            }
        }
    })
}

/// The highest speed (mm/s) at the corner between the move `points[0..3] → points[3..6]`, planned with
/// acceleration `prev_accel`, and the move on to `points[6..9]`, planned with `next_accel`, that keeps each
/// acceleration-limited motor's speed jump within its limit; infinity where nothing caps it (or on bad input).
///
/// # Safety
/// `points` holds nine doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_junction_speed(
    m: *const Machine,
    points: *const f64,
    prev_accel: f64,
    next_accel: f64,
) -> f64 {
    guarded(f64::INFINITY, NO_BUFFER, || {
        let Some(m) = machine(m) else {
            return f64::INFINITY;
        };
        // SAFETY: points holds nine doubles.
        let p = unsafe { std::slice::from_raw_parts(points, 9) };
        let point = |i: usize| [p[3 * i], p[3 * i + 1], p[3 * i + 2]];
        let speed = m.junction_speed([point(0), point(1), point(2)], [prev_accel, next_accel]);
        // NaN from non-finite input caps nothing (the moves themselves are checked elsewhere).
        if speed.is_nan() { f64::INFINITY } else { speed }
    })
}

/// 1 when corners need capping (some motor has an acceleration limit: ask [`jointspace_junction_speed`]), else 0.
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_caps_corners(m: *const Machine) -> c_int {
    guarded(0, NO_BUFFER, || {
        c_int::from(machine(m).is_some_and(Machine::caps_corners))
    })
}

/// The pose the config declares for homing (FEKT-SCARA's `home_position`) into `xyz[3]`: 0, or −1 if none.
///
/// # Safety
/// `xyz` holds three doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_declared_home(m: *const Machine, xyz: *mut f64) -> c_int {
    guarded(-1, NO_BUFFER, || {
        match machine(m).and_then(Machine::declared_home) {
            Some(p) => {
                // SAFETY: xyz holds three doubles.
                unsafe { ptr::copy_nonoverlapping(p.as_ptr(), xyz, 3) };
                0
            }
            None => -1,
        }
    })
}

/// A polar bed's centre, where its angle is undefined: `out[0..2]` its XY, `out[2]` the tolerance (mm) within which
/// a path meets it (the move transform turns the bed in place on that circle). 0, or −1 when the machine has none.
///
/// # Safety
/// `out` holds three doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_rotation_centre(m: *const Machine, out: *mut f64) -> c_int {
    match machine(m).and_then(|m| m.kinematics().rotation_centre()) {
        Some(c) => {
            let values = [c.point[0], c.point[1], c.tolerance];
            // SAFETY: out holds three doubles.
            unsafe { ptr::copy_nonoverlapping(values.as_ptr(), out, 3) };
            0
        }
        None => -1,
    }
}

/// How far `(x, y, z)` is from the edge of the machine's reach (mm, negative outside) into `margin`: 0, or −1
/// when the machine has no such edge (Cartesian) or the point has no pose.
///
/// # Safety
/// `margin` points to a double.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_reach_margin(
    m: *const Machine,
    x: f64,
    y: f64,
    z: f64,
    margin: *mut f64,
) -> c_int {
    guarded(-1, NO_BUFFER, || {
        match machine(m).and_then(|m| m.reach_margin([x, y, z])) {
            Some(v) if v.is_finite() => {
                // SAFETY: margin points to a double.
                unsafe { *margin = v };
                0
            }
            _ => -1,
        }
    })
}

/// Where the plug-in's G-code move transform cuts the move `start → end` requested at `speed` and `accel`, so that
/// Klipper slows only the pieces near a limit, and a polar bed turns in place at its centre (`bed_angle`: where the
/// last move left the bed; `cut_spans` 0: only the centre shapes the move, no cuts at span boundaries). Writes up to
/// `max` waypoints as `x, y, fraction` triples (the fraction of the move each stands for, which Z and E follow; the
/// last is the move's end, or the centre when the end lies within its tolerance) and returns how many; −1 if more
/// were needed; −2, with the reason in `error`, when a piece cannot be made or the move's numbers are not usable (as
/// [`jointspace_check_move`] refuses them, `bed_angle` finite too): the whole move is then refused before any of it
/// is queued.
///
/// # Safety
/// `out` holds `3 · max` doubles; `error` holds `error_len` bytes or is null.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // scalars, so the Python side calls without building arrays per move
pub unsafe extern "C" fn jointspace_move_waypoints(
    m: *const Machine,
    start_x: f64,
    start_y: f64,
    start_z: f64,
    end_x: f64,
    end_y: f64,
    end_z: f64,
    speed: f64,
    accel: f64,
    bed_angle: f64,
    cut_spans: c_int,
    out: *mut f64,
    max: c_int,
    error: *mut c_char,
    error_len: usize,
) -> c_int {
    guarded(-2, (error, error_len), || {
        let Some(m) = machine(m) else { return -1 };
        let (start, end) = ([start_x, start_y, start_z], [end_x, end_y, end_z]);
        let usable = usable_move(start, end, speed, accel).and_then(|()| {
            bed_angle
                .is_finite()
                .then_some(())
                .ok_or_else(|| format!("bed angle {bed_angle} is not finite"))
        });
        let points = match usable
            .and_then(|()| m.waypoints(start, end, speed, accel, bed_angle, cut_spans != 0))
        {
            Ok(points) => points,
            Err(e) => {
                write_message(&e, error, error_len);
                return -2;
            }
        };
        if points.len() > usize::try_from(max).unwrap_or(0) {
            return -1;
        }
        for (i, p) in points.iter().enumerate() {
            // SAFETY: i < max, and out holds 3 · max doubles.
            unsafe {
                *out.add(3 * i) = p.x;
                *out.add(3 * i + 1) = p.y;
                *out.add(3 * i + 2) = p.fraction;
            }
        }
        points.len() as c_int
    })
}

/// A SCARA's calibration pattern: `count` crosses of `cross_size` mm at well-conditioned poses this machine
/// reaches, as G-code (into `gcode`), and the measurements file to fill in (into `template`). Returns the number
/// of crosses, −1 if the machine is not a SCARA or no pose fits, −2 if a buffer is too small.
///
/// # Safety
/// `gcode` holds `gcode_len` bytes and `template` `template_len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_scara_pattern(
    m: *const Machine,
    count: c_int,
    cross_size: f64,
    gcode: *mut c_char,
    gcode_len: usize,
    template: *mut c_char,
    template_len: usize,
) -> c_int {
    guarded(-1, NO_BUFFER, || {
        if !(cross_size > 0.0 && cross_size.is_finite()) {
            return -1;
        }
        let options = calibrate::scara::PatternOptions {
            cross_size,
            ..Default::default()
        };
        let count = usize::try_from(count).unwrap_or(0);
        let Some(Ok(pattern)) = machine(m).and_then(|m| m.scara_pattern(count, &options)) else {
            return -1;
        };
        if pattern.gcode.len() >= gcode_len || pattern.template.len() >= template_len {
            return -2;
        }
        write_message(&pattern.gcode, gcode, gcode_len);
        write_message(&pattern.template, template, template_len);
        pattern.poses.len() as c_int
    })
}

/// The centre scan's passes for `settings`: their arm readings in the order to run them (into `arms`, up to
/// `max`), and how far past a full revolution each pass turns the bed at both ends (rad, into `bed_overlap`).
/// Returns the number of passes, −1 with the reason in `error` if the settings make no scan, −2 if `max` is
/// too small.
///
/// # Safety
/// `settings` points to a `struct jointspace_hall_scan`; `arms` holds `max` doubles; `bed_overlap` one double;
/// `error` holds `error_len` bytes (or is null).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_scan_passes(
    settings: *const scan::HallScanSettings,
    arms: *mut f64,
    max: c_int,
    bed_overlap: *mut f64,
    error: *mut c_char,
    error_len: usize,
) -> c_int {
    guarded(-1, (error, error_len), || {
        // SAFETY: per the contract (null is refused).
        let Some(settings) = (unsafe { settings.as_ref() }) else {
            return -1;
        };
        let sweep = settings.sweep();
        let passes = match calibrate::sweep::pass_arms(&sweep) {
            Ok(p) => p,
            Err(e) => {
                write_message(&e.to_string(), error, error_len);
                return -1;
            }
        };
        if passes.len() > usize::try_from(max).unwrap_or(0) {
            return -2;
        }
        for (i, arm) in passes.iter().enumerate() {
            // SAFETY: i < max, and arms holds max doubles.
            unsafe { *arms.add(i) = *arm };
        }
        // SAFETY: per the contract.
        unsafe { *bed_overlap = sweep.bed_overlap() };
        passes.len() as c_int
    })
}

/// The centre from a sweep's ADC reports: `samples` holds `count` rows of (pass, arm mm, bed rad, ADC value 0..1).
/// On success writes dx, dy and their standard errors into `result[0..4]`, the detections file (the format of
/// `jointspace calibrate centre --scan`) into `csv` and a summary into `report`, and returns 0. Returns −1 with the
/// reason in `report` when the scan is refused (nothing to store), −2 if a buffer is too small.
///
/// # Safety
/// `settings` points to a `struct jointspace_hall_scan`; `samples` holds `4 · count` doubles; `result` four
/// doubles; `csv` and `report` hold `csv_len` and `report_len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_scan_centre(
    settings: *const scan::HallScanSettings,
    samples: *const f64,
    count: usize,
    result: *mut f64,
    csv: *mut c_char,
    csv_len: usize,
    report: *mut c_char,
    report_len: usize,
) -> c_int {
    guarded(-1, (report, report_len), || {
        // SAFETY: per the contract (null is refused).
        let Some(settings) = (unsafe { settings.as_ref() }) else {
            return -1;
        };
        let Some(values) = count.checked_mul(4) else {
            return -1;
        };
        let rows = if samples.is_null() || count == 0 {
            &[][..]
        } else {
            // SAFETY: per the contract, samples holds 4 · count doubles.
            unsafe { std::slice::from_raw_parts(samples, values) }
        };
        let accepted = scan::samples_from_rows(rows).and_then(|s| scan::scan_centre(settings, &s));
        let scan = match accepted {
            Ok(scan) => scan,
            Err(e) => {
                write_message(&e.to_string(), report, report_len);
                return -1;
            }
        };
        let summary = scan::summary(&scan.result);
        if scan.detections_csv.len() >= csv_len || summary.len() >= report_len {
            return -2;
        }
        write_message(&scan.detections_csv, csv, csv_len);
        write_message(&summary, report, report_len);
        let r = &scan.result;
        let values = [
            r.arm_zero_offset,
            r.arm_lateral_offset,
            r.sigma_arm_zero_offset,
            r.sigma_arm_lateral_offset,
        ];
        for (i, v) in values.into_iter().enumerate() {
            // SAFETY: per the contract, result holds four doubles.
            unsafe { *result.add(i) = v };
        }
        0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn caps_klipper_cannot_divide_by_are_refused() {
        let verdict = |caps| MoveVerdict {
            caps,
            ends_at_rest: true,
        };
        assert!(positive_caps(verdict(Some((0.0, 0.0))), 100.0, 3000.0).is_err());
        assert!(positive_caps(verdict(Some((f64::NAN, 10.0))), 100.0, 3000.0).is_err());
        assert!(positive_caps(verdict(Some((1e-4, 0.0))), 100.0, 3000.0).is_err());
        let slowed = verdict(Some((1e-4, 1.0)));
        assert_eq!(positive_caps(slowed, 100.0, 3000.0), Ok(slowed));
        // Segment only: no caps whatever the limits said.
        assert_eq!(
            positive_caps(verdict(Some((0.0, 0.0))), 0.0, 3000.0),
            Ok(verdict(None))
        );
    }
}
