//! End-to-end benchmark: a whole job as `jointspace run` does it (read, plan, every motor stepped and audited) on
//! the bench print of `../shared/bench`, through `printjob::run`. Median of several runs. Absolute times on a
//! shared 2-core machine drift by 30%: compare only against another build measured in the same session, and against
//! Klipper only through `bench/peers.sh`, which runs both side by side.

use std::io::BufReader;
use std::path::Path;
use std::time::Instant;

use printjob::{Machine, RunOptions};

const RUNS: usize = 5;

fn main() {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bench");
    let (cfg, gcode) = (
        shared.join("polar-bench.cfg"),
        shared.join("polar-bench20.gcode"),
    );
    if !cfg.is_file() || !gcode.is_file() {
        eprintln!(
            "SKIPPED: {} is absent (the end-to-end bench file lives in ../shared)",
            shared.display()
        );
        return;
    }
    let (machine, _) = Machine::load(&cfg).expect("bench machine loads");
    let mut times = Vec::with_capacity(RUNS);
    let mut steps = 0;
    for _ in 0..RUNS {
        let start = Instant::now();
        let input = BufReader::new(std::fs::File::open(&gcode).expect("bench file opens"));
        let summary = printjob::run(
            &machine,
            input,
            "polar-bench20.gcode",
            &RunOptions::default(),
            || false,
        )
        .expect("bench print runs");
        times.push(start.elapsed().as_secs_f64());
        steps = summary.total_steps;
    }
    times.sort_by(f64::total_cmp);
    println!(
        "end to end: {steps} steps, median {:.3} s of {RUNS} runs (best {:.3} s); same-run ratios against Klipper: \
         bench/peers.sh",
        times[RUNS / 2],
        times[0]
    );
}
