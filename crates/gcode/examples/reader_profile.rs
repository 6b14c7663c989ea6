//! The reader benchmark's work outside criterion, for profiling:
//! `reader_profile lex|interpret|stats PASSES FILE...` reads the files once into memory (each followed by a
//! newline, as the bench does) and runs PASSES passes over them, printing the best pass in MB/s.
//! With PASSES = 1 under `valgrind --tool=callgrind` it gives repeatable instruction counts, which
//! wall-clock time on a shared machine does not.

use std::time::Instant;

#[path = "../benches/common/mod.rs"]
mod common;

use common::{lex_and_interpret, lex_interpret_and_stats, lex_only};

fn main() {
    let mut args = std::env::args().skip(1);
    let mode = args.next().unwrap_or_default();
    let passes: u32 = args.next().and_then(|p| p.parse().ok()).unwrap_or(1);
    let mut data = Vec::new();
    for path in args {
        data.extend(std::fs::read(&path).unwrap_or_default());
        data.push(b'\n');
    }
    let mut best = f64::INFINITY;
    let mut count = 0;
    for _ in 0..passes {
        let start = Instant::now();
        count = std::hint::black_box(match mode.as_str() {
            "lex" => lex_only(std::hint::black_box(&data)),
            "stats" => lex_interpret_and_stats(std::hint::black_box(&data)) as usize,
            _ => lex_and_interpret(std::hint::black_box(&data)),
        });
        best = best.min(start.elapsed().as_secs_f64());
    }
    let mb_per_s = data.len() as f64 / best / 1e6;
    println!(
        "{mode}: {} bytes, {count} items, best {mb_per_s:.0} MB/s",
        data.len()
    );
}
