//! Converts one G-code file N times onto the example polar machine (part centred) and prints the input
//! size, so that `perf stat` (CPU time, unaffected by other load) gives the throughput:
//! `cargo run --release -p convert --example convert_throughput -- FILE N`.

use convert::{AxisMap, ConvertOptions, Converter, Target, convert_gcode};

#[path = "../tests/it/machines.rs"]
#[allow(dead_code)]
mod machines;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or("usage: throughput FILE N")?;
    let repeats: usize = args.next().unwrap_or_else(|| "10".into()).parse()?;
    let text = std::fs::read(&path)?;
    let commands = convert::read_commands(&text[..], &path)?;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in &commands {
        if let gcode::Command::Move(m) = c {
            for i in 0..2 {
                lo[i] = lo[i].min(m.target[i]);
                hi[i] = hi[i].max(m.target[i]);
            }
        }
    }
    let translate = [-(lo[0] + hi[0]) / 2.0, -(lo[1] + hi[1]) / 2.0];
    let options = ConvertOptions {
        translate,
        ..ConvertOptions::default()
    };
    let map = AxisMap::motors(machines::polar(), Target::Cylindrical)?;
    let mut written = 0;
    for _ in 0..repeats {
        let mut converter = Converter::new(
            map.clone(),
            options.clone(),
            Vec::with_capacity(text.len() * 10),
        )?;
        convert_gcode(&text[..], &path, &mut converter)?;
        let (out, stats) = converter.finish()?;
        written = out.len();
        if repeats == 1 {
            println!("{stats:?}");
            if let Some(path) = std::env::var_os("CONVERT_OUT") {
                std::fs::write(path, &out)?;
            }
        }
    }
    println!(
        "{} bytes in, {written} bytes out, {repeats} times",
        text.len()
    );
    Ok(())
}
