//! End-to-end benchmark: wall time of `jointspace run` (parse, plan, every motor step) on the bench print of
//! `../shared/bench`, against Klipper's host on the same G-code and machine (REFERENCE.md §7: 11.9 s for
//! 228,920 moves and 12.06 M steps on a 2-core machine like this one). Median of several runs; absolute times
//! on a shared 2-core machine are noisy, the ratio is what to read.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

const KLIPPER_WALL_S: f64 = 11.9;
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
    let exe = env!("CARGO_BIN_EXE_jointspace");
    let mut times = Vec::with_capacity(RUNS);
    let mut summary = String::new();
    for _ in 0..RUNS {
        let start = Instant::now();
        let out = Command::new(exe)
            .arg("run")
            .arg("-c")
            .arg(&cfg)
            .arg(&gcode)
            .output()
            .expect("jointspace runs");
        times.push(start.elapsed().as_secs_f64());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        summary = String::from_utf8_lossy(&out.stdout).into_owned();
    }
    times.sort_by(f64::total_cmp);
    let median = times[RUNS / 2];
    println!("{summary}");
    println!(
        "end to end: jointspace run {median:.3} s (median of {RUNS}; best {:.3} s), Klipper {KLIPPER_WALL_S} s: {:.1}× faster",
        times[0],
        KLIPPER_WALL_S / median
    );
}
