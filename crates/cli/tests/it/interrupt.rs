//! Interruption: SIGINT to a running `run` or `convert` (fed an endless stdin stream) must stop it with a
//! non-zero exit and leave no output at all, not even a temporary file. Needs `crate::interrupt` wired
//! into the pipelines.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{CircleStream, binary, example_machine, files_under};

/// Starts `args` with an endless G-code stream on stdin (it stops when the child closes the pipe).
fn start_streaming(
    args: &[&std::ffi::OsStr],
    stream: CircleStream,
) -> (Child, std::thread::JoinHandle<u64>) {
    let mut child = Command::new(binary())
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start jointspace");
    let mut stdin = child.stdin.take().expect("piped stdin");
    let writer = std::thread::spawn(move || stream.write_to(&mut stdin, u64::MAX));
    (child, writer)
}

/// Waits until `dir` holds a file (the run is writing), at most `limit`.
fn wait_for_output(dir: &Path, limit: Duration) -> bool {
    let started = Instant::now();
    while started.elapsed() < limit {
        if !files_under(dir).is_empty() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

fn send_sigint(pid: u32) {
    send_signal(pid, "INT");
}

fn send_signal(pid: u32, signal: &str) {
    let status = Command::new("kill")
        .args([&format!("-{signal}"), &pid.to_string()])
        .status()
        .expect("run kill");
    assert!(status.success(), "kill -{signal} {pid} failed");
}

/// Waits for the child at most `limit`; kills it (and fails) if it does not stop.
fn wait_or_kill(child: &mut Child, limit: Duration) -> std::process::ExitStatus {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("poll child") {
            return status;
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("jointspace did not stop within {limit:?} of SIGINT");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn check_interrupted(args: &[&std::ffi::OsStr], stream: CircleStream, out: &Path) {
    check_stopped_by(args, stream, out, "INT");
}

fn check_stopped_by(args: &[&std::ffi::OsStr], stream: CircleStream, out: &Path, signal: &str) {
    let (mut child, writer) = start_streaming(args, stream);
    // Temporary files show the run is under way; a command that keeps its output in memory until the end
    // shows none, so after a few seconds it is interrupted anyway.
    wait_for_output(out, Duration::from_secs(3));
    // Let it write for a while, so buffers and temporary files are mid-way.
    std::thread::sleep(Duration::from_millis(300));
    send_signal(child.id(), signal);
    let status = wait_or_kill(&mut child, Duration::from_secs(10));
    let _ = writer.join();
    let mut stderr = String::new();
    if let Some(mut pipe) = child.stderr.take() {
        let _ = std::io::Read::read_to_string(&mut pipe, &mut stderr);
    }
    assert!(!status.success(), "an interrupted run exited successfully");
    assert!(
        !stderr.contains("panicked"),
        "the interrupted run panicked:\n{stderr}"
    );
    let left = files_under(out);
    assert!(
        left.is_empty(),
        "an interrupted run left files behind ({status}): {left:?}"
    );
    let folders: Vec<_> = std::fs::read_dir(out)
        .expect("out lists")
        .flatten()
        .collect();
    assert!(folders.is_empty(), "an interrupted run left {folders:?}");
}

/// `run` of an endless stream with step files and the moves CSV into a fresh `out` folder, stopped by `signal`:
/// nothing left behind, not even the step folder.
fn stream_run_stopped_by(signal: &str) {
    let scratch = tempfile::tempdir().expect("temp dir");
    let out = scratch.path().join("out");
    std::fs::create_dir_all(&out).expect("output folder");
    let config = example_machine("cartesian");
    let steps = out.join("steps");
    let moves = out.join("moves.csv");
    let args: Vec<&std::ffi::OsStr> = vec![
        "run".as_ref(),
        "-c".as_ref(),
        config.as_os_str(),
        "-".as_ref(),
        "--steps".as_ref(),
        steps.as_os_str(),
        "--moves".as_ref(),
        moves.as_os_str(),
    ];
    check_stopped_by(&args, CircleStream::new(), &out, signal);
}

#[test]
fn sigint_during_run_leaves_no_output() {
    stream_run_stopped_by("INT");
}

/// SIGTERM (a service manager, `kill`) stops a run as Ctrl-C does.
#[test]
fn sigterm_during_run_leaves_no_output() {
    stream_run_stopped_by("TERM");
}

#[test]
fn sigint_during_run_on_a_file_leaves_no_output() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("print.gcode");
    let mut file = std::io::BufWriter::new(std::fs::File::create(&input).expect("create input"));
    // About 20 s of work for `run`: it is interrupted long before the end.
    CircleStream::new().write_to(&mut file, 1 << 30);
    std::io::Write::flush(&mut file).expect("write input");
    drop(file);
    let out = scratch.path().join("out");
    std::fs::create_dir_all(&out).expect("output folder");
    let config = example_machine("cartesian");
    let steps = out.join("steps");
    let moves = out.join("moves.csv");
    let mut child = Command::new(binary())
        .arg("run")
        .arg("-c")
        .arg(&config)
        .arg(&input)
        .arg("--steps")
        .arg(&steps)
        .arg("--moves")
        .arg(&moves)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start jointspace");
    wait_for_output(&out, Duration::from_secs(3));
    std::thread::sleep(Duration::from_millis(300));
    send_sigint(child.id());
    let status = wait_or_kill(&mut child, Duration::from_secs(10));
    assert!(!status.success(), "an interrupted run exited successfully");
    let left = files_under(&out);
    assert!(
        left.is_empty(),
        "an interrupted run left files behind ({status}): {left:?}"
    );
}

/// Whether the binary has a `convert` subcommand (it arrived after `run`).
fn has_convert() -> bool {
    Command::new(binary())
        .args(["convert", "--help"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn sigint_during_convert_leaves_no_output() {
    if !has_convert() {
        println!("skipped: this jointspace has no `convert` subcommand");
        return;
    }
    let scratch = tempfile::tempdir().expect("temp dir");
    let out = scratch.path().join("out");
    std::fs::create_dir_all(&out).expect("output folder");
    let config = example_machine("polar");
    let target = out.join("converted.gcode");
    let args: Vec<&std::ffi::OsStr> = vec![
        "convert".as_ref(),
        "-c".as_ref(),
        config.as_os_str(),
        "-".as_ref(),
        "-o".as_ref(),
        target.as_os_str(),
    ];
    // Circles at (60, 20): well inside the polar arm's 150 mm reach and away from the bed centre.
    check_interrupted(&args, CircleStream::around([60.0, 20.0]), &out);
}
