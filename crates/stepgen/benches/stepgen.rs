//! Step generation throughput on one core for polar, Cartesian and SCARA machines, from Klipper's planned moves in
//! `../shared/golden` (synthetic moves when the golden data is absent). Timed in CPU time (steps per CPU-second):
//! on this shared VM wall time also counts what other tenants take, which drifts by tens of percent.

use std::path::Path;

use cpu_time::ProcessTime;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kinematics::scara::Scara;
use kinematics::{
    CartesianParams, Kinematics, MachineParams, PolarParams, ScaraParams, StepperParams,
};
use stepgen::{CountSink, ExtruderSpec, StepGenConfig, StepGenerator, read_moves_csv};
use trapq::{Piece, Queue, TrapezoidMove};

const BED_STEP: f64 = std::f64::consts::TAU / 16000.0;
const EXTRUDER_STEP: f64 = 33.5 / 3200.0;

fn stepper(name: &str, step_distance: f64) -> StepperParams {
    StepperParams {
        name: name.into(),
        step_distance,
        position_min: None,
        position_max: None,
    }
}

fn polar() -> Box<dyn Kinematics> {
    let p = PolarParams {
        bed: stepper("stepper_bed", BED_STEP),
        arm: stepper("stepper_arm", 0.0125),
        z: stepper("stepper_z", 0.0025),
        arm_zero_offset: 0.0,
        arm_lateral_offset: 0.0,
    };
    kinematics::build(&MachineParams::Polar(p)).expect("polar parameters")
}

fn cartesian() -> Box<dyn Kinematics> {
    let steppers = [
        stepper("stepper_x", 0.0125),
        stepper("stepper_y", 0.0125),
        stepper("stepper_z", 0.0025),
    ];
    kinematics::build(&MachineParams::Cartesian(CartesianParams { steppers }))
        .expect("cartesian parameters")
}

fn scara() -> Box<dyn Kinematics> {
    Box::new(scara_arm())
}

fn scara_arm() -> Scara {
    let p = ScaraParams {
        z: stepper("stepper_z", 0.0025),
        base_protection_radius: 0.0,
        ..ScaraParams::fekt_example()
    };
    Scara::new(p).expect("scara parameters")
}

/// The same arm with the FEKT fork's cos quirk, which sends its joints to the general solver: the old path,
/// measured in the same run for the ratio.
fn scara_general() -> Box<dyn Kinematics> {
    Box::new(scara_arm().with_fekt_cos_quirk(true))
}

struct Workload {
    name: String,
    kin: Box<dyn Kinematics>,
    start: [f64; 3],
    toolhead: Vec<Piece>,
    extruder: Vec<Piece>,
}

/// Golden moves of `case`, or a synthetic square spiral around `centre` when the data is absent.
fn workload(case: &str, kin: Box<dyn Kinematics>, start: [f64; 3], centre: [f64; 2]) -> Workload {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/golden")
        .join(case)
        .join("moves.csv.gz");
    let moves = match read_moves_csv(&path) {
        Ok(moves) => moves,
        Err(e) => {
            eprintln!("{case}: golden moves unavailable ({e}); using synthetic moves");
            synthetic(start, centre)
        }
    };
    let pieces = |queue: Queue| -> Vec<Piece> {
        moves
            .iter()
            .filter(|(q, _)| *q == queue)
            .flat_map(|(_, m)| m.pieces())
            .collect()
    };
    Workload {
        name: case.to_string(),
        kin,
        start,
        toolhead: pieces(Queue::Toolhead),
        extruder: pieces(Queue::Extruder),
    }
}

fn synthetic(start: [f64; 3], centre: [f64; 2]) -> Vec<(Queue, TrapezoidMove)> {
    let mut moves = Vec::new();
    let (mut time, mut pos, v) = (0.25, start, 100.0);
    for i in 0..2000 {
        let a = i as f64 * 0.3;
        let r = 30.0 + (i % 50) as f64;
        let next = [centre[0] + r * a.cos(), centre[1] + r * a.sin(), start[2]];
        let d = [next[0] - pos[0], next[1] - pos[1], 0.0];
        let len = d[0].hypot(d[1]);
        let mv = TrapezoidMove {
            print_time: time,
            accel_t: 0.0,
            cruise_t: len / v,
            decel_t: 0.0,
            start_pos: pos,
            axes_r: [d[0] / len, d[1] / len, 0.0],
            start_v: v,
            cruise_v: v,
            accel: 0.0,
            motion: trapq::Motion::Travel,
        };
        moves.push((Queue::Toolhead, mv));
        time += len / v;
        pos = next;
    }
    moves
}

/// All motors of the workload, one after another on the calling thread.
fn run_one_core(w: &Workload) -> u64 {
    let extruder = ExtruderSpec {
        name: "extruder".into(),
        step_distance: EXTRUDER_STEP,
        start_position: 0.0,
    };
    let mut generator = StepGenerator::new(
        w.kin.as_ref(),
        w.start,
        Some(extruder),
        StepGenConfig::default(),
    )
    .expect("generator");
    let mut sinks = vec![CountSink::default(); generator.motor_count()];
    generator
        .run_chunk(&w.toolhead, &w.extruder, &mut sinks)
        .expect("steps");
    generator.finish(&mut sinks).expect("finish");
    sinks.iter().map(|s| s.steps).sum()
}

fn bench(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one-thread pool");
    let workloads = [
        workload(
            "polar-kisslicer-cube",
            polar(),
            [300.0, 0.0, 0.5],
            [0.0, 0.0],
        ),
        workload("polar-synthetic", polar(), [300.0, 0.0, 0.5], [0.0, 0.0]),
        workload(
            "cartesian-prusa-minicube-arcs",
            cartesian(),
            [0.0, 0.0, 0.5],
            [120.0, 120.0],
        ),
        workload(
            "scara-fekt-synthetic",
            scara(),
            [0.0, 130.0, 0.5],
            [0.0, 130.0],
        ),
        workload(
            "scara-fekt-synthetic",
            scara_general(),
            [0.0, 130.0, 0.5],
            [0.0, 130.0],
        ),
    ];
    let mut group = c.benchmark_group("stepgen_one_core");
    group.sample_size(10);
    for w in &workloads {
        let steps = pool.install(|| run_one_core(w));
        group.throughput(Throughput::Elements(steps));
        let name = if w.kin.motor_map(0) == kinematics::MotorMap::General && w.kin.name() == "scara"
        {
            format!("{} (general solver)", w.name)
        } else {
            w.name.clone()
        };
        group.bench_function(&name, |b| {
            b.iter_custom(|iters| {
                // The process's CPU time: the work runs on the pool's one thread, the caller waits.
                let start = ProcessTime::now();
                for _ in 0..iters {
                    std::hint::black_box(pool.install(|| run_one_core(w)));
                }
                start.elapsed()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
