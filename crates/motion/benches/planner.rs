//! Planner throughput: G-code text → planned moves (lexing, interpretation, junctions, lookahead), no steps.
//! Uses the end-to-end bench file from `../shared/bench` when present, else a generated print.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use machine::MachineSetup;
use printjob::plan_gcode;
use std::hint::black_box;
use std::path::Path;

fn inputs() -> (String, String) {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bench");
    if let (Ok(cfg), Ok(gcode)) = (
        std::fs::read_to_string(shared.join("polar-bench.cfg")),
        std::fs::read_to_string(shared.join("polar-bench20.gcode")),
    ) {
        return (cfg, gcode);
    }
    eprintln!("../shared/bench is absent: planning a generated print instead");
    let cfg = include_str!("../../../examples/machines/polar.cfg").to_string();
    let mut gcode = String::from("G28\nM83\nG1 Z0.3 F600\n");
    for layer in 0..40 {
        for i in 0..2000 {
            let a = i as f64 * std::f64::consts::TAU / 2000.0;
            let r = 20.0 + 30.0 * ((layer + i) % 7) as f64 / 7.0;
            gcode += &format!("G1 X{:.3} Y{:.3} E0.0100 F3000\n", r * a.cos(), r * a.sin());
        }
    }
    (cfg, gcode)
}

fn planner(c: &mut Criterion) {
    let (cfg, gcode) = inputs();
    let machine = config::MachineConfig::from_str(&cfg, "bench.cfg").expect("bench config loads");
    let mut group = c.benchmark_group("planner");
    group.sample_size(10);
    group.throughput(Throughput::Bytes(gcode.len() as u64));
    for (name, limits) in [("lookahead", false), ("with motor limits", true)] {
        let mut setup = MachineSetup::from_config(&machine).expect("machine builds");
        if !limits {
            setup.planner.kinematic_limits.clear();
        }
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut moves = 0u64;
                let sink = |_: trapq::Queue, _: &trapq::TrapezoidMove| moves += 1;
                let (_, summary) =
                    plan_gcode(&setup, gcode.as_bytes(), "bench.gcode", sink).expect("plans");
                black_box(summary.end_time)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, planner);
criterion_main!(benches);
