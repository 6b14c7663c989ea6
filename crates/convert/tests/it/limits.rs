//! Motor speed limits: the written feeds, re-read with the G-code reader and timed as a firmware times them
//! (F over the written axes' combined distance, or G93 inverse time), never drive a limited motor faster than
//! its limit; verification reports the time the written feeds take.

use std::sync::Arc;

use convert::{
    AngleUnit, AxisMap, ConvertOptions, FeedMode, MotorLimit, Segmentation, Target, VerifyReport,
};
use gcode::{CommandWord, Reader};
use kinematics::Kinematics;

use crate::common::{corpus_files, homed, placement, round_trip};
use crate::machines;

/// Written units per radian of an angle axis.
const DEG: f64 = 180.0 / std::f64::consts::PI;

/// What the written file makes the machine do, read line by line as a firmware reads it.
#[derive(Debug, Default)]
struct Replayed {
    /// Seconds of every timed line, from its written F.
    time: f64,
    /// Fastest speed (written units per second) of each planar axis over the timed lines.
    fastest: [f64; 2],
    /// Fastest speed of each planar axis as a share of `limit` (rad or mm per second, in internal units).
    worst_share: [f64; 2],
}

/// Replays `out` (absolute axes, relative E: the converter's header) with letters X Y; `per_unit` turns a
/// written planar unit into internal units (rad for degrees), `limit` is each planar axis' speed limit.
fn replay(out: &str, per_unit: [f64; 2], limit: [f64; 2]) -> Replayed {
    let mut r = Replayed::default();
    let mut reader = Reader::new(out.as_bytes(), "written.gcode");
    let (mut pos, mut feed, mut inverse) = ([0.0f64; 3], 0.0f64, false);
    while let Some(line) = reader.next_line() {
        let line = line.expect("the written file reads");
        let Some(CommandWord::Code {
            letter: b'G',
            major,
            ..
        }) = line.command()
        else {
            continue;
        };
        match major {
            93 => inverse = true,
            94 => inverse = false,
            0 | 1 => {
                let before = pos;
                for (i, l) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                    if let Some(v) = line.word(l).and_then(|w| w.value) {
                        pos[i] = v;
                    }
                }
                if let Some(f) = line.word(b'F').and_then(|w| w.value) {
                    feed = f;
                }
                if major == 0 {
                    continue; // positioning: no F, not timed
                }
                let d: Vec<f64> = (0..3).map(|i| pos[i] - before[i]).collect();
                let length = d.iter().map(|x| x * x).sum::<f64>().sqrt();
                let e = line.word(b'E').and_then(|w| w.value).unwrap_or(0.0).abs();
                let time = if inverse {
                    60.0 / feed
                } else {
                    60.0 * if length > 0.0 { length } else { e } / feed
                };
                assert!(time.is_finite() && time > 0.0, "{}", line.text());
                r.time += time;
                for i in 0..2 {
                    let speed = d[i].abs() / time;
                    r.fastest[i] = r.fastest[i].max(speed);
                    r.worst_share[i] = r.worst_share[i].max(speed * per_unit[i] / limit[i]);
                }
            }
            _ => {}
        }
    }
    r
}

fn motor(kin: &dyn Kinematics, name: &str) -> usize {
    kin.motors()
        .iter()
        .position(|m| m.name == name)
        .expect("the motor exists")
}

fn limit(motor: usize, v: f64) -> MotorLimit {
    MotorLimit {
        motor,
        max_velocity: Some(v),
        max_accel: None,
    }
}

/// Travels passing 1e-6, 1e-3 and 0.1 mm from the polar centre (both sides of the centre's tolerance), fast,
/// and printing lines through the same places.
const NEAR_CENTRE: &[u8] =
    b"G1 X-30 Y0.000001 F12000\nG1 X30 Y0.000001\nG1 X30 Y0.001\nG1 X-30 Y0.001\n\
G1 X-30 Y0.1\nG1 X30 Y0.1\nG1 X20 Y20 Z0.2\nG1 X-20 Y-19.999 E3 F3000\nG1 X-19.9 Y20 E2\n";

/// The unlimited conversion of [`NEAR_CENTRE`] verified against a bed limited to 5 rad/s: the lines beside the
/// centre are over it.
#[test]
fn verification_finds_lines_over_a_limit() {
    let polar = machines::polar();
    let bed = motor(polar.as_ref(), "stepper_bed");
    let map = AxisMap::motors(polar, Target::Cylindrical).expect("polar map");
    let (out, _, free) = round_trip(&map, &homed(), NEAR_CENTRE);
    assert_eq!((free.over_limit, free.max_limit_use), (0, 0.0));
    let limited = ConvertOptions {
        motor_limits: vec![limit(bed, 5.0)],
        ..homed()
    };
    let commands = convert::read_commands(NEAR_CENTRE, "near.gcode").expect("input parses");
    let r = convert::verify(&map, &limited, &commands, out.as_bytes()).expect("output readable");
    let replayed = replay(&out, [1.0, 1.0 / DEG], [f64::INFINITY, 5.0]);
    assert!(r.over_limit > 0, "{r:?}");
    // The worst line's share of the limit, as the independent replay measures it.
    assert!(
        (r.max_limit_use / replayed.worst_share[1] - 1.0).abs() < 1e-6,
        "{r:?}"
    );
    assert!(r.max_limit_use > 100.0);
}

fn check_near_centre(feed: FeedMode, limited: bool) -> (Replayed, VerifyReport) {
    let polar = machines::polar();
    let bed = motor(polar.as_ref(), "stepper_bed");
    let map = AxisMap::motors(polar, Target::Cylindrical).expect("polar map");
    let options = ConvertOptions {
        feed,
        motor_limits: if limited {
            vec![limit(bed, 5.0)]
        } else {
            Vec::new()
        },
        ..homed()
    };
    let (out, stats, report) = round_trip(&map, &options, NEAR_CENTRE);
    let replayed = replay(&out, [1.0, 1.0 / DEG], [f64::INFINITY, 5.0]);
    println!(
        "{feed:?} limited {limited}: bed up to {:.4e} °/min ({:.4}× 5 rad/s); {} lines slowed; time {:.4} s \
         (verify {:.4} s, Cartesian {:.4} s, at a limit {:.4} s)",
        replayed.fastest[1] * 60.0,
        replayed.worst_share[1],
        stats.limited,
        replayed.time,
        report.time_out,
        report.time_in,
        report.limited_time
    );
    assert_eq!(report.unmatched, 0);
    assert!(report.max_deviation <= Segmentation::DEFAULT_TOLERANCE);
    // The verify report's time is the time the written feeds take.
    assert!((report.time_out - replayed.time).abs() <= 1e-3 * replayed.time);
    (replayed, report)
}

#[test]
fn polar_bed_speed_stays_within_its_limit_near_the_centre() {
    for feed in [FeedMode::MotorSpace, FeedMode::InverseTime] {
        let (free, free_report) = check_near_centre(feed, false);
        // Without a limit the travel 1 µm from the centre writes a bed speed no bed can give.
        assert!(free.worst_share[1] > 100.0, "{free:?}");
        assert_eq!(free_report.max_limit_use, 0.0);
        let (capped, report) = check_near_centre(feed, true);
        assert!(capped.worst_share[1] <= 1.001, "{capped:?}");
        // The limit binds (the fastest line runs at it) and costs time, all of it in lines at the limit.
        assert!(capped.worst_share[1] >= 0.999, "{capped:?}");
        assert!(capped.time > free.time);
        assert_eq!(report.over_limit, 0);
        let beyond = report.time_out - report.flip_time - report.time_in;
        assert!(beyond > 0.0 && beyond <= report.limited_time, "{report:?}");
    }
}

#[test]
fn scara_joint_speeds_stay_within_their_limits() {
    let scara = machines::scara();
    let (a, b) = (
        motor(scara.as_ref(), "stepper_a"),
        motor(scara.as_ref(), "stepper_b"),
    );
    let map = AxisMap::motors(scara, Target::Joints).expect("SCARA map");
    // 200 mm/s lines and an arc across the work area 130 mm out: joint rates up to ~2 rad/s unlimited.
    let text =
        b"G1 X-50 Y130 F12000\nG1 X50 Y130\nG1 X0 Y180 E2\nG1 X0 Y75\nG2 X0 Y185 I0 J55 E4\n\
G1 X-40 Y160 F6000\n";
    let limits = [1.0, 0.7];
    let options = ConvertOptions {
        angle_unit: AngleUnit::Degrees,
        motor_limits: vec![limit(a, limits[0]), limit(b, limits[1])],
        ..homed()
    };
    let free = ConvertOptions {
        motor_limits: Vec::new(),
        ..options.clone()
    };
    let (out_free, _, _) = round_trip(&map, &free, text);
    let unlimited = replay(&out_free, [1.0 / DEG; 2], limits);
    assert!(
        unlimited.worst_share.iter().all(|&s| s > 1.2),
        "{unlimited:?}"
    );
    let (out, stats, report) = round_trip(&map, &options, text);
    let replayed = replay(&out, [1.0 / DEG; 2], limits);
    println!(
        "SCARA: joints up to {:?} of their limits ({:?} unlimited), {} lines slowed, time {:.4} s (verify {:.4} s)",
        replayed.worst_share, unlimited.worst_share, stats.limited, replayed.time, report.time_out
    );
    assert!(
        replayed.worst_share.iter().all(|&s| s <= 1.001),
        "{replayed:?}"
    );
    assert!(
        replayed.worst_share.iter().any(|&s| s >= 0.999),
        "{replayed:?}"
    );
    assert_eq!((report.unmatched, report.over_limit), (0, 0));
    assert!(report.max_deviation <= Segmentation::DEFAULT_TOLERANCE);
    assert!((report.time_out - replayed.time).abs() <= 1e-3 * replayed.time);
}

#[test]
fn corpus_verify_time_is_the_time_of_the_written_feeds() {
    let polar: Arc<dyn Kinematics> = machines::polar();
    let bed = motor(polar.as_ref(), "stepper_bed");
    let map = AxisMap::motors(polar, Target::Cylindrical).expect("polar map");
    for (name, text) in corpus_files() {
        let commands = convert::read_commands(&text[..], &name).expect("corpus parses");
        let (scale, translate) = placement(&commands, [0.0, 0.0], 300.0);
        let free = ConvertOptions {
            scale_xy: scale,
            translate,
            ..homed()
        };
        let limited = ConvertOptions {
            motor_limits: vec![limit(bed, 5.0)],
            ..free.clone()
        };
        let (out_free, _, _) = round_trip(&map, &free, &text);
        let before = replay(&out_free, [1.0, 1.0 / DEG], [f64::INFINITY, 5.0]);
        let (out, stats, r) = round_trip(&map, &limited, &text);
        let after = replay(&out, [1.0, 1.0 / DEG], [f64::INFINITY, 5.0]);
        println!(
            "{name:45} bed feed max {:.3e} → {:.3e} °/min; time Cartesian {:.1} s, written feeds {:.1} → {:.1} s \
             (verify {:.1} s, {:+.1} %), {} lines slowed",
            before.fastest[1] * 60.0,
            after.fastest[1] * 60.0,
            r.time_in,
            before.time,
            after.time,
            r.time_out,
            100.0 * (r.time_out - r.flip_time - r.time_in) / r.time_in,
            stats.limited
        );
        assert!(
            (r.time_out - after.time).abs() <= 1e-3 * after.time,
            "{name}: verify {} s, written feeds {} s",
            r.time_out,
            after.time
        );
        assert!(after.worst_share[1] <= 1.001, "{name}: {after:?}");
        assert_eq!((r.unmatched, r.over_limit), (0, 0), "{name}");
        assert!(r.max_deviation <= Segmentation::DEFAULT_TOLERANCE, "{name}");
        // Never faster than the input asks; every second beyond it in lines at the bed's limit.
        let moves = r.time_out - r.flip_time;
        assert!(moves >= r.time_in * 0.995, "{name}: {r:?}");
        assert!(moves - r.limited_time <= r.time_in * 1.005, "{name}: {r:?}");
    }
}
