//! Throughput of the converter: MB/s of input G-code converted on one core at the default tolerance
//! (a corpus file placed on the example polar machine, output to memory).

use std::path::PathBuf;

use convert::{AxisMap, ConvertOptions, Converter, Target, convert_gcode};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

#[path = "../tests/it/machines.rs"]
#[allow(dead_code)]
mod machines;

const FILES: [&str; 2] = [
    "simplify3d-4.1.2.gcode",
    "prusaslicer-2.7.4_spiral-vase.gcode",
];

fn corpus(name: &str) -> Option<Vec<u8>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/corpus")
        .join(name);
    std::fs::read(path).ok()
}

/// Offset that puts the centre of the file's XY extent on the bed centre.
fn centring(text: &[u8]) -> [f64; 2] {
    let commands = convert::read_commands(text, "bench").unwrap_or_default();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in &commands {
        if let gcode::Command::Move(m) = c {
            for i in 0..2 {
                lo[i] = lo[i].min(m.target[i]);
                hi[i] = hi[i].max(m.target[i]);
            }
        }
    }
    [-(lo[0] + hi[0]) / 2.0, -(lo[1] + hi[1]) / 2.0]
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("convert");
    for name in FILES {
        let Some(text) = corpus(name) else {
            eprintln!("skipping {name}: ../shared/corpus is absent");
            continue;
        };
        let options = ConvertOptions {
            translate: centring(&text),
            ..ConvertOptions::default()
        };
        let map = AxisMap::motors(machines::polar(), Target::Cylindrical).expect("polar map");
        group.throughput(Throughput::Bytes(text.len() as u64));
        group.bench_function(name, |b| {
            b.iter(|| {
                let out = Vec::with_capacity(text.len() * 10);
                let mut converter =
                    Converter::new(map.clone(), options.clone(), out).expect("converter");
                convert_gcode(&text[..], name, &mut converter).expect("conversion");
                converter.finish().expect("finish")
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
