//! Streams a large generated G-code input (default 1 GiB, never held in memory) through the reader and
//! interpreter, to measure peak memory: `/usr/bin/time -v target/release/examples/stream_rss [MiB]`.
//!
//! Measured (2026-11, 2-vCPU VM): 1 GiB streamed (21 M moves), maximum resident set size 2.7 MB.

use std::io::{BufReader, Read};

use gcode::{Command, Commands};

/// An endless slicer-like G-code text, produced on demand, stopping after `remaining` bytes.
struct Generator {
    remaining: u64,
    pending: Vec<u8>,
    offset: usize,
    step: u64,
}

impl Generator {
    fn refill(&mut self) {
        self.pending.clear();
        self.offset = 0;
        let angle = (self.step % 360) as f64 * std::f64::consts::PI / 180.0;
        let e = self.step as f64 * 0.0331;
        let line = format!(
            "G1 X{:.3} Y{:.3} E{:.5} F1800 ; perimeter\n",
            20.0 * angle.cos(),
            20.0 * angle.sin(),
            e
        );
        self.pending.extend_from_slice(line.as_bytes());
        if self.step.is_multiple_of(360) {
            self.pending.extend_from_slice(b";LAYER_CHANGE\n;Z:0.2\n");
        }
        self.step += 1;
    }
}

impl Read for Generator {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let mut written = 0;
        while written < buf.len() && self.remaining > 0 {
            if self.offset == self.pending.len() {
                self.refill();
            }
            let n = (self.pending.len() - self.offset)
                .min(buf.len() - written)
                .min(self.remaining as usize);
            buf[written..written + n].copy_from_slice(&self.pending[self.offset..self.offset + n]);
            self.offset += n;
            written += n;
            self.remaining -= n as u64;
        }
        Ok(written)
    }
}

fn main() {
    let mebibytes: u64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1024);
    let generator = Generator {
        remaining: mebibytes << 20,
        pending: Vec::new(),
        offset: 0,
        step: 0,
    };
    let started = std::time::Instant::now();
    let mut moves = 0u64;
    let mut errors = 0u64;
    for command in Commands::from_reader(BufReader::with_capacity(64 << 10, generator), "generated")
    {
        match command {
            Ok(c) if matches!(c.value, Command::Move(_)) => moves += 1,
            Ok(_) => {}
            Err(_) => errors += 1,
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    println!(
        "{mebibytes} MiB streamed: {moves} moves, {errors} errors, {seconds:.2} s ({:.0} MB/s)",
        (mebibytes << 20) as f64 / 1e6 / seconds
    );
}
