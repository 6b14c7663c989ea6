//! Writing output files safely: into a temporary file beside the target, renamed into place only when complete,
//! so a failed or interrupted run never leaves a half-written file.

use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

pub use outfile::{is_stdio, register_input, write_atomically};

/// An error when `path` is one of the registered inputs (compared as files: device and inode).
pub fn refuse_input(path: &Path) -> anyhow::Result<()> {
    Ok(outfile::refuse_input(path)?)
}

/// Write an output file through `fill` ([`write_atomically`]), or standard output when `path` is `-`.
pub fn write_output<F>(path: &Path, fill: F) -> anyhow::Result<()>
where
    F: FnOnce(&mut dyn Write) -> anyhow::Result<()>,
{
    if !is_stdio(path) {
        return write_atomically(path, fill);
    }
    let mut out = BufWriter::new(std::io::stdout().lock());
    fill(&mut out)?;
    out.flush()?;
    Ok(())
}

/// Refuses `-` where an output is a directory.
pub fn directory_output(path: &Path) -> anyhow::Result<()> {
    if is_stdio(path) {
        anyhow::bail!("`-` (standard output) cannot take this output: it is a directory of files");
    }
    Ok(())
}

/// Standard output's reader has gone (`jointspace … | head`).
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Print to standard output. When the reader has gone (`jointspace … | head`), the rest is dropped quietly
/// (not a panic, as `print!` would) and the command runs on to its own exit status, so one that found
/// errors still exits non-zero.
pub fn stdout(text: &str) {
    use std::io::ErrorKind;
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
        if e.kind() != ErrorKind::BrokenPipe {
            eprintln!("cannot write to standard output: {e}");
            std::process::exit(1);
        }
    }
}

/// `print!` through [`stdout`].
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => { $crate::output::stdout(&format!($($arg)*)) };
}

/// `println!` through [`stdout`].
#[macro_export]
macro_rules! outln {
    () => { $crate::output::stdout("\n") };
    ($($arg:tt)*) => { $crate::output::stdout(&format!("{}\n", format!($($arg)*))) };
}
