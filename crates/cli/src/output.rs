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

/// `text` safe to show on a terminal: control characters (other than newline and tab), DEL and the C1 controls
/// written as `\x1B`-style escapes, so a G-code file or a file name cannot retitle, recolour or clear the user's
/// terminal through an error message or a report.
pub fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    let unsafe_char = |c: char| (c.is_control() && c != '\n' && c != '\t') || c == '\u{7f}';
    if !text.chars().any(unsafe_char) {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if unsafe_char(c) {
            out.push_str(&format!("\\x{:02X}", u32::from(c)));
        } else {
            out.push(c);
        }
    }
    std::borrow::Cow::Owned(out)
}

/// Whether standard stream `fd` (0 or 1) was closed when the process started (`<&-`, `>&-`). Rust's runtime puts
/// `/dev/null` on a closed standard descriptor, opened for reading and writing, so a closed input would read as an
/// empty file and a closed output swallow every report; a shell's `< /dev/null` or `> /dev/null` opens it one way
/// only, which tells the two apart (Linux: `/proc/self/fd` and `fdinfo`).
pub fn was_closed_at_start(fd: u8) -> bool {
    let is_null = std::fs::read_link(format!("/proc/self/fd/{fd}"))
        .is_ok_and(|target| target == Path::new("/dev/null"));
    let read_write = || {
        let info = std::fs::read_to_string(format!("/proc/self/fdinfo/{fd}")).unwrap_or_default();
        info.lines()
            .find_map(|l| l.strip_prefix("flags:"))
            .and_then(|flags| u32::from_str_radix(flags.trim(), 8).ok())
            .is_some_and(|flags| flags & 0o3 == 0o2)
    };
    is_null && read_write()
}

/// Print to standard output. When the reader has gone (`jointspace … | head`), the rest is dropped quietly
/// (not a panic, as `print!` would) and the command runs on to its own exit status, so one that found
/// errors still exits non-zero.
pub fn stdout(text: &str) {
    use std::io::ErrorKind;
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    static CLOSED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    if *CLOSED.get_or_init(|| was_closed_at_start(1)) {
        // Nowhere to put the results the command exists to give: an error, not a silent success.
        eprintln!("cannot write to standard output: it is closed");
        std::process::exit(1);
    }
    let text = printable(text);
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

/// `eprintln!` through [`printable`]: messages that carry a file's name or text.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => { eprintln!("{}", $crate::output::printable(&format!($($arg)*))) };
}

/// `println!` through [`stdout`].
#[macro_export]
macro_rules! outln {
    () => { $crate::output::stdout("\n") };
    ($($arg:tt)*) => { $crate::output::stdout(&format!("{}\n", format!($($arg)*))) };
}
