//! Reader throughput on ≈50 MB of real slicer G-code (the corpus repeated in memory; generated G-code
//! when `../shared` is absent): lexing alone, lexing + interpretation (the reader), and lexing +
//! interpretation + statistics (`jointspace stats`), side by side in one run so that their ratio holds
//! on a machine whose absolute speed drifts.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
#[path = "common/mod.rs"]
mod common;

use common::{lex_and_interpret, lex_interpret_and_stats, lex_only};

const TARGET_BYTES: usize = 50 << 20;

fn corpus_bytes() -> Option<Vec<u8>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/corpus");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .collect();
    files.sort();
    let mut all = Vec::new();
    for file in files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "gcode"))
    {
        all.extend(std::fs::read(file).ok()?);
        all.push(b'\n');
    }
    (!all.is_empty()).then_some(all)
}

/// Perimeters of a 40 mm circle, layer after layer, as a slicer writes them.
fn generated_bytes() -> Vec<u8> {
    let mut out = String::from("G90\nM82\nG92 E0\n");
    let mut e = 0.0;
    for layer in 0..200 {
        out.push_str(&format!(
            ";LAYER_CHANGE\n;Z:{:.2}\nG1 Z{:.2} F600\n;TYPE:Perimeter\n",
            0.2 * f64::from(layer + 1),
            0.2 * f64::from(layer + 1)
        ));
        for step in 0..360 {
            let angle = f64::from(step).to_radians();
            e += 0.0331;
            out.push_str(&format!(
                "G1 X{:.3} Y{:.3} E{:.5} F1800\n",
                20.0 * angle.cos(),
                20.0 * angle.sin(),
                e
            ));
        }
    }
    out.into_bytes()
}

fn input() -> Vec<u8> {
    let unit = corpus_bytes().unwrap_or_else(|| {
        eprintln!("../shared/corpus absent: benchmarking generated G-code");
        generated_bytes()
    });
    let mut data = Vec::with_capacity(TARGET_BYTES + unit.len());
    while data.len() < TARGET_BYTES {
        data.extend_from_slice(&unit);
    }
    data
}

fn bench(c: &mut Criterion) {
    let data = input();
    let mut group = c.benchmark_group("reader");
    group.throughput(Throughput::Bytes(data.len() as u64));
    group.sample_size(10);
    group.bench_function("lex", |b| b.iter(|| black_box(lex_only(black_box(&data)))));
    group.bench_function("lex+interpret", |b| {
        b.iter(|| black_box(lex_and_interpret(black_box(&data))))
    });
    group.bench_function("lex+interpret+stats", |b| {
        b.iter(|| black_box(lex_interpret_and_stats(black_box(&data))))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
