//! Opening inputs: a G-code file (or `-` for standard input) behind a buffered, progress-reporting reader.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// A buffered reader over a file or stdin, with a progress bar on stderr for large files
/// (hidden automatically when stderr is not a terminal).
pub fn open_gcode(path: &Path) -> anyhow::Result<(Box<dyn BufRead>, String, ProgressBar)> {
    crate::output::register_input(path);
    if path == Path::new("-") {
        let bar = ProgressBar::hidden();
        let reader = Interruptible(std::io::stdin());
        return Ok((
            Box::new(BufReader::with_capacity(1 << 16, reader)),
            "<stdin>".into(),
            bar,
        ));
    }
    let file = std::fs::File::open(path)
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e}", path.display()))?;
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    let bar = if size > 16 << 20 {
        let bar = ProgressBar::new(size);
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {bytes}/{total_bytes} {bytes_per_sec} eta {eta}")
        {
            bar.set_style(style);
        }
        bar
    } else {
        ProgressBar::hidden()
    };
    let reader: Box<dyn Read> = Box::new(Interruptible(bar.wrap_read(file)));
    Ok((
        Box::new(BufReader::with_capacity(1 << 16, reader)),
        path.display().to_string(),
        bar,
    ))
}

/// A reader that fails once the user pressed Ctrl-C: every pipeline reading through it stops with an error,
/// and its temporary output files are dropped instead of renamed into place.
struct Interruptible<R>(R);

impl<R: Read> Read for Interruptible<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if crate::interrupt::requested() {
            return Err(std::io::Error::other(crate::interrupt::INTERRUPTED_MESSAGE));
        }
        self.0.read(buf)
    }
}
