//! What the printer executes at a five-bar's special curves: lines that end at and leave each side stretched straight
//! and folded (1e-9, 1e-6, 1e-3, 0.1 and 1 mm short of the curve) and the edge of the parallel band (the distal
//! links near in line: the same offsets outside the band, which is refused everywhere), from several directions, on
//! `klipper/examples/fivebar.cfg`, in Klipper, Kalico and the FEKT-SCARA fork with step compression off, with and
//! without span cuts and the input shaper. Each run's MCU stream is audited as an MCU runs it: the host did not shut
//! down, no two steps of a motor on one clock, none the same way faster than `max_joint_velocity`, and (without the
//! shaper, which rounds the path's corners by design) every step within one step of where the tests' own inverse
//! puts the motors along the path; with the shaper the motors end where the path ends.
//!
//! The cases are found by the tests' geometry: each serial curve's point on a ray from its base joint (every 1°),
//! approached on the line from home; the parallel band's edge on a ray from a point below home (every 0.25°: with the
//! example's joint limits the band is met only in a pocket between the arms' folded bands); every case whose whole
//! approach the margin and the joint limits allow. CI samples three per curve; `fivebar_full_grid` (ignored;
//! `-- --ignored fivebar_full_grid`) takes them all.

use std::path::{Path, PathBuf};

use crate::fivebar::example_config;
use crate::fivebar_reference::{
    MARGIN, MOTORS, SIDES, angles, audit_path, degrees_from, reference_counts, sines,
};
use crate::hosts::{Hosts, KALICO, KALICO_FEKT, KLIPPER, Run, tail, write};

const OFFSETS: [f64; 5] = [1e-9, 1e-6, 1e-3, 0.1, 1.0];
/// Where every case starts and ends: the example's homed pose, rounded.
const HOME: [f64; 2] = [0.0, -37.6];
/// Where the rays to the parallel band start: with the example's joint limits the band is met only in a pocket
/// below it, between the two arms' folded bands.
const POCKET: [f64; 2] = [0.0, -150.0];
/// The example's joint limits (degrees of reading), and the lower end of each side's reading window.
const LIMITS: [(f64, f64); 2] = [(60.0, 210.0), (-30.0, 120.0)];
const WINDOW_LOW: [f64; 2] = [-45.0, -135.0];

/// One special curve: a side stretched straight, a side folded, or the edge of the parallel band.
#[derive(Clone, Copy, Debug)]
enum Curve {
    Straight(usize),
    Folded(usize),
    Parallel,
}

fn at(base: [f64; 2], r: f64, deg: f64) -> [f64; 2] {
    let (s, c) = deg.to_radians().sin_cos();
    [base[0] + r * c, base[1] + r * s]
}

/// Whether the nozzle may be at `n` (the side `exempt`, if any, may be in its serial band: the move rests there).
fn allowed(n: [f64; 2], exempt: Option<usize>) -> bool {
    let (Some(a), Some((arm, parallel))) = (angles(n, [2.4, 0.8]), sines(n)) else {
        return false;
    };
    let within = (0..2).all(|k| {
        let deg = degrees_from(a[k], WINDOW_LOW[k]);
        LIMITS[k].0 <= deg && deg <= LIMITS[k].1
    });
    let bands = (0..2).all(|k| Some(k) == exempt || arm[k] >= MARGIN);
    within && bands && parallel >= MARGIN
}

/// Every point of `a → b` allowed, at 0.05 mm spacing (the last `rest` fraction may lie in side `exempt`'s band).
fn segment_allowed(a: [f64; 2], b: [f64; 2], exempt: Option<usize>) -> bool {
    let n = ((b[0] - a[0]).hypot(b[1] - a[1]) / 0.05).ceil().max(1.0) as usize;
    (0..=n).all(|i| {
        let t = i as f64 / n as f64;
        let p = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
        allowed(p, exempt.filter(|_| t > 0.5))
    })
}

/// The approach to `curve` along the ray at `deg`: (start of the approach, the curve's point on the ray, the unit
/// direction towards the curve), or `None` where the ray does not meet it.
fn approach(curve: Curve, deg: f64) -> Option<([f64; 2], [f64; 2], [f64; 2])> {
    match curve {
        Curve::Straight(k) => {
            let side = &SIDES[k];
            Some(towards_home(at(
                side.base,
                side.proximal + side.distal,
                deg,
            )))
        }
        Curve::Folded(k) => {
            let side = &SIDES[k];
            Some(towards_home(at(
                side.base,
                (side.proximal - side.distal).abs(),
                deg,
            )))
        }
        Curve::Parallel => {
            // From the pocket along the ray until the distal links' sine falls to the margin, found by bisection.
            let inside = |r: f64| sines(at(POCKET, r, deg)).is_some_and(|(_, p)| p >= MARGIN);
            let mut r = 0.0;
            while inside(r + 1.0) && r < 400.0 {
                r += 1.0;
            }
            let (mut lo, mut hi) = (r, r + 1.0);
            // A ray that leaves the reach before the band does not meet it.
            sines(at(POCKET, hi, deg))?;
            while hi - lo > 1e-13 {
                let mid = 0.5 * (lo + hi);
                if inside(mid) { lo = mid } else { hi = mid }
            }
            let (s, c) = deg.to_radians().sin_cos();
            Some((
                at(POCKET, (lo - 40.0).max(0.0), deg),
                at(POCKET, lo, deg),
                [c, s],
            ))
        }
    }
}

/// A serial curve's point approached from home: from 40 mm before it on the line from home.
fn towards_home(point: [f64; 2]) -> ([f64; 2], [f64; 2], [f64; 2]) {
    let (dx, dy) = (point[0] - HOME[0], point[1] - HOME[1]);
    let length = dx.hypot(dy);
    let dir = [dx / length, dy / length];
    let start = [point[0] - 40.0 * dir[0], point[1] - 40.0 * dir[1]];
    (start, point, dir)
}

fn exempt_side(curve: Curve) -> Option<usize> {
    match curve {
        Curve::Straight(k) | Curve::Folded(k) => Some(k),
        Curve::Parallel => None,
    }
}

/// The case's path from home: to the approach's start, to each offset short of the curve and back, home.
fn case_path(curve: Curve, deg: f64) -> Option<Vec<[f64; 2]>> {
    let (start, point, dir) = approach(curve, deg)?;
    let exempt = exempt_side(curve);
    let mut path = vec![HOME, start];
    for d in OFFSETS {
        let p = [point[0] - d * dir[0], point[1] - d * dir[1]];
        if !allowed(p, exempt) || !segment_allowed(start, p, exempt) {
            return None;
        }
        path.extend([p, start]);
    }
    segment_allowed(HOME, start, None).then_some(())?;
    path.push(HOME);
    Some(path)
}

/// The rays (degrees) each curve is met along whose whole case is allowed.
fn rays(curve: Curve) -> Vec<f64> {
    let candidates: Vec<f64> = match curve {
        // The pocket spans a few tens of degrees about straight down.
        Curve::Parallel => (0..240).map(|i| 240.037 + 0.25 * f64::from(i)).collect(),
        _ => (0..360).map(|d| f64::from(d) + 0.37).collect(),
    };
    candidates
        .into_iter()
        .filter(|&d| case_path(curve, d).is_some())
        .collect()
}

const CURVES: [Curve; 5] = [
    Curve::Straight(0),
    Curve::Straight(1),
    Curve::Folded(0),
    Curve::Folded(1),
    Curve::Parallel,
];

/// Every curve's cases, `per_curve` rays spread over those allowed (all of them for `None`): the whole path.
fn grid_path(per_curve: Option<usize>) -> Vec<[f64; 2]> {
    let mut path = vec![HOME];
    for curve in CURVES {
        let all = rays(curve);
        assert!(
            all.len() >= 3,
            "{curve:?}: only {} rays reach it: {all:?}",
            all.len()
        );
        let chosen: Vec<f64> = match per_curve {
            Some(n) => (0..n)
                .map(|i| all[i * (all.len() - 1) / (n - 1).max(1)])
                .collect(),
            None => all,
        };
        println!("{curve:?}: {} rays, {chosen:?}", chosen.len());
        for deg in chosen {
            path.extend(
                case_path(curve, deg)
                    .expect("an allowed case")
                    .into_iter()
                    .skip(1),
            );
        }
    }
    path
}

fn grid_gcode(path: &[[f64; 2]]) -> String {
    let mut g = format!(
        "SET_KINEMATIC_POSITION X={} Y={} Z=1\nG90\nG1 F6000\n",
        path[0][0], path[0][1]
    );
    for p in &path[1..] {
        g.push_str(&format!("G1 X{:.17} Y{:.17}\n", p[0], p[1]));
    }
    g + "M400\n"
}

fn config(dir: &Path, name: &str, split: bool, shaper: bool) -> PathBuf {
    let mut extra = String::from("\n[force_move]\nenable_force_move: True\n");
    if shaper {
        extra
            .push_str("\n[input_shaper]\nshaper_freq_x: 40\nshaper_freq_y: 40\nshaper_type: mzv\n");
    }
    let split_line = if split {
        "[jointspace]"
    } else {
        "[jointspace]\nsplit_moves: False"
    };
    example_config(dir, name, &[("[jointspace]", split_line)], &extra)
}

fn audit(what: &str, run: &Run, path: &[[f64; 2]], shaper: bool) {
    assert!(
        run.success && !run.log.contains("shutdown"),
        "{what}: klippy failed; log ends:\n{}",
        tail(&run.log, 30)
    );
    let steps = run.steps();
    let streams = MOTORS.map(|m| steps.get(m).cloned().unwrap_or_default());
    for (motor, stream) in MOTORS.iter().zip(&streams) {
        let net = crate::centre_grid::audit_motor(
            &format!("{what}: {motor}"),
            stream,
            crate::fivebar_reference::MOTOR_STEP,
            crate::fivebar_reference::MAX_JOINT_VELOCITY,
        );
        assert_eq!(net, 0, "{what}: {motor} ends {net} steps from home");
    }
    if shaper {
        println!(
            "{what}: {} + {} steps, back home",
            streams[0].len(),
            streams[1].len()
        );
        return;
    }
    let reference = reference_counts(path);
    let audit = audit_path(what, [&streams[0], &streams[1]], 0, &reference);
    println!(
        "{what}: {} steps along {} reference states, {} within one step, the rest exact",
        audit.states,
        reference.len(),
        audit.off_by_one
    );
}

fn grid_in(host: &str, variants: &[(bool, bool)], per_curve: Option<usize>) {
    let Some(hosts) = Hosts::get("fivebar_grid") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let path = grid_path(per_curve);
    let input = write(dir.path(), "grid.gcode", &grid_gcode(&path));
    for &(split, shaper) in variants {
        let name = format!(
            "{}{}",
            if split { "split" } else { "whole-moves" },
            if shaper { "+shaper" } else { "" }
        );
        let cfg = config(dir.path(), &format!("{name}.cfg"), split, shaper);
        let started = std::time::Instant::now();
        let run = hosts.batch(host, true, &cfg, &input, &dir.path().join(&name));
        audit(&format!("{host} {name}"), &run, &path, shaper);
        println!("{host} {name}: {:.1} s", started.elapsed().as_secs_f64());
    }
}

#[test]
fn fivebar_grid_completes_in_klipper() {
    grid_in(
        KLIPPER,
        &[(true, false), (false, false), (true, true)],
        Some(3),
    );
}

#[test]
fn fivebar_grid_completes_in_kalico_and_the_fekt_fork() {
    grid_in(KALICO, &[(true, false), (false, true)], Some(3));
    grid_in(KALICO_FEKT, &[(true, false)], Some(3));
}

/// Every allowed ray at 1° spacing, in all three hosts (several minutes).
#[test]
#[ignore]
fn fivebar_full_grid() {
    grid_in(
        KLIPPER,
        &[(true, false), (false, false), (true, true)],
        None,
    );
    grid_in(KALICO, &[(true, false), (false, true)], None);
    grid_in(KALICO_FEKT, &[(true, false), (false, false)], None);
}

/// The grid's own geometry finds what it claims: each curve's point is on the curve (a side at its full or folded
/// reach; the distal links' sine at the margin) and the approach's start keeps clear of it.
#[test]
fn the_grid_meets_each_curve() {
    for curve in CURVES {
        let rays = rays(curve);
        println!("{curve:?}: {} rays", rays.len());
        assert!(rays.len() >= 3, "{curve:?}: {rays:?}");
        for deg in rays {
            let (start, point, dir) = approach(curve, deg).expect("an approach");
            let beside = [point[0] - 1e-9 * dir[0], point[1] - 1e-9 * dir[1]];
            let (arm, parallel) = sines(beside).expect("a pose beside the curve");
            match curve {
                Curve::Straight(k) | Curve::Folded(k) => {
                    assert!(arm[k] < 1e-5, "{curve:?} {deg}: {arm:?}")
                }
                Curve::Parallel => assert!((parallel - MARGIN).abs() < 1e-9, "{deg}: {parallel}"),
            }
            assert!(
                allowed(start, None),
                "{curve:?} {deg}: the approach starts in a band"
            );
        }
    }
}
