//! `libjointspace_klipper.so`: jointspace's kinematics inside Klipper and Kalico.
//!
//! Klipper generates steps by asking a per-stepper `struct stepper_kinematics` for the motor position at trial
//! times (`klippy/chelper/itersolve.c`); this library allocates such structs with its own callbacks (the
//! `kinematics` crate's geometry, plain data, reentrant, no allocation), and answers the plain questions the
//! Python kinematics class (`klipper/jointspace.py`) asks: forward kinematics, whether a whole move can be made
//! and how fast, the pose to report. Klipper's itersolve and step compression do the rest.
//!
//! The C interface is declared in `klipper/jointspace.h`. Conventions: functions return 0 on success and a
//! negative number on failure, with the reason written into a caller's buffer; nothing here panics across the
//! boundary (an `extern "C"` function aborts rather than unwind, and the code is written not to panic), and no
//! function returns NaN.

// The C interface is this crate's whole job: `unsafe` is allowed here and nowhere else in the workspace, and every
// block says why it is sound.
#![allow(unsafe_code)]

pub mod abi;
pub mod machine;
pub mod pieces;
pub mod scan;
pub mod stepper;

use std::ffi::{CStr, c_char, c_int};
use std::ptr;

use abi::StepperKinematics;
use machine::{Machine, MoveVerdict};
use stepper::{Solver, allocate};

/// The library's version, `"jointspace-klipper X.Y.Z"`.
const VERSION: &CStr = concat_c_version();

const fn concat_c_version() -> &'static CStr {
    match CStr::from_bytes_with_nul(
        concat!("jointspace-klipper ", env!("CARGO_PKG_VERSION"), "\0").as_bytes(),
    ) {
        Ok(v) => v,
        Err(_) => c"jointspace-klipper",
    }
}

/// Writes `message` into the caller's buffer (truncated, always NUL-terminated).
fn write_message(message: &str, buffer: *mut c_char, length: usize) {
    if buffer.is_null() || length == 0 {
        return;
    }
    let bytes = message.as_bytes();
    let n = bytes.len().min(length - 1);
    // SAFETY: the caller promises `buffer` holds `length` bytes; n + 1 ≤ length.
    unsafe {
        ptr::copy_nonoverlapping(bytes.as_ptr(), buffer.cast::<u8>(), n);
        *buffer.add(n) = 0;
    }
}

/// Reads three doubles from a caller's array.
///
/// # Safety
/// `p` points to at least three doubles.
unsafe fn read3(p: *const f64) -> [f64; 3] {
    // SAFETY: per the contract.
    unsafe { [*p, *p.add(1), *p.add(2)] }
}

/// The machine behind a handle, or `None` for null.
fn machine<'a>(m: *const Machine) -> Option<&'a Machine> {
    // SAFETY: a non-null handle comes from `jointspace_machine_new` and lives until `jointspace_machine_free`.
    unsafe { m.as_ref() }
}

/// The library version string (static).
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_version() -> *const c_char {
    VERSION.as_ptr()
}

/// Layout of `struct stepper_kinematics` as this library was built for it: size, then the offsets of
/// `commanded_pos`, `active_flags`, `calc_position_cb` and `post_cb` (written into `out[0..5]`). The tests
/// compare it with the host's `itersolve.h`; the Python side refuses to load on a mismatch.
///
/// # Safety
/// `out` points to at least five `size_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_stepper_kinematics_layout(out: *mut usize) {
    let layout = [
        std::mem::size_of::<StepperKinematics>(),
        std::mem::offset_of!(StepperKinematics, commanded_pos),
        std::mem::offset_of!(StepperKinematics, active_flags),
        std::mem::offset_of!(StepperKinematics, calc_position_cb),
        std::mem::offset_of!(StepperKinematics, post_cb),
    ];
    for (i, v) in layout.into_iter().enumerate() {
        // SAFETY: per the contract, out has five slots.
        unsafe { *out.add(i) = v };
    }
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
    if config_text.is_null() {
        write_message("no config text", error, error_len);
        return ptr::null_mut();
    }
    // SAFETY: per the contract, a NUL-terminated string.
    let text = unsafe { CStr::from_ptr(config_text) }.to_string_lossy();
    match Machine::from_config_text(&text, fused_arithmetic != 0) {
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
    if !m.is_null() {
        // SAFETY: per the contract, the box made by jointspace_machine_new, freed once.
        drop(unsafe { Box::from_raw(m) });
    }
}

/// `section key` lines of every config key the machine read (valid while the machine lives).
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_machine_read_keys(m: *const Machine) -> *const c_char {
    machine(m).map_or(c"".as_ptr(), |m| m.read_keys().as_ptr())
}

/// Number of motors of the machine (the order of every motor array below).
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_motor_count(m: *const Machine) -> c_int {
    machine(m).map_or(0, |m| m.motor_names().len() as c_int)
}

/// The config section of motor `index` (valid while the machine lives), or null.
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_motor_name(m: *const Machine, index: c_int) -> *const c_char {
    machine(m)
        .and_then(|m| m.motor_names().get(usize::try_from(index).ok()?))
        .map_or(ptr::null(), |n| n.as_ptr())
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
    if name.is_null() {
        return ptr::null_mut();
    }
    // SAFETY: per the contract.
    let name = unsafe { CStr::from_ptr(name) }.to_string_lossy();
    match machine(m).and_then(|m| m.solver(&name)) {
        Some(solver) => allocate(solver, machine(m).is_some_and(Machine::fused)),
        None => ptr::null_mut(),
    }
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
    if ![cx, cy, cz].iter().all(|c| c.is_finite()) {
        return ptr::null_mut();
    }
    let solver = Solver::Linear {
        coeffs: [cx, cy, cz],
    };
    allocate(solver, fused_arithmetic != 0)
}

/// The ideal polar arm's position at `move_time` into `m` (`√(x² + y²)`), in plain or fused arithmetic. The
/// Python side compares it with the host's own polar solver on sample moves to learn which arithmetic the host's
/// C helper was compiled with, so every solver here reproduces the host's positions to the bit.
///
/// # Safety
/// `m` points to a `struct move` (its first ten doubles are read).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_polar_radius(
    m: *const abi::Move,
    move_time: f64,
    fused_arithmetic: c_int,
) -> f64 {
    // SAFETY: per the contract.
    let m = unsafe { &*m };
    Solver::PolarRadius.position(m, move_time, 0.0, fused_arithmetic != 0)
}

/// Toolhead position `xyz[3]` of motor positions `motors[motor_count]`. 0, or −1 with the reason.
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
    let Some(m) = machine(m) else { return -1 };
    let n = m.motor_names().len();
    // SAFETY: per the contract, n doubles.
    let motors = unsafe { std::slice::from_raw_parts(motors, n) };
    match m.kinematics().forward(motors) {
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
}

/// Motor positions `motors[motor_count]` of toolhead position `xyz[3]`, angles nearest `previous` (may be null).
/// 0, or −1 with the reason.
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
    let Some(m) = machine(m) else { return -1 };
    let n = m.motor_names().len();
    // SAFETY: per the contract.
    let (p, out) = unsafe { (read3(xyz), std::slice::from_raw_parts_mut(motors, n)) };
    let result = if previous.is_null() {
        m.kinematics().inverse(p, out)
    } else {
        // SAFETY: per the contract, n doubles.
        let previous = unsafe { std::slice::from_raw_parts(previous, n) };
        m.kinematics().inverse_near(p, previous, out)
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            write_message(&e.to_string(), error, error_len);
            -1
        }
    }
}

/// Checks the straight move `start → end` requested at `speed` (mm/s) and `accel` (mm/s²): the whole segment
/// against reach, the polar centre, singular poses and joint limits, and the motor limits (bed angular speed and
/// acceleration, joint speeds, step rates) over its whole length. Returns −1 when it cannot be made (the reason in
/// `error`), else flags: 1 when the move must be slowed (`limits[0]` cruise speed, `limits[1]` acceleration), 2 when
/// it ends at a pose the arm may only rest at (it must end at rest).
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
    let Some(m) = machine(m) else { return -1 };
    let verdict = m.check_move(
        [start_x, start_y, start_z],
        [end_x, end_y, end_z],
        speed,
        accel,
    );
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
    let Some(m) = machine(m) else {
        return f64::INFINITY;
    };
    // SAFETY: points holds nine doubles.
    let p = unsafe { std::slice::from_raw_parts(points, 9) };
    let point = |i: usize| [p[3 * i], p[3 * i + 1], p[3 * i + 2]];
    let speed = m.junction_speed([point(0), point(1), point(2)], [prev_accel, next_accel]);
    // NaN from non-finite input caps nothing (the moves themselves are checked elsewhere).
    if speed.is_nan() { f64::INFINITY } else { speed }
}

/// 1 when corners need capping (some motor has an acceleration limit: ask [`jointspace_junction_speed`]), else 0.
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_caps_corners(m: *const Machine) -> c_int {
    c_int::from(machine(m).is_some_and(Machine::caps_corners))
}

/// The pose the config declares for homing (FEKT-SCARA's `home_position`) into `xyz[3]`: 0, or −1 if none.
///
/// # Safety
/// `xyz` holds three doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn jointspace_declared_home(m: *const Machine, xyz: *mut f64) -> c_int {
    match machine(m).and_then(Machine::declared_home) {
        Some(p) => {
            // SAFETY: xyz holds three doubles.
            unsafe { ptr::copy_nonoverlapping(p.as_ptr(), xyz, 3) };
            0
        }
        None => -1,
    }
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
    match machine(m).and_then(|m| m.reach_margin([x, y, z])) {
        Some(v) if v.is_finite() => {
            // SAFETY: margin points to a double.
            unsafe { *margin = v };
            0
        }
        _ => -1,
    }
}

/// Where the plug-in's G-code move transform cuts the move `start → end` requested at `speed` and `accel`, so that
/// Klipper slows only the pieces near a limit, and a polar bed turns in place at its centre (`bed_angle`: where the
/// last move left the bed; `cut_spans` 0: only the centre shapes the move, no cuts at span boundaries). Writes up to
/// `max` waypoints as `x, y, fraction` triples (the fraction of the move each stands for, which Z and E follow; the
/// last is the move's end, or the centre when the end lies within its tolerance) and returns how many; −1 if more
/// were needed; −2, with the reason in `error`, when a piece cannot be made (the whole move is then refused before
/// any of it is queued).
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
    let Some(m) = machine(m) else { return -1 };
    let points = match m.waypoints(
        [start_x, start_y, start_z],
        [end_x, end_y, end_z],
        speed,
        accel,
        bed_angle,
        cut_spans != 0,
    ) {
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
    if !(cross_size > 0.0 && cross_size.is_finite()) {
        return -1;
    }
    let options = calibrate::scara::PatternOptions {
        cross_size,
        ..Default::default()
    };
    let count = usize::try_from(count).unwrap_or(0);
    let Some((pattern, csv)) = machine(m).and_then(|m| m.scara_pattern(count, &options)) else {
        return -1;
    };
    if pattern.poses.is_empty() {
        return -1;
    }
    if pattern.gcode.len() >= gcode_len || csv.len() >= template_len {
        return -2;
    }
    write_message(&pattern.gcode, gcode, gcode_len);
    write_message(&csv, template, template_len);
    pattern.poses.len() as c_int
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
    // SAFETY: per the contract (null is refused).
    let Some(settings) = (unsafe { settings.as_ref() }) else {
        return -1;
    };
    let rows = if samples.is_null() || count == 0 {
        &[][..]
    } else {
        // SAFETY: per the contract, samples holds 4 · count doubles.
        unsafe { std::slice::from_raw_parts(samples, 4 * count) }
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
}
