//! The library through its C interface, without a host: machines built from printer.cfg text, the solvers
//! Klipper would call (through the callback pointer in the allocated struct) against the closed forms of
//! REFERENCE.md §2, finite output for any input, and the whole-move checks.

use std::f64::consts::PI;
use std::ffi::{CStr, CString, c_char};

use jointspace_klipper::abi::{Move, StepperKinematics};
use jointspace_klipper::machine::Machine;
use jointspace_klipper::{
    jointspace_check_move, jointspace_machine_free, jointspace_machine_new,
    jointspace_stepper_alloc,
};
use proptest::prelude::*;

use crate::hosts::workspace_root;

/// An example machine's printer.cfg with the plug-in's kinematics name and extra `[printer]` keys.
fn config(example: &str, extra: &str) -> CString {
    let path = workspace_root().join(format!("examples/machines/{example}.cfg"));
    let text = std::fs::read_to_string(path).expect("example config");
    let text = text.replace(
        &format!("kinematics: {example}"),
        &format!("kinematics: jointspace_{example}\n{extra}"),
    );
    CString::new(text).expect("no NUL")
}

pub fn machine(example: &str, extra: &str) -> *mut Machine {
    let mut error = [0 as c_char; 256];
    let text = config(example, extra);
    // SAFETY: valid strings and buffer.
    let m = unsafe { jointspace_machine_new(text.as_ptr(), 0, error.as_mut_ptr(), error.len()) };
    assert!(
        !m.is_null(),
        "{}",
        unsafe { CStr::from_ptr(error.as_ptr()) }.to_string_lossy()
    );
    m
}

/// A stepper the way Klipper holds it: the struct, whose callback it calls with moves and times.
struct Stepper(*mut StepperKinematics);

impl Stepper {
    fn new(m: *mut Machine, name: &str) -> Stepper {
        let name = CString::new(name).expect("name");
        // SAFETY: a live machine and a valid name.
        let sk = unsafe { jointspace_stepper_alloc(m, name.as_ptr()) };
        assert!(!sk.is_null(), "no solver");
        Stepper(sk)
    }

    /// The position at toolhead point `p` (a resting move), as itersolve_calc_position_from_coord asks it.
    fn at(&self, p: [f64; 3], commanded: f64) -> f64 {
        let m = Move {
            print_time: 0.0,
            move_t: 1000.0,
            start_v: 0.0,
            half_accel: 0.0,
            start_pos: p,
            axes_r: [0.0; 3],
        };
        self.on(&m, 500.0, commanded)
    }

    fn on(&self, m: &Move, t: f64, commanded: f64) -> f64 {
        // SAFETY: the struct came from jointspace_stepper_alloc; the callback is ours.
        unsafe {
            (*self.0).commanded_pos = commanded;
            let callback = (*self.0).calc_position_cb.expect("callback");
            callback(self.0, std::ptr::from_ref(m).cast_mut(), t)
        }
    }
}

impl Drop for Stepper {
    fn drop(&mut self) {
        // SAFETY: calloc'd by the library; freed once, as Klipper does.
        unsafe { libc::free(self.0.cast()) };
    }
}

#[derive(Debug)]
pub struct Owned(pub *mut Machine);
impl Drop for Owned {
    fn drop(&mut self) {
        // SAFETY: from jointspace_machine_new, freed once.
        unsafe { jointspace_machine_free(self.0) };
    }
}

#[test]
fn polar_with_offsets_follows_the_closed_form() {
    let (dx, dy): (f64, f64) = (0.7, -0.3);
    let m = Owned(machine(
        "polar",
        &format!("arm_zero_offset: {dx}\narm_lateral_offset: {dy}"),
    ));
    let (bed, arm) = (
        Stepper::new(m.0, "stepper_bed"),
        Stepper::new(m.0, "stepper_arm"),
    );
    for (x, y) in [
        (100.0f64, 0.0f64),
        (-3.0, 4.0),
        (0.5, -120.0),
        (-200.0, -1.0),
    ] {
        // REFERENCE.md §2: r = −dx + √(|p|² − dy²), the bed at atan2(p) − atan2(dy, dx + r).
        let r = -dx + ((x * x + y * y) - dy * dy).sqrt();
        let theta = y.atan2(x) - dy.atan2(dx + r);
        let got = bed.at([x, y, 0.0], theta + 0.1);
        assert!(
            (got - theta).abs() < 1e-12,
            "bed at ({x}, {y}): {got} vs {theta}"
        );
        assert!(
            (arm.at([x, y, 0.0], 0.0) - r).abs() < 1e-12,
            "arm at ({x}, {y})"
        );
    }
    // Continuous: near a commanded reading a whole turn away, the bed answers in that turn.
    let r = -dx + (2500.0 - dy * dy).sqrt();
    let theta = PI / 2.0 - dy.atan2(dx + r);
    let turned = bed.at([0.0, 50.0, 0.0], 2.0 * PI + 1.5);
    assert!(
        (turned - (2.0 * PI + theta)).abs() < 1e-12,
        "{turned} vs {}",
        2.0 * PI + theta
    );
}

#[test]
fn scara_follows_the_fekt_closed_form() {
    let m = Owned(machine("scara", ""));
    let (a, b) = (
        Stepper::new(m.0, "stepper_a"),
        Stepper::new(m.0, "stepper_b"),
    );
    for (x, y) in [(0.0, 141.4), (50.0, 120.0), (-150.0, 40.0), (120.0, 150.0)] {
        let cos_q2 = (x * x + y * y - 20000.0) / 20000.0;
        let q2 = f64::acos(cos_q2);
        let q1 = f64::atan2(y, x) - f64::atan2(100.0 * q2.sin(), 100.0 + 100.0 * q2.cos());
        assert_eq!(a.at([x, y, 0.0], 0.0), q1, "shoulder at ({x}, {y})");
        assert_eq!(
            b.at([x, y, 0.0], 0.0),
            q2 + q1 / 3.0,
            "elbow motor at ({x}, {y})"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    /// Whatever move Klipper hands over (unreachable points, the exact centre, huge or non-finite values), the
    /// answer is a finite number; where there is no motor position the motor stays where it was commanded.
    #[test]
    fn solvers_never_return_nan(
        start in prop::array::uniform3(prop_oneof![-1e6..1e6f64, Just(0.0), Just(f64::NAN), Just(f64::INFINITY)]),
        dir in prop::array::uniform3(-1.0..1.0f64),
        v in 0.0..500.0f64,
        t in 0.0..2.0f64,
        commanded in -10.0..10.0f64,
    ) {
        let polar = Owned(machine("polar", "arm_lateral_offset: 0.5"));
        let ideal = Owned(machine("polar", ""));
        let scara = Owned(machine("scara", ""));
        let m = Move { print_time: 0.0, move_t: 2.0, start_v: v, half_accel: 0.0, start_pos: start, axes_r: dir };
        for (machine, motor) in [(&polar, "stepper_bed"), (&polar, "stepper_arm"), (&ideal, "stepper_bed"),
                                 (&ideal, "stepper_arm"), (&scara, "stepper_a"), (&scara, "stepper_b"),
                                 (&scara, "stepper_z")] {
            let s = Stepper::new(machine.0, motor);
            let p = s.on(&m, t, commanded);
            prop_assert!(p.is_finite(), "{motor}: {p}");
        }
    }
}

/// Whole-move check: refusals carry the reason; a move passing `d` from the centre of a bed limited to `ω`
/// is capped near `ω·d` (the bed turns at v/d at the closest approach).
#[test]
fn check_move_refuses_and_caps() {
    let omega = 5.0;
    let m = Owned(machine("polar", &format!("max_angular_velocity: {omega}")));
    let mut limits = [0.0; 2];
    let mut error = [0 as c_char; 256];
    let mut check = |start: [f64; 3], end: [f64; 3], speed: f64| {
        // SAFETY: a live machine, two limit slots, a 256-byte buffer.
        let rc = unsafe {
            jointspace_check_move(
                m.0,
                start[0],
                start[1],
                start[2],
                end[0],
                end[1],
                end[2],
                speed,
                3000.0,
                limits.as_mut_ptr(),
                error.as_mut_ptr(),
                error.len(),
            )
        };
        let reason = unsafe { CStr::from_ptr(error.as_ptr()) }
            .to_string_lossy()
            .into_owned();
        (rc, limits, reason)
    };
    let (rc, _, reason) = check([100.0, 0.0, 1.0], [-100.0, 0.0, 1.0], 100.0);
    assert_eq!(rc, -1);
    assert!(reason.contains("rotation centre"), "{reason}");
    let (rc, _, reason) = check([100.0, 0.0, 1.0], [250.0, 200.0, 1.0], 100.0);
    assert_eq!(rc, -1);
    assert!(reason.contains("stepper_arm"), "{reason}");
    let d = 10.0;
    let (rc, caps, _) = check([-100.0, d, 1.0], [100.0, d, 1.0], 100.0);
    assert_eq!(rc, 1);
    assert!(
        caps[0] <= omega * d && caps[0] > 0.8 * omega * d,
        "cap {} vs ω·d {}",
        caps[0],
        omega * d
    );
    let (rc, _, _) = check([100.0, 0.0, 1.0], [150.0, 0.0, 1.0], 100.0);
    assert_eq!(rc, 0, "a radial move turns the bed not at all");
}

#[test]
fn bad_config_is_refused_with_the_reason() {
    let mut error = [0 as c_char; 256];
    let text =
        CString::new("[printer]\nkinematics: jointspace_scara\nmax_velocity: 100\n").expect("text");
    // SAFETY: valid strings and buffer.
    let m = unsafe { jointspace_machine_new(text.as_ptr(), 0, error.as_mut_ptr(), error.len()) };
    assert!(m.is_null());
    let reason = unsafe { CStr::from_ptr(error.as_ptr()) }.to_string_lossy();
    assert!(reason.contains("max_accel"), "{reason}");
}
