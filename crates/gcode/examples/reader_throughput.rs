//! Reader throughput measured in CPU time of this thread (robust on a loaded machine, unlike the
//! criterion wall-clock numbers): `cargo run --release -p gcode --example reader_throughput [corpus dir]`.

use std::path::PathBuf;

use gcode::{Commands, Reader};

/// Nanoseconds this thread has run on a CPU (Linux `schedstat`); `None` elsewhere.
fn cpu_ns() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

/// The corpus (the first argument's directory, else `../shared/corpus`) repeated to
/// `THROUGHPUT_MB` megabytes (default 50); `None` when there is no corpus.
fn input() -> Option<Vec<u8>> {
    let dir = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/corpus")
        });
    let mut unit = Vec::new();
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|d| d.filter_map(Result::ok).map(|e| e.path()).collect())
        .unwrap_or_default();
    files.sort();
    for file in files {
        unit.extend(std::fs::read(file).unwrap_or_default());
        unit.push(b'\n');
    }
    if unit.is_empty() {
        eprintln!("no corpus in {}", dir.display());
        return None;
    }
    let megabytes: usize = std::env::var("THROUGHPUT_MB")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(50);
    let mut data = Vec::new();
    while data.len() < megabytes << 20 {
        data.extend_from_slice(&unit);
    }
    Some(data)
}

fn main() {
    let Some(data) = input() else {
        return;
    };
    // `THROUGHPUT_ONLY=lex+interpret` runs one measurement (for profiling).
    let only = std::env::var("THROUGHPUT_ONLY").ok();
    let measure = |name: &str, run: &dyn Fn() -> usize| {
        if only.as_deref().is_some_and(|o| o != name) {
            return;
        }
        let mut best = f64::MAX;
        let rounds = if only.is_some() { 1 } else { 5 };
        for _ in 0..rounds {
            let (Some(before), started) = (cpu_ns(), std::time::Instant::now()) else {
                return;
            };
            std::hint::black_box(run());
            let cpu = cpu_ns().map_or(0, |after| after - before) as f64 * 1e-9;
            best = best.min(cpu.max(1e-9));
            let _ = started;
        }
        println!(
            "{name}: {:.0} MB/s ({} MB, best of {rounds}, CPU time)",
            data.len() as f64 / 1e6 / best,
            data.len() >> 20
        );
    };
    // The naive baseline: split on whitespace, std's parser on every word.
    measure("naive split+parse", &|| {
        let mut sum = 0.0;
        for line in data.split(|&b| b == b'\n') {
            let code = line.split(|&b| b == b';').next().unwrap_or_default();
            let code = std::str::from_utf8(code).unwrap_or_default();
            for word in code.split_whitespace().skip(1) {
                sum += word
                    .get(1..)
                    .and_then(|v| v.parse::<f64>().ok())
                    .unwrap_or(0.0);
            }
        }
        sum as usize
    });
    measure("lex", &|| {
        let mut reader = Reader::new(&data[..], "bench");
        let mut words = 0;
        while let Some(line) = reader.next_line() {
            words += line.map_or(0, |l| l.words().len());
        }
        words
    });
    measure("lex+interpret", &|| {
        Commands::from_reader(&data[..], "bench")
            .filter(Result::is_ok)
            .count()
    });
}
