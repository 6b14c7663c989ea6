//! The library through its C interface, without a host: machines built from printer.cfg text, the solvers
//! Klipper would call (through the callback pointer in the allocated struct) against the closed forms of
//! REFERENCE.md §2, finite output for any input, and the whole-move checks.

use std::f64::consts::{PI, TAU};
use std::ffi::{CStr, CString, c_char};

use jointspace_klipper::abi::{Move, StepperKinematics};
use jointspace_klipper::machine::Machine;
use jointspace_klipper::{
    jointspace_check_move, jointspace_forward, jointspace_inverse, jointspace_junction_speed,
    jointspace_machine_free, jointspace_machine_new, jointspace_machine_value,
    jointspace_move_waypoints, jointspace_reach_margin, jointspace_stepper_alloc,
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

/// Each base joint of the five-bar follows the tests' own circle–circle inverse (`fivebar_reference`) over a grid
/// of the workspace, keeps its reading's whole turns, and holds the commanded reading where the point has no pose.
#[test]
fn fivebar_joints_follow_the_circle_intersections() {
    use crate::fivebar_reference::{SIDES, angle};
    let m = Owned(machine("fivebar", ""));
    let joints = [
        Stepper::new(m.0, "stepper_left"),
        Stepper::new(m.0, "stepper_right"),
    ];
    let (mut checked, mut worst) = (0, 0.0f64);
    for i in -30..=30 {
        for j in -40..=30 {
            let n = [5.0 * f64::from(i), 5.0 * f64::from(j)];
            for (k, joint) in joints.iter().enumerate() {
                let near = [2.4, 0.8][k];
                let got = joint.at([n[0], n[1], 0.0], near);
                match angle(&SIDES[k], n, near) {
                    Some(expected) => {
                        worst = worst.max((got - expected).abs());
                        checked += 1;
                        // A reading whole turns away keeps its turns.
                        let turned = joint.at([n[0], n[1], 0.0], near + 2.0 * TAU);
                        assert!((turned - (expected + 2.0 * TAU)).abs() < 1e-9, "{n:?}");
                    }
                    None => assert_eq!(got, near, "{n:?}: no pose, the reading holds"),
                }
            }
        }
    }
    println!("five-bar joints: {checked} readings, largest difference {worst:e} rad");
    assert!(checked > 3000, "{checked}");
    assert!(worst < 1e-12, "largest difference {worst} rad");
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
        let fivebar = Owned(machine("fivebar", ""));
        let m = Move { print_time: 0.0, move_t: 2.0, start_v: v, half_accel: 0.0, start_pos: start, axes_r: dir };
        for (machine, motor) in [(&polar, "stepper_bed"), (&polar, "stepper_arm"), (&ideal, "stepper_bed"),
                                 (&ideal, "stepper_arm"), (&scara, "stepper_a"), (&scara, "stepper_b"),
                                 (&scara, "stepper_z"), (&fivebar, "stepper_left"),
                                 (&fivebar, "stepper_right")] {
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
    assert!(
        reason.contains("mm beyond the arm's reach of 150 mm"),
        "{reason}"
    );
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

/// What the plug-in asks instead of reading a `[printer]` key a second time: the value the machine was built with
/// (defaults included), and none for a key this machine does not have.
#[test]
fn the_machine_answers_its_printer_keys() {
    let value = |m: *mut Machine, key: &str| {
        let key = CString::new(key).expect("key");
        let mut v = f64::NAN;
        // SAFETY: a live machine, a valid string and a double.
        let rc = unsafe { jointspace_machine_value(m, key.as_ptr(), &mut v) };
        (rc == 0).then_some(v)
    };
    let polar = machine("polar", "arm_zero_offset: 0.25\narm_lateral_offset: -0.1");
    assert_eq!(value(polar, "arm_zero_offset"), Some(0.25));
    assert_eq!(value(polar, "arm_lateral_offset"), Some(-0.1));
    assert_eq!(value(polar, "max_z_velocity"), Some(20.0));
    assert_eq!(value(polar, "max_z_accel"), Some(100.0));
    assert_eq!(value(polar, "offset_x"), None);
    let scara = machine("scara", "");
    assert_eq!(value(scara, "link1_length"), Some(100.0));
    assert_eq!(value(scara, "link2_length"), Some(100.0));
    assert_eq!(value(scara, "offset_y"), Some(0.0));
    assert_eq!(value(scara, "arm_zero_offset"), None);
    assert_eq!(value(scara, "max_velocity"), None);
    assert_eq!(value(std::ptr::null_mut(), "max_z_accel"), None);
    let fivebar = machine("fivebar", "");
    for (key, expected) in [
        ("left_base_x", Some(-50.0)),
        ("left_base_y", Some(-200.0)),
        ("right_base_x", Some(50.0)),
        ("right_proximal_length", Some(150.0)),
        ("left_distal_length", Some(200.0)),
        ("right_distal_length", Some(200.0)),
        ("left_zero", None),
        ("link1_length", None),
        ("right_", None),
    ] {
        assert_eq!(value(fivebar, key), expected, "{key}");
    }
    for m in [polar, scara, fivebar] {
        // SAFETY: made above, freed once.
        unsafe { jointspace_machine_free(m) };
    }
}

// ---------------------------------------------------------------------------------------------------------------
// Nothing a G-code line or a config value holds crashes the host: the C interface on the example machines of
// `klipper/examples/`, at the poses where the geometry degenerates, with huge, tiny and non-finite numbers.

thread_local! {
    /// Panics on this thread since the hook was installed (the library catches them; the tests count them).
    static PANICS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Runs `f` (inside `catch_unwind`, so a panic that escapes is a failure, not an abort) and counts the panics it
/// raised, caught or not: the library turns a panic into a failure value, which must not pass for an answer.
fn without_panic<T>(what: &str, f: impl FnOnce() -> T) -> T {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            PANICS.with(|p| p.set(p.get() + 1));
            previous(info);
        }));
    });
    let before = PANICS.with(std::cell::Cell::get);
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    let panics = PANICS.with(std::cell::Cell::get) - before;
    match result {
        Ok(v) if panics == 0 => v,
        Ok(_) => panic!("{what}: {panics} panic(s) inside the library (caught there)"),
        Err(_) => panic!("{what}: a panic crossed the C interface"),
    }
}

/// A printer.cfg of `klipper/examples/` as the plug-in hands it over.
fn example(name: &str) -> Owned {
    let path = workspace_root().join(format!("klipper/examples/{name}.cfg"));
    let text =
        CString::new(std::fs::read_to_string(path).expect("example config")).expect("no NUL");
    let mut error = [0 as c_char; 256];
    // SAFETY: valid strings and buffer.
    let m = unsafe { jointspace_machine_new(text.as_ptr(), 0, error.as_mut_ptr(), error.len()) };
    assert!(!m.is_null(), "{}", reason(&error));
    Owned(m)
}

fn reason(error: &[c_char]) -> String {
    // SAFETY: the library NUL-terminates what it writes; the buffers start zeroed.
    unsafe { CStr::from_ptr(error.as_ptr()) }
        .to_string_lossy()
        .into_owned()
}

/// `jointspace_check_move`: (return code, caps, reason).
fn check(
    m: &Owned,
    start: [f64; 3],
    end: [f64; 3],
    speed: f64,
    accel: f64,
) -> (i32, [f64; 2], String) {
    let mut limits = [0.0; 2];
    let mut error = [0 as c_char; 256];
    let rc = without_panic("check_move", || {
        // SAFETY: a live machine, two limit slots, a 256-byte buffer.
        unsafe {
            jointspace_check_move(
                m.0,
                start[0],
                start[1],
                start[2],
                end[0],
                end[1],
                end[2],
                speed,
                accel,
                limits.as_mut_ptr(),
                error.as_mut_ptr(),
                error.len(),
            )
        }
    });
    (rc, limits, reason(&error))
}

/// `jointspace_move_waypoints` (at most 256), cut at span boundaries: the return code and the `(x, y, fraction)`
/// triples written.
fn waypoints(
    m: &Owned,
    start: [f64; 3],
    end: [f64; 3],
    speed: f64,
    accel: f64,
    bed: f64,
) -> (i32, Vec<[f64; 3]>) {
    let (rc, points, _) = waypoints_with_reason(m, [start, end], [speed, accel], bed, true);
    (rc, points)
}

/// `jointspace_move_waypoints` (at most 4096) of the move `ends[0] → ends[1]` at `[speed, accel]`: the return code,
/// the `(x, y, fraction)` triples written and the reason of a refusal.
pub fn waypoints_with_reason(
    m: &Owned,
    [start, end]: [[f64; 3]; 2],
    [speed, accel]: [f64; 2],
    bed: f64,
    cut_spans: bool,
) -> (i32, Vec<[f64; 3]>, String) {
    let mut out = vec![0.0; 3 * 4096];
    let mut error = [0 as c_char; 256];
    let rc = without_panic("move_waypoints", || {
        // SAFETY: a live machine; out holds 3 · 4096 doubles, error 256 bytes.
        unsafe {
            jointspace_move_waypoints(
                m.0,
                start[0],
                start[1],
                start[2],
                end[0],
                end[1],
                end[2],
                speed,
                accel,
                bed,
                i32::from(cut_spans),
                out.as_mut_ptr(),
                4096,
                error.as_mut_ptr(),
                error.len(),
            )
        }
    });
    let n = usize::try_from(rc).unwrap_or(0);
    let points = out.chunks(3).take(n).map(|c| [c[0], c[1], c[2]]).collect();
    (rc, points, reason(&error))
}

/// A refusal or an answer Klipper can apply: −1 with a reason that is not a caught panic, or flags with caps that
/// are positive and finite (only where speed and acceleration were requested).
fn assert_clean_check(
    what: &str,
    (rc, caps, reason): &(i32, [f64; 2], String),
    speed: f64,
    accel: f64,
) {
    match rc {
        -1 => {
            assert!(!reason.is_empty(), "{what}: refused without a reason");
            assert!(!reason.contains("internal error"), "{what}: {reason}");
        }
        0..=3 => {
            if rc & 1 == 1 {
                assert!(
                    speed > 0.0 && accel > 0.0,
                    "{what}: caps for a segment-only check"
                );
                assert!(
                    caps.iter().all(|c| *c > 0.0 && c.is_finite()),
                    "{what}: caps {caps:?}"
                );
                assert!(
                    caps[0] <= speed && caps[1] <= accel,
                    "{what}: caps {caps:?} above the request"
                );
            }
        }
        _ => panic!("{what}: return code {rc}"),
    }
}

/// Waypoints are finite, their fractions grow to exactly 1; or the move is refused (−2, or −1: too many pieces).
fn assert_clean_waypoints(what: &str, (rc, points): &(i32, Vec<[f64; 3]>)) {
    if *rc == -1 || *rc == -2 {
        return;
    }
    assert!(*rc >= 1, "{what}: {rc} waypoints");
    assert!(
        points.iter().flatten().all(|v| v.is_finite()),
        "{what}: {points:?}"
    );
    assert!(
        points.windows(2).all(|w| w[0][2] <= w[1][2]),
        "{what}: fractions {points:?}"
    );
    assert_eq!(points.last().map(|p| p[2]), Some(1.0), "{what}: {points:?}");
}

/// The FEKT example's home pose direction and shoulder direction at its endstops (45° and a 105° elbow motor, in
/// the machine's radians), and the arm's full reach from its link lengths.
fn scara_straight_arm_directions(m: &Owned) -> ([f64; 2], f64) {
    let motors = [45f64.to_radians(), 105f64.to_radians(), 0.0];
    let mut xyz = [0.0; 3];
    let mut error = [0 as c_char; 256];
    // SAFETY: three motors, three coordinates, a 256-byte buffer.
    let rc = unsafe {
        jointspace_forward(
            m.0,
            motors.as_ptr(),
            xyz.as_mut_ptr(),
            error.as_mut_ptr(),
            error.len(),
        )
    };
    assert_eq!(rc, 0, "{}", reason(&error));
    let config = std::fs::read_to_string(workspace_root().join("klipper/examples/scara.cfg"))
        .expect("config");
    let length = |key: &str| -> f64 {
        config
            .lines()
            .find_map(|l| l.strip_prefix(key)?.trim().parse().ok())
            .expect("link length")
    };
    let reach = length("link1_length:") + length("link2_length:");
    ([xyz[1].atan2(xyz[0]), motors[0]], reach)
}

/// Issue (a): a 1e-10 mm move from the SCARA's straight arm, and from points 1e-12..1e-6 mm inside it, put both cuts
/// of `motion::kinematic_limits`' span splitter within its 1e-9 mm tolerance of each other, leaving no span, and
/// the rest fit indexed the empty list (a panic in check_move and move_waypoints, which aborted Klipper).
#[test]
fn a_tiny_move_at_the_straight_arm_is_answered() {
    let m = example("scara");
    let (directions, reach) = scara_straight_arm_directions(&m);
    assert!(
        (directions[0] - PI / 2.0).abs() < 1e-9,
        "home pose along {}",
        directions[0]
    );
    let mut answered = 0;
    for angle in directions {
        let (c, s) = (angle.cos(), angle.sin());
        for inside in [0.0, 1e-12, 1e-11, 1e-10, 1e-9, 1e-8, 1e-7, 1e-6] {
            let start = [(reach - inside) * c, (reach - inside) * s, 1.0];
            for d in [
                [-c, -s, 0.0],
                [c, s, 0.0],
                [-s, c, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ] {
                let end = [0, 1, 2].map(|k| start[k] + 1e-10 * d[k]);
                let what = format!("{angle} rad, {inside} mm inside, along {d:?}");
                let verdict = check(&m, start, end, 150.0, 2000.0);
                assert_clean_check(&what, &verdict, 150.0, 2000.0);
                answered += usize::from(verdict.0 >= 0);
                assert_clean_waypoints(&what, &waypoints(&m, start, end, 150.0, 2000.0, 0.0));
                assert_clean_waypoints(&what, &waypoints(&m, end, start, 150.0, 2000.0, 0.0));
            }
        }
    }
    // The inward moves from inside the reach are legal: they are answered, not refused.
    assert!(answered >= 20, "only {answered} moves answered");
    // Straight in from 1e-6 mm inside the straight arm: it ends at rest beside the singular pose, with a cruise cap
    // the acceleration from rest reaches over the move (positive: Klipper divides by it).
    let start = [0.0, reach - 1e-6, 1.0];
    let (rc, caps, reason) = check(&m, start, [0.0, reach - 1e-6 - 1e-10, 1.0], 150.0, 2000.0);
    assert_eq!(rc, 3, "{reason}");
    assert!(
        caps[0] > 0.0 && caps[0] < (2.0 * 2000.0 * 1e-10f64).sqrt() * 1.001,
        "{caps:?}"
    );
}

/// Issue (b): a move from the polar centre to a coordinate Python reads as infinity (`G1 X1e400`). Inside, the line's
/// direction was NaN (inf/inf) and the bed's curvature bound clamped NaN (a panic in move_waypoints). It is
/// refused at the boundary with the coordinate named, and the machine's own answer no longer panics.
#[test]
fn a_move_from_the_polar_centre_to_infinity_is_refused() {
    let m = example("polar");
    let centre = [0.0, 0.0, 1.0];
    for (end, named) in [
        ([f64::INFINITY, 0.0, 1.0], "X=inf"),
        ([0.0, f64::NEG_INFINITY, 1.0], "Y=-inf"),
        ([f64::INFINITY, 1.0, 1.0], "X=inf"),
        ([0.0, 0.0, f64::NAN], "Z=NaN"),
        ([1e300, 0.0, 1.0], "X=1e300 mm"),
    ] {
        let (rc, _, reason) = check(&m, centre, end, 100.0, 3000.0);
        assert_eq!(rc, -1);
        assert!(reason.contains(named), "{reason}");
        assert!(
            reason.contains("finite coordinate") || reason.contains("beyond any machine"),
            "{reason}"
        );
        assert_eq!(waypoints(&m, centre, end, 100.0, 3000.0, 0.0).0, -2);
        // SAFETY: the machine lives while `m` does.
        let machine = unsafe { &*m.0 };
        let inside = without_panic("Machine::waypoints", || {
            machine.waypoints(centre, end, 100.0, 3000.0, 0.0, true)
        });
        assert!(inside.is_err(), "{inside:?}");
        let refused = without_panic("Machine::check_move", || {
            machine.check_move(centre, end, 100.0, 3000.0)
        });
        assert!(refused.is_err(), "{refused:?}");
    }
    // Speed and acceleration: non-finite is refused, ≤ 0 checks the segment only.
    for (speed, accel, named) in [
        (f64::NAN, 3000.0, "speed=NaN"),
        (100.0, f64::INFINITY, "accel=inf"),
    ] {
        let (rc, _, reason) = check(&m, [10.0, 0.0, 1.0], [20.0, 0.0, 1.0], speed, accel);
        assert_eq!(rc, -1);
        assert!(reason.contains(named), "{reason}");
    }
    let (rc, _, reason) = check(&m, [-100.0, 1.0, 1.0], [100.0, 1.0, 1.0], 0.0, 3000.0);
    assert_eq!(rc, 0, "segment only, no caps: {reason}");
}

/// Issue (c): a move ending in the SCARA's singular band with a 200-digit Z (`Z1e199`): its squared length
/// overflowed, the line's length was infinite, every cut was dropped as non-finite and the rest fit indexed an empty
/// span list. Refused at the boundary as beyond any machine; inside, the line has no length and no spans.
#[test]
fn a_move_into_the_singular_band_with_a_huge_z_is_refused() {
    let m = example("scara");
    let z = "1".to_string() + &"0".repeat(199);
    let z: f64 = z.parse().expect("a number");
    for start in [[0.0, 150.0, 1.0], [20.0, 130.0, 1.0], [0.0, 199.0, 1.0]] {
        for end in [[0.0, 200.0, z], [0.0, 199.9999, z], [0.0, 199.99, -z]] {
            let (rc, _, reason) = check(&m, start, end, 150.0, 2000.0);
            assert_eq!(rc, -1);
            assert!(
                reason.contains("mm is beyond any machine") && reason.starts_with("Z="),
                "{reason}"
            );
            assert!(reason.len() < 40, "the value is written short: {reason}");
            assert_eq!(waypoints(&m, start, end, 150.0, 2000.0, 0.0).0, -2);
            // SAFETY: the machine lives while `m` does.
            let machine = unsafe { &*m.0 };
            let inside = without_panic("Machine::waypoints", || {
                machine.waypoints(start, end, 150.0, 2000.0, 0.0, true)
            });
            assert!(inside.as_ref().map_or(true, |p| p.len() == 1), "{inside:?}");
        }
    }
    // The same move with a Z the machine has is an ordinary answer (it ends at rest in the band).
    let (rc, caps, reason) = check(&m, [0.0, 150.0, 1.0], [0.0, 199.99, 5.0], 150.0, 2000.0);
    assert_eq!(rc, 3, "{reason}");
    assert!(caps[0] > 0.0 && caps[1] > 0.0, "{caps:?}");
}

/// Klipper divides by the caps (`move.limit_speed`): a move whose limits would allow it no speed — one that stays
/// within rounding of the straight arm, where the joints cannot be evaluated — is refused with the reason instead of
/// capped at 0 mm/s (a ZeroDivisionError in Klipper's toolhead); a legal move into the band keeps a positive cap.
#[test]
fn caps_are_positive_or_the_move_is_refused() {
    let m = example("scara");
    let pose = [0.0, 200.0, 1.0];
    for end in [[0.0, 200.0, 1.0 + 1e-10], [1e-10, 200.0, 1.0]] {
        let (rc, caps, reason) = check(&m, pose, end, 150.0, 2000.0);
        assert_eq!(rc, -1, "{caps:?}");
        assert!(reason.contains("allow no speed"), "{reason}");
    }
    // A G-code move to the exact straight arm (`G1 X0 Y200`) ends at rest there, cruising at a positive speed.
    for start in [[0.0, 150.0, 1.0], [20.0, 130.0, 1.0], [0.0, 199.999, 1.0]] {
        let verdict = check(&m, start, pose, 150.0, 2000.0);
        assert_clean_check(
            &format!("{start:?} to the straight arm"),
            &verdict,
            150.0,
            2000.0,
        );
        assert_eq!(verdict.0 & 2, 2, "{start:?}: {}", verdict.2);
    }
    for length in [1e-12, 1e-9, 1e-6, 1e-3, 1.0, 50.0] {
        let start = [0.0, 199.99 - length, 1.0];
        let verdict = check(&m, start, [0.0, 199.99, 1.0], 150.0, 2000.0);
        assert_clean_check(
            &format!("{length} mm into the band"),
            &verdict,
            150.0,
            2000.0,
        );
        assert_eq!(verdict.0, 3, "{length}: {}", verdict.2);
    }
}

/// The example machines, built once and shared by every case (a machine is immutable, its answers reentrant);
/// never freed, they live as long as the test binary.
const KINDS: [&str; 3] = ["polar", "scara", "fivebar"];

fn shared_examples() -> [&'static Owned; 3] {
    static MACHINES: std::sync::OnceLock<[usize; 3]> = std::sync::OnceLock::new();
    let addresses =
        MACHINES.get_or_init(|| KINDS.map(|name| Box::into_raw(Box::new(example(name))) as usize));
    // SAFETY: boxes leaked above, never freed or written.
    addresses.map(|a| unsafe { &*(a as *const Owned) })
}

// SAFETY (for the shared machines): `Owned` holds a pointer to an immutable `Machine`, whose answers take `&self`.
unsafe impl Sync for Owned {}
// SAFETY: as above; the machine is freed only by the thread that drops the `Owned`, once.
unsafe impl Send for Owned {}

/// A number a G-code line or a host may hand over that no machine can use, or only just.
fn wild() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(0.0),
        Just(-0.0),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        Just(5e-324),
        Just(1e9),
        Just(-1e9 - 1.0),
        (-320.0..308.0f64).prop_map(|e| 10f64.powf(e)),
        (-320.0..308.0f64).prop_map(|e| -(10f64.powf(e))),
    ]
}

/// Distances from a special pose (mm) where rounding and tolerances meet.
const NEAR: [f64; 6] = [0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-3];

/// A point near one of the machine's special poses (`kind` indexes [`KINDS`]): the polar centre; the SCARA's
/// straight arm (full reach) or folded arm (its shoulder, with equal links); the five-bar's left or right arm
/// straight (350 mm from its base joint) or folded (50 mm); at `NEAR` distances inside or beside them.
fn near_pose(kind: usize, which: usize, angle: f64, near: usize, beside: f64, z: f64) -> [f64; 3] {
    let d = NEAR[near % NEAR.len()];
    let (c, s) = (angle.cos(), angle.sin());
    let (centre, r) = match kind {
        1 if which.is_multiple_of(2) => ([0.0, 0.0], 200.0 - d),
        2 => {
            let base = if which < 2 {
                [-50.0, -200.0]
            } else {
                [50.0, -200.0]
            };
            (
                base,
                if which.is_multiple_of(2) {
                    350.0 - d
                } else {
                    50.0 + d
                },
            )
        }
        _ => ([0.0, 0.0], d),
    };
    [
        centre[0] + r * c - beside * s * d,
        centre[1] + r * s + beside * c * d,
        z,
    ]
}

/// The move's end: along a direction by a length from 1e-12 to 1e3 mm, to another special point, or wild.
#[derive(Debug, Clone)]
enum EndKind {
    Along {
        log_length: f64,
        azimuth: f64,
        elevation: f64,
    },
    Pose {
        which: usize,
        angle: f64,
        near: usize,
    },
    Wild([f64; 3]),
}

fn end_kind() -> impl Strategy<Value = EndKind> {
    prop_oneof![
        4 => (-12.0..3.0f64, -PI..PI, prop_oneof![Just(0.0), Just(PI / 2.0), -PI / 2.0..PI / 2.0])
            .prop_map(|(log_length, azimuth, elevation)| EndKind::Along { log_length, azimuth, elevation }),
        2 => (0..4usize, -PI..PI, 0..6usize).prop_map(|(which, angle, near)| EndKind::Pose { which, angle, near }),
        1 => prop::array::uniform3(prop_oneof![wild(), -300.0..300.0f64]).prop_map(EndKind::Wild),
    ]
}

fn end_of(kind: &EndKind, machine: usize, start: [f64; 3]) -> [f64; 3] {
    match *kind {
        EndKind::Along {
            log_length,
            azimuth,
            elevation,
        } => {
            let length = 10f64.powf(log_length);
            let dir = [
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
            ];
            [0, 1, 2].map(|k| start[k] + length * dir[k])
        }
        EndKind::Pose { which, angle, near } => {
            near_pose(machine, which, angle, near, 0.0, start[2])
        }
        EndKind::Wild(p) => p,
    }
}

/// Every answer is finite or a clean refusal: `inverse` gives finite motors or −1 with a reason, `forward` of them
/// a finite point, `reach_margin` a finite margin or −1.
fn assert_pose_answers(m: &Owned, p: [f64; 3], previous: [f64; 3], what: &str) {
    let mut motors = [0.0; 3];
    let mut xyz = [0.0; 3];
    let mut margin = 0.0;
    let mut error = [0 as c_char; 256];
    for previous in [std::ptr::null(), previous.as_ptr()] {
        let rc = without_panic("inverse", || {
            // SAFETY: three coordinates, three motors (the examples have three), a 256-byte buffer.
            unsafe {
                jointspace_inverse(
                    m.0,
                    p.as_ptr(),
                    previous,
                    motors.as_mut_ptr(),
                    error.as_mut_ptr(),
                    error.len(),
                )
            }
        });
        match rc {
            0 => assert!(
                motors.iter().all(|v| v.is_finite()),
                "{what}: inverse {motors:?}"
            ),
            -1 => assert!(
                !reason(&error).is_empty(),
                "{what}: inverse refused without a reason"
            ),
            _ => panic!("{what}: inverse returned {rc}"),
        }
        let rc = without_panic("forward", || {
            // SAFETY: three motors, three coordinates, a 256-byte buffer.
            unsafe {
                jointspace_forward(
                    m.0,
                    previous_or(previous, &motors),
                    xyz.as_mut_ptr(),
                    error.as_mut_ptr(),
                    error.len(),
                )
            }
        });
        match rc {
            0 => assert!(xyz.iter().all(|v| v.is_finite()), "{what}: forward {xyz:?}"),
            -1 => assert!(
                !reason(&error).is_empty(),
                "{what}: forward refused without a reason"
            ),
            _ => panic!("{what}: forward returned {rc}"),
        }
    }
    let rc = without_panic("reach_margin", || {
        // SAFETY: one double.
        unsafe { jointspace_reach_margin(m.0, p[0], p[1], p[2], &mut margin) }
    });
    assert!(
        rc == -1 || (rc == 0 && margin.is_finite()),
        "{what}: reach_margin {rc} {margin}"
    );
}

/// The motors `forward` reads: the wild `previous` when given, else what `inverse` wrote.
fn previous_or(previous: *const f64, motors: &[f64; 3]) -> *const f64 {
    if previous.is_null() {
        motors.as_ptr()
    } else {
        previous
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]
    /// Whatever move a G-code line asks for near the poses where the geometry degenerates (the polar centre, the
    /// SCARA's and the five-bar's straight and folded arms), at lengths from 1e-12 to 1e3 mm, or with huge, tiny and non-finite
    /// numbers: no panic (caught or not), and every answer finite or a clean −1 with a reason.
    #[test]
    fn the_c_interface_answers_every_move_near_the_special_poses(
        kind in 0..3usize,
        start_kind in 0..4usize,
        (which, angle, near, beside) in (0..4usize, -PI..PI, 0..6usize, -1.0..1.0f64),
        z in prop_oneof![Just(1.0), 0.0..200.0f64, wild()],
        wild_start in prop::array::uniform3(wild()),
        end in end_kind(),
        corner in end_kind(),
        speed in prop_oneof![Just(150.0), 1e-6..1e4f64, Just(0.0), -10.0..0.0f64, wild()],
        accel in prop_oneof![Just(2000.0), 1e-6..1e6f64, Just(0.0), wild()],
        bed_angle in prop_oneof![-10.0..10.0f64, wild()],
        previous in prop::array::uniform3(prop_oneof![-7.0..7.0f64, wild()]),
    ) {
        let m = shared_examples()[kind];
        let start = match start_kind {
            0 | 1 => near_pose(kind, which, angle, near, beside, z),
            2 => wild_start,
            _ => [200.0 * beside, 200.0 * angle.sin(), z],
        };
        let end = end_of(&end, kind, start);
        let what = format!("{} {start:?} -> {end:?} at {speed}, {accel}", KINDS[kind]);
        assert_clean_check(&what, &check(m, start, end, speed, accel), speed, accel);
        assert_clean_waypoints(&what, &waypoints(m, start, end, speed, accel, bed_angle));
        let next = end_of(&corner, kind, end);
        let points = [start, end, next].concat();
        let v = without_panic("junction_speed", || {
            // SAFETY: nine doubles.
            unsafe { jointspace_junction_speed(m.0, points.as_ptr(), accel, accel) }
        });
        prop_assert!(v >= 0.0, "{what}: junction {v}");
        assert_pose_answers(m, end, previous, &what);
        assert_pose_answers(m, start, previous, &what);
    }
}

/// Found by the `klipper_abi` fuzz target: a move with a non-finite start and direction (an infinite Y, a NaN time)
/// took the ideal polar bed's solver through its near-centre branch (`distance² >= NEAR²` is false for NaN) to NaN.
/// The callback now holds the commanded reading for anything that is not a finite position.
#[test]
fn a_non_finite_move_leaves_every_motor_where_it_was_commanded() {
    let m = example("polar");
    let mv = Move {
        print_time: 0.0,
        move_t: f64::NAN,
        start_v: 0.0,
        half_accel: f64::NAN,
        start_pos: [-374.4, f64::INFINITY, 1.0],
        axes_r: [0.0, f64::NAN, 0.0],
    };
    for motor in ["stepper_bed", "stepper_arm", "stepper_z"] {
        let s = Stepper::new(m.0, motor);
        for t in [f64::NAN, 0.0, 1.0] {
            assert_eq!(s.on(&mv, t, 0.25), 0.25, "{motor} at {t}");
        }
    }
}
