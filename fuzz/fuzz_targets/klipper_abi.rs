//! Fuzz target `klipper_abi`: the Klipper plug-in's C interface driven as `klipper/jointspace_klipper/jointspace.py` drives it.
//!
//! A machine from one of `klipper/examples/` (its `[printer]` and `[stepper_*]` sections, as the plug-in hands them
//! over) with fuzz-chosen key values, absurd numbers included; then moves whose ends are biased to the poses where
//! the geometry degenerates (the polar centre, the SCARA's straight and folded arm, the five-bar's arms straight and
//! folded, at 0..1e-3 mm from them) or are huge, tiny and non-finite: `check_move`, `move_waypoints`, `junction_speed`, `inverse`/`forward`,
//! `reach_margin`, and every motor's step solver as Klipper's itersolve calls it.
//!
//! A crash is any panic, even one the library catches (libfuzzer-sys's panic hook aborts on every panic), a NaN or
//! non-finite answer, a refusal without a reason, or a cap Klipper could not divide by.
#![no_main]

use std::ffi::{CStr, CString, c_char};

use jointspace_klipper::abi::Move;
use jointspace_klipper::machine::Machine;
use jointspace_klipper::*;
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

const POLAR: &str = include_str!("../../klipper/examples/polar.cfg");
const SCARA: &str = include_str!("../../klipper/examples/scara.cfg");
const FIVEBAR: &str = include_str!("../../klipper/examples/fivebar.cfg");

/// Which example machine a run drives.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Example {
    Polar,
    Scara,
    Fivebar,
}

impl Example {
    fn config(self) -> &'static str {
        match self {
            Example::Polar => POLAR,
            Example::Scara => SCARA,
            Example::Fivebar => FIVEBAR,
        }
    }

    /// The centres and radii of the circles its special poses lie on (the polar centre; the SCARA's straight arm;
    /// each five-bar side straight and folded about its base joint, as in `klipper/examples/fivebar.cfg`).
    fn special_circles(self) -> &'static [([f64; 2], f64)] {
        match self {
            Example::Polar => &[([0.0, 0.0], 0.0)],
            Example::Scara => &[([0.0, 0.0], 0.0), ([0.0, 0.0], 200.0)],
            Example::Fivebar => &[
                ([-50.0, -200.0], 350.0),
                ([-50.0, -200.0], 50.0),
                ([50.0, -200.0], 350.0),
                ([50.0, -200.0], 50.0),
            ],
        }
    }
}

/// Keys whose values are numbers (`[printer]` and stepper keys both examples read or might).
const PRINTER_KEYS: &[&str] = &[
    "max_velocity",
    "max_accel",
    "minimum_cruise_ratio",
    "square_corner_velocity",
    "max_z_velocity",
    "max_z_accel",
    "link1_length",
    "link2_length",
    "offset_x",
    "offset_y",
    "ecr",
    "base_protection_radius",
    "singularity_margin",
    "max_joint_velocity",
    "max_joint_accel",
    "max_angular_velocity",
    "max_angular_accel",
    "arm_zero_offset",
    "arm_lateral_offset",
    "left_base_x",
    "left_base_y",
    "right_base_x",
    "right_base_y",
    "left_proximal_length",
    "right_proximal_length",
    "left_distal_length",
    "right_distal_length",
    "left_zero",
    "right_zero",
];
const STEPPER_KEYS: &[&str] = &[
    "position_endstop",
    "position_min",
    "position_max",
    "rotation_distance",
    "microsteps",
    "full_steps_per_rotation",
    "gear_ratio",
];
const STEPPERS: &[&str] = &[
    "stepper_bed",
    "stepper_arm",
    "stepper_a",
    "stepper_b",
    "stepper_left",
    "stepper_right",
    "stepper_z",
];

/// Numbers as a config line or a G-code line may spell them.
const ABSURD_TEXT: &[&str] = &[
    "0",
    "-0",
    "1e-300",
    "1e300",
    "1e400",
    "-1e400",
    "nan",
    "inf",
    "-inf",
    "1e-12",
    "1e9",
    "-1e9",
    "0.0000001",
    "100000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "3:1",
    "0:1",
    "1:0",
    "-5",
    "2147483648",
    "18446744073709551616",
];

fn number(u: &mut Unstructured) -> Result<f64> {
    Ok(match u.int_in_range(0..=5)? {
        0 => *u.choose(&WILD)?,
        1 => f64::from_bits(u.arbitrary()?),
        2 => 10f64.powi(u.int_in_range(-320..=308)?) * if u.arbitrary()? { 1.0 } else { -1.0 },
        _ => f64::from(u.int_in_range(-4000..=4000)?) / 10.0,
    })
}

const WILD: [f64; 12] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.0,
    -0.0,
    f64::MAX,
    f64::MIN_POSITIVE,
    5e-324,
    1e9,
    -1e9 - 1.0,
    1e199,
    1e-10,
];

/// A config value: an absurd spelling, or a fuzz number written out (Rust's `{}`/`{:e}` as a user might type it).
fn value(u: &mut Unstructured) -> Result<String> {
    Ok(match u.int_in_range(0..=2)? {
        0 => (*u.choose(ABSURD_TEXT)?).to_string(),
        1 => format!("{}", number(u)?),
        _ => format!("{:e}", number(u)?),
    })
}

/// `text` with `key: value` as the first line of `[section]` (an existing `key:` there removed); unchanged when
/// the section is absent.
fn set(text: &str, section: &str, key: &str, value: &str) -> String {
    let header = format!("[{section}]");
    let mut out = String::with_capacity(text.len() + 64);
    let mut inside = false;
    for line in text.lines() {
        if line.starts_with('[') {
            inside = line.trim() == header;
            out.push_str(line);
            out.push('\n');
            if inside {
                out.push_str(&format!("{key}: {value}\n"));
            }
            continue;
        }
        if inside && line.split(':').next().is_some_and(|k| k.trim() == key) {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// The sections the plug-in hands over: `[printer]` and every `[stepper_*]`.
fn plugin_sections(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut keep = false;
    for line in text.lines() {
        if line.starts_with('[') {
            keep = line.starts_with("[printer]") || line.starts_with("[stepper_");
        }
        if keep {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// A point near one of the special poses, or anywhere, or wild.
fn point(u: &mut Unstructured, machine: Example) -> Result<[f64; 3]> {
    const NEAR: [f64; 7] = [0.0, 1e-15, 1e-12, 1e-10, 1e-9, 1e-6, 1e-3];
    let z = if u.arbitrary()? { 1.0 } else { number(u)? };
    Ok(match u.int_in_range(0..=5)? {
        0..=2 => {
            let d = *u.choose(&NEAR)? * if u.arbitrary()? { 1.0 } else { -1.0 };
            let angle = f64::from(u.int_in_range(-3600..=3600)?) / 3600.0 * std::f64::consts::PI;
            let (centre, radius) = *u.choose(machine.special_circles())?;
            let r = radius - d;
            [centre[0] + r * angle.cos(), centre[1] + r * angle.sin(), z]
        }
        3 => [number(u)?, number(u)?, z],
        _ => [
            f64::from(u.int_in_range(-3000..=3000)?) / 10.0,
            f64::from(u.int_in_range(-3000..=3000)?) / 10.0,
            z,
        ],
    })
}

/// The move's end: a short hop from `start` (1e-12..1e3 mm) or another point.
fn end_from(u: &mut Unstructured, machine: Example, start: [f64; 3]) -> Result<[f64; 3]> {
    if u.arbitrary()? {
        let length = 10f64.powi(u.int_in_range(-12..=3)?);
        let mut end = start;
        for v in &mut end {
            *v += length * f64::from(u.int_in_range(-8..=8)?) / 8.0;
        }
        return Ok(end);
    }
    point(u, machine)
}

fn reason(error: &[c_char]) -> String {
    // SAFETY: the buffers start zeroed and the library NUL-terminates what it writes.
    unsafe { CStr::from_ptr(error.as_ptr()) }
        .to_string_lossy()
        .into_owned()
}

fn refusal_is_clean(what: &str, error: &[c_char]) {
    let reason = reason(error);
    assert!(!reason.is_empty(), "{what}: refused without a reason");
    assert!(!reason.contains("internal error"), "{what}: {reason}");
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});

fn run(u: &mut Unstructured) -> Result<()> {
    let machine = *u.choose(&[Example::Polar, Example::Scara, Example::Fivebar])?;
    let mut text = plugin_sections(machine.config());
    for _ in 0..u.int_in_range(0..=4)? {
        let value = value(u)?;
        text = if u.arbitrary()? {
            set(&text, "printer", u.choose(PRINTER_KEYS)?, &value)
        } else {
            set(&text, u.choose(STEPPERS)?, u.choose(STEPPER_KEYS)?, &value)
        };
    }
    let Ok(text) = CString::new(text) else {
        return Ok(());
    };
    let mut error = [0 as c_char; 512];
    // SAFETY: a NUL-terminated string and a 512-byte buffer.
    let m = unsafe { jointspace_machine_new(text.as_ptr(), 0, error.as_mut_ptr(), error.len()) };
    if m.is_null() {
        refusal_is_clean("machine_new", &error);
        return Ok(());
    }
    let result = drive(u, m, machine);
    // SAFETY: from jointspace_machine_new, freed once.
    unsafe { jointspace_machine_free(m) };
    result
}

/// What the plug-in asks of a machine: its keys and motors, solvers, then moves.
fn drive(u: &mut Unstructured, m: *mut Machine, machine: Example) -> Result<()> {
    // SAFETY: the machine lives until the caller frees it; the returned strings live as long.
    let keys = unsafe { CStr::from_ptr(jointspace_machine_read_keys(m)) };
    assert!(!keys.to_bytes().is_empty());
    let count = jointspace_motor_count(m);
    assert!(count == 3, "motor count {count}");
    let _ = jointspace_caps_corners(m);
    let mut solvers = Vec::new();
    for i in 0..count {
        let name = jointspace_motor_name(m, i);
        assert!(!name.is_null());
        // SAFETY: a name the library returned.
        let sk = unsafe { jointspace_stepper_alloc(m, name) };
        assert!(!sk.is_null(), "no solver for motor {i}");
        solvers.push(sk);
    }
    let outcome = moves(u, m, machine, &solvers);
    for sk in solvers {
        // SAFETY: calloc'd by the library; Klipper frees it with free.
        unsafe { libc::free(sk.cast()) };
    }
    outcome
}

fn moves(
    u: &mut Unstructured,
    m: *mut Machine,
    machine: Example,
    solvers: &[*mut jointspace_klipper::abi::StepperKinematics],
) -> Result<()> {
    let mut start = point(u, machine)?;
    for _ in 0..u.int_in_range(1..=6)? {
        let end = end_from(u, machine, start)?;
        let speed = if u.arbitrary()? { 150.0 } else { number(u)? };
        let accel = if u.arbitrary()? { 2000.0 } else { number(u)? };
        check_move(m, start, end, speed, accel);
        waypoints(m, start, end, speed, accel, number(u)?);
        let next = end_from(u, machine, end)?;
        let points = [start, end, next].concat();
        // SAFETY: nine doubles.
        let v = unsafe { jointspace_junction_speed(m, points.as_ptr(), accel, number(u)?) };
        assert!(v >= 0.0, "junction {v}");
        pose(m, end, [number(u)?, number(u)?, number(u)?]);
        step(solvers, start, end, speed, accel, number(u)?);
        start = end;
    }
    Ok(())
}

fn check_move(m: *mut Machine, s: [f64; 3], e: [f64; 3], speed: f64, accel: f64) {
    let mut limits = [0.0; 2];
    let mut error = [0 as c_char; 512];
    // SAFETY: two limit slots and a 512-byte buffer.
    let rc = unsafe {
        jointspace_check_move(
            m,
            s[0],
            s[1],
            s[2],
            e[0],
            e[1],
            e[2],
            speed,
            accel,
            limits.as_mut_ptr(),
            error.as_mut_ptr(),
            error.len(),
        )
    };
    let what = format!("check_move {s:?} -> {e:?} at {speed}, {accel}");
    match rc {
        -1 => refusal_is_clean(&what, &error),
        0..=3 => {
            if rc & 1 == 1 {
                assert!(
                    limits.iter().all(|c| *c > 0.0 && c.is_finite()),
                    "{what}: caps {limits:?}"
                );
            }
        }
        _ => panic!("{what}: {rc}"),
    }
}

fn waypoints(m: *mut Machine, s: [f64; 3], e: [f64; 3], speed: f64, accel: f64, bed: f64) {
    let mut out = [0.0; 3 * 64];
    let mut error = [0 as c_char; 512];
    let cut_spans = i32::from(bed.to_bits() & 1 == 0);
    // SAFETY: out holds 3 · 64 doubles, error 512 bytes.
    let rc = unsafe {
        jointspace_move_waypoints(
            m,
            s[0],
            s[1],
            s[2],
            e[0],
            e[1],
            e[2],
            speed,
            accel,
            bed,
            cut_spans,
            out.as_mut_ptr(),
            64,
            error.as_mut_ptr(),
            512,
        )
    };
    if rc == -1 {
        return;
    }
    if rc == -2 {
        // SAFETY: the library wrote a NUL-terminated reason.
        let reason = unsafe { std::ffi::CStr::from_ptr(error.as_ptr()) };
        assert!(!reason.to_bytes().is_empty(), "a refusal without a reason");
        return;
    }
    let what = format!("waypoints {s:?} -> {e:?} at {speed}, {accel}, bed {bed}");
    assert!((1..=64).contains(&rc), "{what}: {rc}");
    let points = &out[..3 * rc as usize];
    assert!(points.iter().all(|v| v.is_finite()), "{what}: {points:?}");
    assert_eq!(points[points.len() - 1], 1.0, "{what}: {points:?}");
}

fn pose(m: *mut Machine, p: [f64; 3], previous: [f64; 3]) {
    let mut motors = [0.0; 3];
    let mut xyz = [0.0; 3];
    let mut error = [0 as c_char; 512];
    for prev in [std::ptr::null(), previous.as_ptr()] {
        // SAFETY: three coordinates and motors, a 512-byte buffer.
        let rc = unsafe {
            jointspace_inverse(
                m,
                p.as_ptr(),
                prev,
                motors.as_mut_ptr(),
                error.as_mut_ptr(),
                512,
            )
        };
        match rc {
            0 => assert!(
                motors.iter().all(|v| v.is_finite()),
                "inverse {p:?}: {motors:?}"
            ),
            _ => refusal_is_clean("inverse", &error),
        }
        let read = if rc == 0 { motors } else { previous };
        // SAFETY: three motors and coordinates, a 512-byte buffer.
        let rc = unsafe {
            jointspace_forward(m, read.as_ptr(), xyz.as_mut_ptr(), error.as_mut_ptr(), 512)
        };
        match rc {
            0 => assert!(
                xyz.iter().all(|v| v.is_finite()),
                "forward {read:?}: {xyz:?}"
            ),
            _ => refusal_is_clean("forward", &error),
        }
    }
    let mut margin = 0.0;
    // SAFETY: one double.
    let rc = unsafe { jointspace_reach_margin(m, p[0], p[1], p[2], &mut margin) };
    assert!(
        rc == -1 || (rc == 0 && margin.is_finite()),
        "reach_margin {p:?}: {rc} {margin}"
    );
}

/// Every motor's solver along the move, as itersolve asks it (a trapezoid's three phases at a few times).
fn step(
    solvers: &[*mut jointspace_klipper::abi::StepperKinematics],
    s: [f64; 3],
    e: [f64; 3],
    speed: f64,
    accel: f64,
    commanded: f64,
) {
    // Klipper's commanded position is a motor reading: always finite.
    let commanded = if commanded.is_finite() {
        commanded
    } else {
        0.0
    };
    let d = [e[0] - s[0], e[1] - s[1], e[2] - s[2]];
    let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let axes_r = if length > 0.0 {
        d.map(|v| v / length)
    } else {
        [0.0; 3]
    };
    let m = Move {
        print_time: 0.0,
        move_t: length / speed,
        start_v: 0.0,
        half_accel: 0.5 * accel,
        start_pos: s,
        axes_r,
    };
    for &sk in solvers {
        for t in [0.0, 0.25, 0.5, 1.0].map(|f| f * m.move_t) {
            // SAFETY: a stepper from jointspace_stepper_alloc and a live move; Klipper calls the callback so.
            let p = unsafe {
                (*sk).commanded_pos = commanded;
                let callback = (*sk).calc_position_cb.expect("a callback");
                callback(sk, std::ptr::from_ref(&m).cast_mut(), t)
            };
            assert!(p.is_finite(), "solver at {t} of {m:?}: {p}");
        }
    }
}
