//! Fuzz findings kept as regression tests: every input in `tests/fuzz_regressions/` (crash, out-of-memory
//! and timeout inputs from `fuzz/artifacts/`) runs through the command its fuzz target drives: `convert-*`
//! through `convert` for the example polar machine, the others through `run` on the example Cartesian
//! machine. Each must end in time with success or a clean diagnostic (exit 0 or 1), never a panic or an
//! abort, within the memory bound.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{binary, example_machine, peak_rss_kb};

const RSS_LIMIT_KB: u64 = 64 * 1024;
const TIME_LIMIT: Duration = Duration::from_secs(20);

fn check_input(path: &Path) -> Result<(), String> {
    let scratch = tempfile::tempdir().map_err(|e| e.to_string())?;
    let mut command = Command::new(binary());
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if name.starts_with("convert-") {
        command
            .args(["convert", "-c"])
            .arg(example_machine("polar"))
            .arg(path);
        command
            .arg("-o")
            .arg(scratch.path().join("converted.gcode"));
    } else {
        command
            .args(["run", "-c"])
            .arg(example_machine("cartesian"))
            .arg(path);
    }
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start jointspace: {e}"))?;
    let started = Instant::now();
    let mut peak = 0;
    let status = loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            break status;
        }
        peak = peak.max(peak_rss_kb(child.id()).unwrap_or(0));
        if started.elapsed() > TIME_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("still running after {TIME_LIMIT:?}"));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut stderr = String::new();
    if let Some(mut pipe) = child.stderr.take() {
        let _ = std::io::Read::read_to_string(&mut pipe, &mut stderr);
    }
    let mut problems = Vec::new();
    if !matches!(status.code(), Some(0 | 1)) {
        problems.push(format!("ended with {status}"));
    }
    if stderr.contains("panicked") || stderr.contains("memory allocation") {
        problems.push("panicked or aborted".to_string());
    }
    if peak > RSS_LIMIT_KB {
        problems.push(format!("peak RSS {peak} kB above {RSS_LIMIT_KB} kB"));
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{}\n{}",
            problems.join("; "),
            stderr.lines().take(8).collect::<Vec<_>>().join("\n")
        ))
    }
}

#[test]
fn fuzz_findings_end_cleanly() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut inputs: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("tests/fuzz_regressions exists")
        .flatten()
        .map(|e| e.path())
        .collect();
    inputs.sort();
    assert!(
        !inputs.is_empty(),
        "no fuzz regression inputs in {}",
        dir.display()
    );
    let failures: Vec<String> = inputs
        .iter()
        .filter_map(|input| {
            check_input(input)
                .err()
                .map(|e| format!("{}: {e}", input.display()))
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
