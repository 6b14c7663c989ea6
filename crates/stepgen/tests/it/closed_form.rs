//! Cases whose step times follow from a formula, computed here independently of the solver.

use kinematics::Kinematics;
use stepgen::{ExtruderSpec, Step, StepError, StepGenConfig, StepGenerator};
use trapq::{Piece, Queue, TrapezoidMove};

use crate::machines;

const HZ: f64 = 16e6;

fn cruise(print_time: f64, duration: f64, start: [f64; 3], dir: [f64; 3], v: f64) -> TrapezoidMove {
    TrapezoidMove {
        print_time,
        accel_t: 0.0,
        cruise_t: duration,
        decel_t: 0.0,
        start_pos: start,
        axes_r: dir,
        start_v: v,
        cruise_v: v,
        accel: 0.0,
        motion: trapq::Motion::Travel,
    }
}

fn run(
    kin: &dyn Kinematics,
    start: [f64; 3],
    moves: &[(Queue, TrapezoidMove)],
) -> Result<Vec<Vec<Step>>, StepError> {
    let extruder = ExtruderSpec {
        name: "extruder".into(),
        step_distance: 0.01,
        start_position: 0.0,
    };
    let mut generator = StepGenerator::new(kin, start, Some(extruder), StepGenConfig::default())?;
    let mut sinks = vec![Vec::new(); generator.motor_count()];
    generator.run_moves(moves.iter().copied(), 64, &mut sinks)?;
    Ok(sinks)
}

fn clock(t: f64) -> u64 {
    (t * HZ).round() as u64
}

fn assert_close(ours: &[Step], expected: &[(f64, bool)]) {
    assert_eq!(ours.len(), expected.len(), "step count");
    for (i, (step, &(t, dir))) in ours.iter().zip(expected).enumerate() {
        assert_eq!(step.dir, dir, "direction of step {i}");
        let diff = step.clock as i64 - clock(t) as i64;
        assert!(
            diff.abs() <= 1,
            "step {i}: clock {} expected {} (t {t})",
            step.clock,
            clock(t)
        );
    }
}

#[test]
fn constant_velocity_line_steps_at_predictable_times() {
    // X from 0.004 (off the step grid) at 10 mm/s for 1 s; step 0.0125 mm: level k at 0.004 + (k + ½)·step.
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let mv = cruise(1.0, 1.0, [0.004, 0.0, 0.0], [1.0, 0.0, 0.0], 10.0);
    let steps = run(kin.as_ref(), [0.004, 0.0, 0.0], &[(Queue::Toolhead, mv)]).expect("steps");
    let expected: Vec<(f64, bool)> = (0..800)
        .map(|k| (1.0 + (k as f64 + 0.5) * 0.0125 / 10.0, true))
        .collect();
    assert_close(&steps[0], &expected);
    // Exactly on whole ticks: 10000 + 20000·k.
    assert_eq!(steps[0][3].clock, 16_000_000 + 10_000 + 3 * 20_000);
    assert!(steps[1].is_empty() && steps[2].is_empty() && steps[3].is_empty());
}

#[test]
fn accelerating_from_rest_follows_square_root_law() {
    // d = a t²/2 along −Y with a = 1000 mm/s² for 0.1 s (5 mm).
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let mv = TrapezoidMove {
        print_time: 0.5,
        accel_t: 0.1,
        cruise_t: 0.0,
        decel_t: 0.0,
        start_pos: [0.0, 0.0, 0.0],
        axes_r: [0.0, -1.0, 0.0],
        start_v: 0.0,
        cruise_v: 100.0,
        accel: 1000.0,
        motion: trapq::Motion::Travel,
    };
    let steps = run(kin.as_ref(), [0.0; 3], &[(Queue::Toolhead, mv)]).expect("steps");
    let expected: Vec<(f64, bool)> = (0..400)
        .map(|k| {
            (
                0.5 + (2.0 * (k as f64 + 0.5) * 0.0125 / 1000.0).sqrt(),
                false,
            )
        })
        .collect();
    assert_close(&steps[1], &expected);
}

#[test]
fn extruder_retraction_steps_backwards() {
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let mv = cruise(2.0, 0.1, [3.0, 0.0, 0.0], [1.0, 0.0, 0.0], -5.0);
    let steps = run(kin.as_ref(), [0.0; 3], &[(Queue::Extruder, mv)]).expect("steps");
    // The extruder starts at 0 and its queue starts at E = 3.0: the 300 steps of that jump happen at once
    // (all up). Then E goes from 3.0 down to 2.5 at 5 mm/s: 50 steps down, level k at 2.995 − k·0.01.
    let down: Vec<&Step> = steps[3].iter().filter(|s| !s.dir).collect();
    assert_eq!(steps[3].iter().filter(|s| s.dir).count(), 300);
    assert_eq!(down.len(), 50);
    for (k, step) in down.iter().enumerate() {
        let t = 2.0 + (0.005 + k as f64 * 0.01) / 5.0;
        assert!(
            (step.clock as i64 - clock(t) as i64).abs() <= 1,
            "retraction step {k}"
        );
    }
}

#[test]
fn polar_arm_radial_line_is_linear_and_bed_still() {
    let kin = machines::polar(std::f64::consts::TAU / 16000.0, 0.0125, 0.0025);
    // From (100, 0) outward to (110, 0) at 20 mm/s.
    let mv = cruise(1.0, 0.5, [100.0, 0.0, 0.0], [1.0, 0.0, 0.0], 20.0);
    let steps = run(kin.as_ref(), [100.0, 0.0, 0.0], &[(Queue::Toolhead, mv)]).expect("steps");
    assert!(steps[0].is_empty(), "bed must not move on a radial line");
    let expected: Vec<(f64, bool)> = (0..800)
        .map(|k| (1.0 + (k as f64 + 0.5) * 0.0125 / 20.0, true))
        .collect();
    assert_close(&steps[1], &expected);
}

#[test]
fn polar_bed_on_a_straight_line_past_the_centre() {
    // Line y = 10 from x = 50 to x = −50 at 20 mm/s: the bed angle goes from atan2(10, 50) up to
    // atan2(10, −50); it reaches level θ where x = 10·cos θ / sin θ, at t = (50 − x)/20.
    let step = std::f64::consts::TAU / 16000.0;
    let kin = machines::polar(step, 0.0125, 0.0025);
    let mv = cruise(1.0, 5.0, [50.0, 10.0, 0.0], [-1.0, 0.0, 0.0], 20.0);
    let steps = run(kin.as_ref(), [50.0, 10.0, 0.0], &[(Queue::Toolhead, mv)]).expect("steps");
    let (theta0, theta1) = (10f64.atan2(50.0), 10f64.atan2(-50.0));
    let count = ((theta1 - theta0) / step).round() as usize;
    let expected: Vec<(f64, bool)> = (0..count)
        .map(|k| {
            let level = theta0 + (k as f64 + 0.5) * step;
            let x = 10.0 * level.cos() / level.sin();
            (1.0 + (50.0 - x) / 20.0, true)
        })
        .collect();
    assert_close(&steps[0], &expected);
    // The arm goes in (50.99 → 10) and out again: a reversal at the closest approach, t = 3.5 s.
    let arm = &steps[1];
    let turn = arm.iter().position(|s| s.dir).expect("arm turns round");
    assert!(arm[..turn].iter().all(|s| !s.dir) && arm[turn..].iter().all(|s| s.dir));
    assert!(arm[turn - 1].clock < clock(3.5) && arm[turn].clock > clock(3.5));
}

#[test]
fn move_through_the_polar_centre_is_an_error() {
    let kin = machines::polar(std::f64::consts::TAU / 16000.0, 0.0125, 0.0025);
    let mv = cruise(1.0, 1.0, [10.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 20.0);
    match run(kin.as_ref(), [10.0, 0.0, 0.0], &[(Queue::Toolhead, mv)]) {
        Err(StepError::ThroughCentre { motor, .. }) => assert_eq!(motor, "stepper_bed"),
        other => panic!("expected ThroughCentre, got {other:?}"),
    }
}

#[test]
fn non_finite_piece_is_an_error_not_a_nan() {
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let mv = cruise(1.0, f64::NAN, [0.0; 3], [1.0, 0.0, 0.0], 10.0);
    let result = run(kin.as_ref(), [0.0; 3], &[(Queue::Toolhead, mv)]);
    assert!(
        matches!(result, Err(StepError::InvalidPiece { .. })),
        "{result:?}"
    );
}

#[test]
fn scara_joint_steps_are_exact_crossings() {
    // A general (non closed-form) motor: every step clock must bracket the crossing of its level,
    // evaluated here straight from the kinematics.
    let step = std::f64::consts::TAU / 9600.0;
    let kin = machines::scara_fekt(step, step, 0.0025, 100.0, 100.0, [0.0, 0.0], 3.0);
    let start = [-60.0, 120.0, 0.0];
    let dir = [0.8, 0.6, 0.0];
    let mv = TrapezoidMove {
        print_time: 1.0,
        accel_t: 0.05,
        cruise_t: 0.5,
        decel_t: 0.05,
        start_pos: start,
        axes_r: dir,
        start_v: 0.0,
        cruise_v: 100.0,
        accel: 2000.0,
        motion: trapq::Motion::Travel,
    };
    let pieces: Vec<Piece> = mv.pieces().collect();
    let steps = run(kin.as_ref(), start, &[(Queue::Toolhead, mv)]).expect("steps");
    let mut p0 = [0.0; 3];
    kin.inverse(start, &mut p0).expect("reachable");
    for motor in 0..2 {
        assert!(steps[motor].len() > 100, "motor {motor} should step");
        let mut net = 0i64;
        for s in &steps[motor] {
            let level = p0[motor] + (net as f64 + if s.dir { 0.5 } else { -0.5 }) * step;
            let at = |t: f64| {
                let piece = pieces
                    .iter()
                    .rev()
                    .find(|p| p.print_time <= t)
                    .expect("piece");
                let mut m = [0.0; 3];
                kin.inverse(
                    piece.position((t - piece.print_time).min(piece.duration)),
                    &mut m,
                )
                .expect("pose");
                m[motor] - level
            };
            let t = s.clock as f64 / HZ;
            let (before, after) = (at(t - 0.5 / HZ), at(t + 0.5 / HZ));
            assert!(
                before * after <= 0.0,
                "motor {motor} step at {} does not bracket its level",
                s.clock
            );
            net += if s.dir { 1 } else { -1 };
        }
    }
}

#[test]
fn output_is_identical_whatever_the_thread_count() {
    let kin = machines::polar(std::f64::consts::TAU / 16000.0, 0.0125, 0.0025);
    let moves: Vec<(Queue, TrapezoidMove)> = (0..40)
        .flat_map(|i| {
            let a = i as f64 * 0.7;
            let start = [30.0 * a.cos(), 30.0 * a.sin(), 0.2];
            let next = [30.0 * (a + 0.7).cos(), 30.0 * (a + 0.7).sin(), 0.2];
            let d = [next[0] - start[0], next[1] - start[1], 0.0];
            let len = d[0].hypot(d[1]);
            let mv = cruise(
                1.0 + i as f64 * len / 50.0,
                len / 50.0,
                start,
                [d[0] / len, d[1] / len, 0.0],
                50.0,
            );
            let e = cruise(
                mv.print_time,
                mv.cruise_t,
                [i as f64 * 0.5, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                0.5 / mv.cruise_t,
            );
            [(Queue::Toolhead, mv), (Queue::Extruder, e)]
        })
        .collect();
    let start = moves[0].1.start_pos;
    let in_pool = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| run(kin.as_ref(), start, &moves).expect("steps"))
    };
    let one = in_pool(1);
    assert!(
        [0, 1, 3].iter().all(|&m| !one[m].is_empty()),
        "bed, arm and extruder step"
    );
    assert_eq!(one, in_pool(2));
    assert_eq!(one, in_pool(4));
}

#[test]
fn radial_move_then_z_move_near_the_centre() {
    // In to 0.5 mm from the centre along the arm (9.5 mm: 760 arm steps), then 1 mm up (400 Z steps):
    // the bed never turns.
    let kin = machines::polar(std::f64::consts::TAU / 16000.0, 0.0125, 0.0025);
    let to_centre = cruise(1.0, 0.5, [10.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 19.0);
    let lift = cruise(1.6, 0.1, [0.5, 0.0, 0.0], [0.0, 0.0, 1.0], 10.0);
    let steps = run(
        kin.as_ref(),
        [10.0, 0.0, 0.0],
        &[(Queue::Toolhead, to_centre), (Queue::Toolhead, lift)],
    )
    .expect("no centre pass");
    assert!(steps[0].is_empty());
    assert_eq!(steps[1].len(), 760);
    assert_eq!(steps[2].len(), 400);
}

#[test]
fn pipeline_writes_step_files_and_statistics() {
    use trapq::MoveSink;
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let dir = tempfile::tempdir().expect("temp dir");
    let names: Vec<String> = ["stepper_x", "stepper_y", "stepper_z"]
        .map(String::from)
        .to_vec();
    let sinks = stepgen::step_file_sinks(dir.path(), &names, true, HZ).expect("files");
    let mut pipeline =
        stepgen::StepPipeline::new(kin.as_ref(), None, StepGenConfig::default(), sinks);
    assert_eq!(pipeline.motor_names(), names);
    pipeline
        .set_position([0.0; 3], 0.0)
        .expect("the sink takes the position");
    // 1 mm along X at 10 mm/s (80 steps 0.00125 s apart), then 1 mm back.
    pipeline
        .append(
            Queue::Toolhead,
            &cruise(1.0, 0.1, [0.0; 3], [1.0, 0.0, 0.0], 10.0),
        )
        .expect("the sink takes the move");
    pipeline
        .append(
            Queue::Toolhead,
            &cruise(1.1, 0.1, [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 10.0),
        )
        .expect("the sink takes the move");
    let (sinks, filtered) = pipeline.finish().expect("steps");
    let stats = stepgen::finish_step_files(&names, sinks, &filtered, HZ).expect("files written");
    let (name, x) = &stats[0];
    assert_eq!(name, "stepper_x");
    assert_eq!((x.steps, x.net_steps, x.filtered_pairs), (160, 0, 0));
    assert_eq!(x.first_clock, Some(clock(1.0 + 0.000625)));
    assert_eq!(x.min_interval_ticks, Some(20_000));
    assert_eq!(x.peak_rate_min_interval, 800.0);
    assert_eq!(x.peak_rate_1ms, 1000.0);
    let back = stepgen::read_step_file(dir.path().join("stepper_x.txt.gz")).expect("read back");
    assert_eq!(back.len(), 160);
    assert!(back[..80].iter().all(|s| s.dir) && back[80..].iter().all(|s| !s.dir));
    assert_eq!(stats[1].1.steps, 0);
}

#[test]
fn pipeline_restarts_motors_at_a_declared_position() {
    use trapq::MoveSink;
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let mut pipeline = stepgen::StepPipeline::new(
        kin.as_ref(),
        None,
        StepGenConfig::default(),
        vec![Vec::new(); 3],
    );
    // Moves before any declared pose are an error at the end.
    pipeline
        .append(
            Queue::Toolhead,
            &cruise(1.0, 0.1, [0.0; 3], [1.0, 0.0, 0.0], 10.0),
        )
        .expect("the sink takes the move");
    assert!(matches!(pipeline.finish(), Err(StepError::NoStartPose)));

    let mut pipeline = stepgen::StepPipeline::new(
        kin.as_ref(),
        None,
        StepGenConfig::default(),
        vec![Vec::new(); 3],
    );
    pipeline
        .set_position([0.0; 3], 0.0)
        .expect("the sink takes the position");
    pipeline
        .append(
            Queue::Toolhead,
            &cruise(1.0, 0.1, [0.0; 3], [1.0, 0.0, 0.0], 10.0),
        )
        .expect("the sink takes the move");
    // X is declared to be 5 (no motion), then moves on from there: no burst of steps for the jump.
    pipeline
        .set_position([5.0, 0.0, 0.0], 0.0)
        .expect("the sink takes the position");
    pipeline
        .append(
            Queue::Toolhead,
            &cruise(2.0, 0.1, [5.0, 0.0, 0.0], [1.0, 0.0, 0.0], 10.0),
        )
        .expect("the sink takes the move");
    let (sinks, _) = pipeline.finish().expect("steps");
    assert_eq!(sinks[0].len(), 160);
    assert!(sinks[0].iter().all(|s| s.dir));
    assert_eq!(sinks[0][80].clock, clock(2.0 + 0.000625));
}

/// A star of cruise moves through and near the polar centre, each followed by extrusion: more pieces than
/// one chunk holds, with a declared position in the middle.
fn star_of_moves() -> Vec<(Queue, TrapezoidMove)> {
    let mut moves = Vec::new();
    let mut print_time = 1.0;
    let mut at = [30.0, 0.0, 0.0];
    for i in 0..12_000 {
        let angle = i as f64 * 2.399963;
        // Targets alternate between the rim and points 0.05–0.85 mm from the centre.
        let radius = if i % 2 == 0 {
            30.0
        } else {
            0.05 + (i % 9) as f64 * 0.1
        };
        let target = [radius * angle.cos(), radius * angle.sin(), 0.0];
        let delta = [target[0] - at[0], target[1] - at[1], 0.0];
        let length = delta[0].hypot(delta[1]);
        if length < 1e-6 {
            continue;
        }
        let dir = [delta[0] / length, delta[1] / length, 0.0];
        let duration = length / 120.0;
        moves.push((
            Queue::Toolhead,
            cruise(print_time, duration, at, dir, 120.0),
        ));
        let e = i as f64 * 0.05;
        moves.push((
            Queue::Extruder,
            cruise(
                print_time,
                duration,
                [e, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                0.05 / duration,
            ),
        ));
        print_time += duration;
        at = target;
    }
    moves
}

/// Steps of four motors and their filtered pairs, or the error.
type PipelineResult = Result<(Vec<Vec<Step>>, Vec<u64>), StepError>;

/// `feed` through the sequential [`stepgen::StepPipeline`] and through [`stepgen::run_in_parallel`].
fn sequential_and_threaded(
    kin: &dyn Kinematics,
    extruder: &ExtruderSpec,
    feed: impl Fn(&mut dyn trapq::MoveSink),
) -> (PipelineResult, PipelineResult) {
    let mut sequential = stepgen::StepPipeline::new(
        kin,
        Some(extruder.clone()),
        StepGenConfig::default(),
        vec![Vec::<Step>::new(); 4],
    );
    feed(&mut sequential);
    let threaded = stepgen::run_in_parallel(
        kin,
        Some(extruder.clone()),
        StepGenConfig::default(),
        vec![Vec::<Step>::new(); 4],
        || false,
        |mut sender| feed(&mut sender),
    )
    .map(|((), steps, pairs)| (steps, pairs));
    (sequential.finish(), threaded)
}

#[test]
fn threaded_pipeline_gives_the_sequential_pipelines_steps() {
    use trapq::MoveSink;
    let kin = machines::polar(std::f64::consts::TAU / 16000.0, 0.0125, 0.0025);
    let extruder = ExtruderSpec {
        name: "extruder".into(),
        step_distance: 0.002,
        start_position: 0.0,
    };
    let moves = star_of_moves();
    let (first_half, second_half) = moves.split_at(moves.len() / 2);
    // The second half is declared to start 0.1 mm of filament further on (as after `G92 E`).
    let restart = match second_half[0] {
        (Queue::Toolhead, mv) => (mv.start_pos, second_half[1].1.start_pos[0] + 0.1),
        (Queue::Extruder, mv) => (second_half[1].1.start_pos, mv.start_pos[0] + 0.1),
    };
    let feed = |sink: &mut dyn MoveSink| {
        sink.set_position([30.0, 0.0, 0.0], 0.0)
            .expect("the sink takes the position");
        for (queue, mv) in first_half {
            sink.append(*queue, mv).expect("the sink takes the move");
        }
        sink.set_position(restart.0, restart.1)
            .expect("the sink takes the position");
        for (queue, mv) in second_half {
            sink.append(*queue, mv).expect("the sink takes the move");
        }
    };
    let (sequential, threaded) = sequential_and_threaded(kin.as_ref(), &extruder, feed);
    let (expected, expected_pairs) = sequential.expect("sequential steps");
    let (threaded, pairs) = threaded.expect("threaded steps");
    assert!(
        expected[0].len() > 100_000,
        "bed steps {}",
        expected[0].len()
    );
    // Bed, arm and extruder step (Z stays put).
    assert!([0, 1, 3].iter().all(|&motor| !expected[motor].is_empty()));
    assert_eq!(threaded, expected);
    assert_eq!(pairs, expected_pairs);
}

/// Records steps until a given count, then fails as a full disk would.
#[derive(Debug)]
struct FailingSink {
    steps: u64,
    room: u64,
}

impl stepgen::StepSink for FailingSink {
    fn step(&mut self, _clock: u64, _dir: bool) {
        self.steps += 1;
    }

    fn failure(&self) -> Option<String> {
        (self.steps > self.room).then(|| "no space left on device".to_string())
    }
}

/// A sink that fails stops its motor and, through the planner's sink, the planning: the moves fed after the
/// failure are refused, and the run's error is the sink's.
#[test]
fn a_failing_step_sink_stops_the_run_early() {
    use trapq::MoveSink;
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let sinks = (0..3)
        .map(|_| FailingSink {
            steps: 0,
            room: 1000,
        })
        .collect();
    let mut fed = 0;
    let result = stepgen::run_in_parallel(
        kin.as_ref(),
        None,
        StepGenConfig::default(),
        sinks,
        || false,
        |mut sender| {
            // A failed or cancelled motor may refuse it; the feed goes on, as a planner that did not stop.
            let _ = sender.set_position([0.0; 3], 0.0);
            // 10 mm per move back and forth in X: 800 X steps a move; a million moves if nothing stopped it.
            for i in 0..1_000_000 {
                let (start, dir) = match i % 2 {
                    0 => ([0.0; 3], [1.0, 0.0, 0.0]),
                    _ => ([10.0, 0.0, 0.0], [-1.0, 0.0, 0.0]),
                };
                let mv = cruise(1.0 + 0.1 * f64::from(i), 0.1, start, dir, 100.0);
                if sender.append(Queue::Toolhead, &mv).is_err() {
                    break;
                }
                fed += 1;
            }
        },
    );
    assert!(
        matches!(&result, Err(StepError::Output(m)) if m == "no space left on device"),
        "{result:?}"
    );
    assert!(fed < 100_000, "planning went on for {fed} moves");
}

#[test]
fn threaded_pipeline_reports_moves_before_a_declared_position() {
    use trapq::MoveSink;
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let result = stepgen::run_in_parallel(
        kin.as_ref(),
        None,
        StepGenConfig::default(),
        vec![Vec::<Step>::new(); 3],
        || false,
        |mut sender| {
            sender.append(
                Queue::Toolhead,
                &cruise(1.0, 0.1, [0.0; 3], [1.0, 0.0, 0.0], 10.0),
            )
        },
    );
    assert!(matches!(result, Err(StepError::NoStartPose)));
    let cancelled = stepgen::run_in_parallel(
        kin.as_ref(),
        None,
        StepGenConfig::default(),
        vec![Vec::<Step>::new(); 3],
        || true,
        |mut sender| {
            // A failed or cancelled motor may refuse it; the feed goes on, as a planner that did not stop.
            let _ = sender.set_position([0.0; 3], 0.0);
            sender.append(
                Queue::Toolhead,
                &cruise(1.0, 0.1, [0.0; 3], [1.0, 0.0, 0.0], 10.0),
            )
        },
    );
    assert!(matches!(cancelled, Err(StepError::Cancelled)));
}

/// Motors failing at different points: the threaded pipeline reports the earliest failure, as the sequential
/// one does, however the threads happen to be scheduled.
#[test]
fn threaded_pipeline_reports_the_earliest_failure() {
    use trapq::MoveSink;
    let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
    let extruder = ExtruderSpec {
        name: "extruder".into(),
        step_distance: 0.002,
        start_position: 0.0,
    };
    let feed = |sink: &mut dyn MoveSink| {
        // A failed or cancelled motor may refuse it; the feed goes on, as a planner that did not stop.
        let _ = sink.set_position([0.0; 3], 0.0);
        // Only the extruder fails here (its piece starts at a non-finite position)… (Once a motor has failed
        // the sink may refuse further moves; the moves are fed on regardless, as a planner that did not stop.)
        let _ = sink.append(
            Queue::Extruder,
            &cruise(1.0, 0.1, [f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0),
        );
        // A failed or cancelled motor may refuse it; the feed goes on, as a planner that did not stop.
        let _ = sink.set_position([0.0; 3], 0.0);
        // …and the toolhead motors only later.
        let _ = sink.append(
            Queue::Toolhead,
            &cruise(2.0, 0.1, [f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], 10.0),
        );
    };
    for _ in 0..20 {
        let (sequential, threaded) = sequential_and_threaded(kin.as_ref(), &extruder, feed);
        let expected = sequential.expect_err("the extruder fails").to_string();
        assert!(expected.contains("extruder"), "{expected}");
        assert_eq!(threaded.expect_err("fails").to_string(), expected);
    }
}
