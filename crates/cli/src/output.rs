//! Writing output files safely: into a temporary file beside the target, renamed into place only when complete,
//! so a failed or interrupted run never leaves a half-written file.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// The files this run reads (identified by device and inode, not by name), which no output may replace.
static INPUTS: Mutex<Vec<(FileId, PathBuf)>> = Mutex::new(Vec::new());

/// A file's identity: the same file under any name, through links or `..`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FileId {
    dev: u64,
    ino: u64,
}

#[cfg(unix)]
fn file_id(path: &Path) -> Option<FileId> {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(path).ok()?;
    Some(FileId {
        dev: m.dev(),
        ino: m.ino(),
    })
}

#[cfg(not(unix))]
fn file_id(path: &Path) -> Option<FileId> {
    // Without inodes: the canonical path's hash stands for the file.
    use std::hash::{Hash, Hasher};
    let canonical = std::fs::canonicalize(path).ok()?;
    let mut h = std::collections::hash_map::DefaultHasher::new();
    canonical.hash(&mut h);
    Some(FileId {
        dev: 0,
        ino: h.finish(),
    })
}

/// Records that this run reads `path` (`-`: standard input, when it is a file), so that no output replaces it.
pub fn register_input(path: &Path) {
    let (id, name) = if is_stdio(path) {
        (file_id(Path::new("/dev/stdin")), PathBuf::from("<stdin>"))
    } else {
        (file_id(path), path.to_path_buf())
    };
    if let (Some(id), Ok(mut inputs)) = (id, INPUTS.lock()) {
        inputs.push((id, name));
    }
}

/// An error when `path` is one of the registered inputs (compared as files: device and inode).
pub fn refuse_input(path: &Path) -> anyhow::Result<()> {
    let Some(id) = file_id(path) else {
        return Ok(());
    };
    let inputs = INPUTS
        .lock()
        .map_err(|_| anyhow::anyhow!("input registry poisoned"))?;
    match inputs.iter().find(|(input, _)| *input == id) {
        Some((_, name)) => Err(anyhow::anyhow!(
            "refusing to write {}: it is the input {} (the same file); choose another output",
            path.display(),
            name.display()
        )),
        None => Ok(()),
    }
}

/// `-`: standard input or output.
pub fn is_stdio(path: &Path) -> bool {
    path.as_os_str() == "-"
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

/// Write `path` through `fill`; the file appears only if `fill` succeeds. It never replaces an input of this
/// run ([`register_input`]); it gets the permissions of any newly created file (0666 less the umask).
pub fn write_atomically<F>(path: &Path, fill: F) -> anyhow::Result<()>
where
    F: FnOnce(&mut dyn Write) -> anyhow::Result<()>,
{
    let temp = temp_file_for(path)?;
    {
        let mut writer = BufWriter::new(temp.as_file());
        fill(&mut writer)?;
        writer.flush()?;
    }
    temp.persist(path)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

/// The temporary file that becomes `path` when persisted: beside it (same file system), never for an input of
/// this run, created with the permissions of any new file (0666 less the umask; tempfile's own are 0600).
pub fn temp_file_for(path: &Path) -> anyhow::Result<tempfile::NamedTempFile> {
    refuse_input(path)?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let mut builder = tempfile::Builder::new();
    builder.prefix(".jointspace-");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // The mode is given at creation, so the umask applies to it as to any new file.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder
        .tempfile_in(dir)
        .map_err(|e| anyhow::anyhow!("cannot create a temporary file in {}: {e}", dir.display()))
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
