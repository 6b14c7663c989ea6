//! Opening inputs: a G-code file (or `-` for standard input) behind a buffered, progress-reporting reader.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{BufReader, Read};
use std::path::Path;
use std::time::{Duration, Instant};

/// A G-code input: the buffer is concrete and only the source behind it is dynamic, so the reader's
/// `fill_buf`/`consume` on every line are direct (inlined) calls, and only a refill (one per
/// [`BUFFER_BYTES`]) goes through a virtual call.
pub type GcodeInput = BufReader<Box<dyn Read>>;

/// Read size: few system calls, and the buffer stays in the cache (256 KiB measured no faster for `stats`).
const BUFFER_BYTES: usize = 1 << 16;

/// A buffered reader over a file or stdin, with a progress bar on stderr for a file whose reading takes more
/// than [`PROGRESS_DELAY`] (hidden automatically when stderr is not a terminal).
pub fn open_gcode(path: &Path) -> anyhow::Result<(GcodeInput, String, ProgressBar)> {
    crate::output::register_input(path);
    if path == Path::new("-") {
        // A closed standard input would read as an empty file and pass every check.
        if crate::output::was_closed_at_start(0) {
            anyhow::bail!("cannot read standard input: it is closed");
        }
        let bar = ProgressBar::hidden();
        let reader: Box<dyn Read> = Box::new(Interruptible(std::io::stdin()));
        return Ok((
            BufReader::with_capacity(BUFFER_BYTES, reader),
            "<stdin>".into(),
            bar,
        ));
    }
    let file = std::fs::File::open(path)
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e}", path.display()))?;
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    // Hidden at first; shown (on a terminal) once reading has taken a second, whatever the file's size: a
    // short run shows nothing, a long one (a slow simulation of a small file too) shows where it is.
    let bar = ProgressBar::with_draw_target(Some(size), ProgressDrawTarget::hidden());
    if let Ok(style) =
        ProgressStyle::with_template("{bar:40} {bytes}/{total_bytes} {bytes_per_sec} eta {eta}")
    {
        bar.set_style(style);
    }
    let reader: Box<dyn Read> = Box::new(Interruptible(DelayedBar {
        inner: bar.wrap_read(file),
        bar: bar.clone(),
        started: Instant::now(),
        shown: false,
    }));
    Ok((
        BufReader::with_capacity(BUFFER_BYTES, reader),
        path.display().to_string(),
        bar,
    ))
}

/// How long a run reads before its progress bar appears.
pub const PROGRESS_DELAY: Duration = Duration::from_secs(1);

/// Shows `bar` on standard error once reading has gone on for [`PROGRESS_DELAY`].
struct DelayedBar<R> {
    inner: R,
    bar: ProgressBar,
    started: Instant,
    shown: bool,
}

impl<R: Read> Read for DelayedBar<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if !self.shown && self.started.elapsed() >= PROGRESS_DELAY {
            self.shown = true;
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        self.inner.read(buf)
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn delayed(started: Instant) -> DelayedBar<&'static [u8]> {
        DelayedBar {
            inner: b"G1 X1\n",
            bar: ProgressBar::hidden(),
            started,
            shown: false,
        }
    }

    #[test]
    fn the_bar_appears_after_a_second_of_reading_whatever_the_size() {
        let mut buf = [0u8; 4];
        let mut quick = delayed(Instant::now());
        assert_eq!(quick.read(&mut buf).expect("read"), 4);
        assert!(!quick.shown, "a short run shows no bar");
        let Some(long_ago) = Instant::now().checked_sub(PROGRESS_DELAY * 2) else {
            return;
        };
        let mut slow = delayed(long_ago);
        assert_eq!(slow.read(&mut buf).expect("read"), 4);
        assert!(slow.shown, "a long run of a 6-byte input shows its bar");
    }
}
