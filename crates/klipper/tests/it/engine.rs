//! The plug-in inside Klipper against jointspace's own engine (`jointspace run --klipper-batch`) on the same
//! printer.cfg: one SCARA print and one polar print with both assembly offsets, exact mode. Two step generators
//! (Klipper's itersolve over our solver; jointspace's own) must agree step for step.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use jointspace_klipper::abi::Move;
use jointspace_klipper::machine::Machine;
use stepgen::read_moves_csv;
use trapq::{Piece, Queue};

use crate::hosts::{
    Hosts, KLIPPER, Step, cargo_build, compare, plugin_config, read_step_dir, shared, target_dir,
};

/// The `jointspace` binary (built by the workspace's tests; built here if this crate is tested alone).
pub fn jointspace() -> PathBuf {
    cargo_build("cli");
    target_dir().join("jointspace")
}

/// Runs the `jointspace` command line with `args`; panics with its output unless it succeeds.
pub fn run_jointspace<I, A>(args: I) -> Output
where
    I: IntoIterator<Item = A>,
    A: AsRef<OsStr>,
{
    let output = Command::new(jointspace())
        .args(args)
        .output()
        .expect("jointspace runs");
    assert!(
        output.status.success(),
        "jointspace failed: {}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// The toolhead's pieces of a moves CSV (jointspace's own reader of Klipper's `trapq_append` columns).
fn toolhead_pieces(path: &Path) -> Vec<Piece> {
    read_moves_csv(path)
        .expect("moves CSV")
        .iter()
        .filter(|(q, _)| *q == Queue::Toolhead)
        .flat_map(|(_, m)| m.pieces())
        .collect()
}

/// The toolhead at print time `t` as Klipper's trapq holds it: the piece as a `Move`, and the time into it.
fn phase_at(pieces: &[Piece], t: f64) -> Option<(Move, f64)> {
    let p = pieces
        .iter()
        .rev()
        .find(|p| p.print_time <= t && t <= p.end_time())?;
    let phase = Move {
        print_time: p.print_time,
        move_t: p.duration,
        start_v: p.start_v,
        half_accel: p.half_accel,
        start_pos: p.start_pos,
        axes_r: p.axes_r,
    };
    Some((phase, t - p.print_time))
}

/// Steps over a tick apart must be ones where Klipper's own search stops short: its itersolve accepts a time
/// where the motor is within 1e-9 (motor units) of the half-step level, which near a turning point of the motor
/// (its position flat in time) spans several ticks. The motor's ideal position at Klipper's clock is computed
/// here from the planned moves through the library's solver.
fn assert_within_klippers_tolerance(
    test: &str,
    config: &Path,
    start: [f64; 3],
    klipper: &std::collections::BTreeMap<String, Vec<Step>>,
    engine: &std::collections::BTreeMap<String, Vec<Step>>,
    moves: &[Piece],
) {
    let text = std::fs::read_to_string(config).expect("config");
    let machine = Machine::from_config_text(&text, false).expect("machine");
    for (name, theirs) in klipper {
        let Some(solver) = machine.solver(name) else {
            continue;
        };
        let kin = machine.kinematics();
        let index = kin
            .motors()
            .iter()
            .position(|m| &m.name == name)
            .expect("motor");
        let step_dist = kin.motors()[index].step_distance;
        let resting = Move {
            print_time: 0.0,
            move_t: 1.0,
            start_v: 0.0,
            half_accel: 0.0,
            start_pos: start,
            axes_r: [0.0; 3],
        };
        let origin = solver.position(&resting, 0.0, 0.0, false);
        let mut net = 0i64;
        for (i, (k, e)) in theirs.iter().zip(&engine[name]).enumerate() {
            let level = origin + (net as f64 + if k.1 == 1 { 0.5 } else { -0.5 }) * step_dist;
            if (k.0 - e.0).abs() > 1 {
                let commanded = origin + net as f64 * step_dist;
                let at = |clock: f64| {
                    let (m, t) = phase_at(moves, clock / 16e6).expect("a planned move at the step");
                    solver.position(&m, t, commanded, false) - level
                };
                let clock = k.0 as f64;
                let (lo, mid, hi) = (at(clock - 0.5), at(clock), at(clock + 0.5));
                let slack = (hi - lo).abs() * 0.5;
                assert!(
                    mid.abs() <= 1e-9 + slack + 1e-12,
                    "{test}: {name} step {i}: Klipper {} vs engine {} ticks, {mid:e} from the level",
                    k.0,
                    e.0
                );
            }
            net += if k.1 == 1 { 1 } else { -1 };
        }
    }
}

fn compare_with_engine(test: &str, config: &Path, start: [f64; 3], gcode: &Path, dir: &Path) {
    let Some(hosts) = Hosts::get(test) else {
        return;
    };
    let run = hosts.batch(KLIPPER, true, config, gcode, &dir.join("klipper"));
    run.expect_success(test);
    let ours = dir.join("engine");
    let moves = dir.join("moves.csv");
    run_jointspace([
        OsStr::new("run"),
        OsStr::new("-c"),
        config.as_os_str(),
        OsStr::new("--klipper-batch"),
        OsStr::new("--steps"),
        ours.as_os_str(),
        OsStr::new("--moves"),
        moves.as_os_str(),
        gcode.as_os_str(),
    ]);
    let (klipper, engine) = (run.steps(), read_step_dir(&ours));
    let mut beyond = 0;
    for (name, steps) in &klipper {
        let c = compare(steps, &engine[name], 1);
        assert!(
            c.counts.0 == c.counts.1 && c.same_directions,
            "{test}: {name}: {c:?}"
        );
        beyond += c.beyond_tolerance;
    }
    assert_within_klippers_tolerance(
        test,
        config,
        start,
        &klipper,
        &engine,
        &toolhead_pieces(&moves),
    );
    println!(
        "{test}: plug-in in Klipper and jointspace run: same steps and directions, clocks within 1 tick \
         except {beyond} at Klipper's own search tolerance"
    );
}

#[test]
fn scara_print_matches_the_engine() {
    let dir = tempfile::tempdir().expect("temp dir");
    let case = shared().join("golden/scara-fekt-synthetic");
    if !case.is_dir() {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            case.display()
        );
        println!(
            "scara_print_matches_the_engine: skipped: {} is absent",
            case.display()
        );
        return;
    }
    let config = plugin_config(
        &case.join("printer.cfg"),
        &[("kinematics: scara", "kinematics: jointspace_scara")],
        dir.path(),
        "printer.cfg",
    );
    compare_with_engine(
        "scara_print_matches_the_engine",
        &config,
        [0.0, 130.0, 0.5],
        &case.join("input.gcode"),
        dir.path(),
    );
}

#[test]
fn polar_print_with_offsets_matches_the_engine() {
    let dir = tempfile::tempdir().expect("temp dir");
    let case = shared().join("golden/polar-synthetic");
    if !case.is_dir() {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            case.display()
        );
        println!(
            "polar_print_with_offsets_matches_the_engine: skipped: {} is absent",
            case.display()
        );
        return;
    }
    // The arm's zero 0.4 mm past the centre (so its position stays positive everywhere) and its line 0.2 mm
    // beside it: no closed form, the general solver on both sides. The case passes no closer than 0.3 mm to
    // the centre, outside the 0.2 mm circle the arm cannot reach.
    let config = plugin_config(
        &case.join("printer.cfg"),
        &[
            (
                "kinematics: polar",
                "kinematics: jointspace_polar\narm_zero_offset: -0.4\narm_lateral_offset: 0.2",
            ),
            // The start pose X300 puts the arm 0.4 mm further out.
            ("position_max: 300", "position_max: 301"),
            // Klipper's rule lets this bed (no angular limit) step at 533,000 steps/s near the centre: a board
            // with 100 ns step pulses (TMC drivers) can, one with Klipper's default 2 µs cannot.
            (
                "gear_ratio: 80:16",
                "gear_ratio: 80:16\nstep_pulse_duration: 0.0000001",
            ),
        ],
        dir.path(),
        "printer.cfg",
    );
    compare_with_engine(
        "polar_print_with_offsets_matches_the_engine",
        &config,
        [300.0, 0.0, 0.5],
        &case.join("input.gcode"),
        dir.path(),
    );
}

/// The five-bar: a slicer's part (KISSlicer's cube about the origin, 361 s) from a declared pose. The plug-in's
/// solvers follow each base joint's closed form; jointspace's engine steps the same joints with its bracketed solver
/// over the whole inverse. (A part whose motor idles over 2³² ticks, 268 s, cannot be compared: the step files
/// decoded from the host's 32-bit MCU clocks lose those turns of the clock.)
#[test]
fn fivebar_print_matches_the_engine() {
    let corpus = shared().join("corpus");
    if !corpus.is_dir() {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "the shared corpus is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)"
        );
        println!("fivebar_print_matches_the_engine: skipped: the shared corpus is absent");
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let config = crate::fivebar::example_config(
        dir.path(),
        "printer.cfg",
        // The part is sliced for 255 °C and lines up to 12 mm² in cross-section.
        &[
            (
                "max_extrude_cross_section: 1.0",
                "max_extrude_cross_section: 12",
            ),
            ("max_temp: 250", "max_temp: 300"),
        ],
        "\n[force_move]\nenable_force_move: True\n",
    );
    let part = std::fs::read_to_string(corpus.join("kisslicer-1.1_cube-centred.gcode"))
        .expect("corpus file");
    let gcode = crate::hosts::write(
        dir.path(),
        "part.gcode",
        &format!("SET_KINEMATIC_POSITION X=0 Y=0 Z=0.3\n{part}\nM400\n"),
    );
    compare_with_engine(
        "fivebar_print_matches_the_engine",
        &config,
        [0.0, 0.0, 0.3],
        &gcode,
        dir.path(),
    );
}
