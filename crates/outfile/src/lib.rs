//! Output files written whole or not at all: into a temporary file beside the target (same file system), renamed
//! into place only when complete, so a failed or interrupted run never leaves a half-written file; and never over
//! one of the run's inputs (compared as files, by device and inode, not by name).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("refusing to write {}: it is the input {} (the same file); choose another output", .path.display(), .input.display())]
    IsInput { path: PathBuf, input: PathBuf },
    #[error("cannot create {}: {source}", .path.display())]
    CreateDir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot create a temporary file in {}: {source}", .dir.display())]
    Temp {
        dir: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write {}: {source}", .path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The files this run reads, which no output may replace.
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

/// `-`: standard input or output.
pub fn is_stdio(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Records that this run reads `path` (`-`: standard input, when it is a file), so that no output replaces it.
pub fn register_input(path: &Path) {
    let (id, name) = if is_stdio(path) {
        (file_id(Path::new("/dev/stdin")), PathBuf::from("<stdin>"))
    } else {
        (file_id(path), path.to_path_buf())
    };
    if let Some(id) = id {
        inputs().push((id, name));
    }
}

/// The registry, also after a thread panicked while holding it (it is only ever pushed to).
fn inputs() -> std::sync::MutexGuard<'static, Vec<(FileId, PathBuf)>> {
    INPUTS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// An error when `path` is one of the registered inputs.
pub fn refuse_input(path: &Path) -> Result<(), OutputError> {
    let Some(id) = file_id(path) else {
        return Ok(());
    };
    match inputs().iter().find(|(input, _)| *input == id) {
        Some((_, input)) => Err(OutputError::IsInput {
            path: path.to_path_buf(),
            input: input.clone(),
        }),
        None => Ok(()),
    }
}

/// The temporary file that becomes `path`: beside it, never for an input of this run, created with the
/// permissions of any new file (0666 less the umask; tempfile's own are 0600).
fn temp_file_for(path: &Path) -> Result<tempfile::NamedTempFile, OutputError> {
    refuse_input(path)?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).map_err(|source| OutputError::CreateDir {
        path: dir.to_path_buf(),
        source,
    })?;
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
        .map_err(|source| OutputError::Temp {
            dir: dir.to_path_buf(),
            source,
        })
}

/// A file being written: it appears at its path only when committed, and a dropped one leaves nothing.
#[derive(Debug)]
pub struct PendingFile {
    temp: tempfile::NamedTempFile,
    path: PathBuf,
}

impl PendingFile {
    /// Start writing `path` (refused when it is an input of this run).
    pub fn create(path: &Path) -> Result<PendingFile, OutputError> {
        Ok(PendingFile {
            temp: temp_file_for(path)?,
            path: path.to_path_buf(),
        })
    }

    /// The file to write into.
    pub fn file(&self) -> &std::fs::File {
        self.temp.as_file()
    }

    /// Another handle on the file to write into, owned (for writers that must own theirs).
    pub fn reopen(&self) -> Result<std::fs::File, OutputError> {
        self.temp.reopen().map_err(|e| write_error(&self.path, e))
    }

    /// Where the file goes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Put the complete file in place (its data synced first, so a crash cannot leave it empty).
    pub fn commit(self) -> Result<(), OutputError> {
        let path = self.path;
        self.temp
            .as_file()
            .sync_all()
            .map_err(|e| write_error(&path, e))?;
        self.temp
            .persist(&path)
            .map(drop)
            .map_err(|e| write_error(&path, e.error))
    }
}

/// `source` while writing `path`.
pub fn write_error(path: &Path, source: std::io::Error) -> OutputError {
    OutputError::Write {
        path: path.to_path_buf(),
        source,
    }
}

/// Write `path` through `fill`; the file appears only if `fill` succeeds. Errors of `fill` are the caller's own.
pub fn write_atomically<E, F>(path: &Path, fill: F) -> Result<(), E>
where
    E: From<OutputError>,
    F: FnOnce(&mut dyn Write) -> Result<(), E>,
{
    let pending = PendingFile::create(path)?;
    {
        let mut writer = BufWriter::new(pending.file());
        fill(&mut writer)?;
        writer.flush().map_err(|e| write_error(path, e))?;
    }
    Ok(pending.commit()?)
}

/// Write `bytes` to `path` whole or not at all.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomically(path, |w| {
        w.write_all(bytes).map_err(|e| write_error(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_fill_leaves_nothing_behind() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("out.txt");
        let result: Result<(), OutputError> = write_atomically(&path, |w| {
            w.write_all(b"half").map_err(|e| write_error(&path, e))?;
            Err(write_error(&path, std::io::Error::other("disk full")))
        });
        assert!(result.is_err());
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
        assert!(left.is_empty(), "{left:?}");
    }

    #[test]
    fn an_input_is_never_replaced_under_another_name() {
        let dir = tempfile::tempdir().expect("temp dir");
        let input = dir.path().join("in.gcode");
        std::fs::write(&input, "G1 X1\n").expect("write");
        register_input(&input);
        let other_name = dir.path().join(".").join("in.gcode");
        let err = write_bytes(&other_name, b"x").expect_err("refused");
        assert!(err.to_string().contains("it is the input"), "{err}");
        assert_eq!(std::fs::read(&input).expect("read"), b"G1 X1\n");
    }
}
