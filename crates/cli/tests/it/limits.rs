//! Limits that must hold on inputs of any size: bounded memory on a generated stream piped through stdin
//! (never stored), linear time on long files, many tiny moves and very long lines.

use std::io::Write;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{CircleStream, binary, example_machine, peak_rss_kb};

const MB: u64 = 1 << 20;

/// Peak RSS the `run` pipeline may use, whatever the input length.
const RSS_LIMIT_KB: u64 = 64 * 1024;

/// Pipes `bytes` of generated G-code into `run -c cartesian.cfg -`, watching the child's peak RSS.
/// Returns (peak RSS in kB, seconds, stdout).
fn run_stream(bytes: u64) -> (u64, f64, String) {
    let started = Instant::now();
    let mut child = Command::new(binary())
        .args(["run", "-c"])
        .arg(example_machine("cartesian"))
        .arg("-")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start jointspace");
    let pid = child.id();
    let mut stdin = child.stdin.take().expect("piped stdin");
    let writer = std::thread::spawn(move || {
        let written = CircleStream::new().write_to(&mut stdin, bytes);
        drop(stdin);
        written
    });
    let mut peak = 0;
    while child.try_wait().expect("poll child").is_none() {
        peak = peak.max(peak_rss_kb(pid).unwrap_or(0));
        std::thread::sleep(Duration::from_millis(20));
    }
    let written = writer.join().expect("writer thread");
    let output = child.wait_with_output().expect("collect output");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success(),
        "run failed on the generated stream: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        written >= bytes,
        "only {written} of {bytes} bytes were consumed"
    );
    (peak, started.elapsed().as_secs_f64(), stdout)
}

fn check_memory(bytes: u64) {
    let (peak_kb, seconds, stdout) = run_stream(bytes);
    println!(
        "run on a {} MB stdin stream: peak RSS {:.1} MB, {seconds:.1} s ({:.0} MB/s)",
        bytes / MB,
        peak_kb as f64 / 1024.0,
        (bytes / MB) as f64 / seconds
    );
    assert!(peak_kb > 0, "could not read the child's VmHWM");
    assert!(
        peak_kb <= RSS_LIMIT_KB,
        "peak RSS {peak_kb} kB is above {RSS_LIMIT_KB} kB:\n{stdout}"
    );
    // 126 chords per circle, two queues: the move counts tell the whole stream was planned.
    let expected_moves = bytes / 3600 * 126;
    assert!(
        stdout
            .lines()
            .any(|l| l.contains("toolhead") && moves_in(l) >= expected_moves),
        "fewer moves than the stream holds (expected ≥ {expected_moves}):\n{stdout}"
    );
}

/// The toolhead move count of the summary's `moves` line.
fn moves_in(line: &str) -> u64 {
    line.split_whitespace()
        .find_map(|w| w.parse().ok())
        .unwrap_or(0)
}

#[test]
fn memory_stays_bounded_on_a_long_stdin_stream() {
    // Release builds (CI) stream 200 MB; a debug build runs a tenth of that to stay quick.
    let bytes = if cfg!(debug_assertions) {
        20 * MB
    } else {
        200 * MB
    };
    check_memory(bytes);
}

/// The acceptance measurement: a 2 GB stream. Run with `JOINTSPACE_BIG_TESTS=1 cargo test --release`.
#[test]
fn memory_stays_bounded_on_a_2_gb_stdin_stream() {
    if std::env::var_os("JOINTSPACE_BIG_TESTS").is_none() {
        println!("skipped: set JOINTSPACE_BIG_TESTS=1 to stream 2 GB through `run`");
        return;
    }
    check_memory(2048 * MB);
}

/// Seconds `run` takes on `input` (best of two, to damp noise from other processes).
fn run_time(input: &[u8]) -> f64 {
    (0..2)
        .map(|_| {
            let started = Instant::now();
            let mut child = Command::new(binary())
                .args(["run", "-c"])
                .arg(example_machine("cartesian"))
                .arg("-")
                .stdin(Stdio::piped())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("start jointspace");
            let mut stdin = child.stdin.take().expect("piped stdin");
            // An input may be refused early (a line too long): the pipe then closes.
            let _ = stdin.write_all(input);
            drop(stdin);
            child.wait().expect("wait for jointspace");
            started.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Time on 4× the input must grow about 4× (linear), far from 16× (quadratic).
fn assert_linear(what: &str, make: impl Fn(u64) -> Vec<u8>, small: u64) {
    let small_time = run_time(&make(small));
    let large_time = run_time(&make(4 * small));
    let ratio = large_time / small_time;
    println!("{what}: {small_time:.3} s → {large_time:.3} s for 4× the input (×{ratio:.1})");
    // Below a quarter of a second the ratio is mostly process start-up and scheduling noise; a quadratic
    // cost at these sizes would take far longer than that.
    assert!(
        ratio < 8.0 || large_time < 0.25,
        "{what}: 4× the input took ×{ratio:.1} the time ({small_time:.3} s → {large_time:.3} s)"
    );
}

fn scale(mb: u64) -> u64 {
    if cfg!(debug_assertions) {
        mb * MB / 8
    } else {
        mb * MB
    }
}

#[test]
fn many_tiny_moves_take_linear_time() {
    assert_linear(
        "0.1 mm moves",
        |bytes| CircleStream::new().to_vec(bytes),
        scale(8),
    );
}

#[test]
fn a_very_long_comment_line_takes_linear_time() {
    assert_linear(
        "one long comment line",
        |bytes| {
            let mut text = b"G28\nG1 X10 Y10 F3000 ;".to_vec();
            text.resize(bytes as usize, b'c');
            text.extend_from_slice(b"\nG1 X20 Y20\n");
            text
        },
        scale(6),
    );
}

#[test]
fn lines_of_many_words_take_linear_time() {
    assert_linear(
        "lines of 1000 words",
        |bytes| {
            let line = format!("G1{} F3000\n", " X10.125 Y20.5".repeat(500));
            let mut text = b"G28\n".to_vec();
            while (text.len() as u64) < bytes {
                text.extend_from_slice(line.as_bytes());
            }
            text
        },
        scale(2),
    );
}

/// A 30 MB line of packed words (`X1X1…`, 15 million words) is refused at the per-line word limit, with
/// its place, and without ever holding the words in memory.
#[test]
fn a_line_of_millions_of_words_is_refused_in_bounded_memory() {
    let mut text = b"G28\nG1".to_vec();
    while text.len() < 30 * MB as usize {
        text.extend_from_slice(b"X1");
    }
    text.extend_from_slice(b"\nG1 X20 Y20\n");
    let mut child = Command::new(binary())
        .args(["run", "-c"])
        .arg(example_machine("cartesian"))
        .arg("-")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start jointspace");
    let pid = child.id();
    let mut stdin = child.stdin.take().expect("piped stdin");
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(&text);
    });
    let mut peak = 0;
    while child.try_wait().expect("poll child").is_none() {
        peak = peak.max(peak_rss_kb(pid).unwrap_or(0));
        std::thread::sleep(Duration::from_millis(5));
    }
    writer.join().expect("writer thread");
    let output = child.wait_with_output().expect("collect output");
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!(
        "30 MB line of words: peak RSS {:.1} MB",
        peak as f64 / 1024.0
    );
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("<stdin>:2:") && stderr.contains("more than 1024"),
        "{stderr}"
    );
    assert!(
        peak <= RSS_LIMIT_KB,
        "peak RSS {peak} kB is above {RSS_LIMIT_KB} kB"
    );
}

#[test]
fn a_long_run_of_commands_without_moves_takes_linear_time() {
    assert_linear(
        "many non-move commands",
        |bytes| {
            let mut text = b"G28\n".to_vec();
            while (text.len() as u64) < bytes {
                text.extend_from_slice(b"M106 S255\nM104 S200\nG92 E0\n;LAYER_CHANGE\n");
            }
            text
        },
        scale(4),
    );
}

/// A spiral vase of `turns` turns (radius 30 mm about (60, 0), 0.1 mm per turn, 64 chords a turn), extruding
/// all the way up.
fn spiral_vase(turns: u32) -> String {
    let mut text = String::from("G28\nM83\nG1 X90 Y0 Z0.2 F3000\n");
    for i in 1..=turns * 64 {
        let angle = std::f64::consts::TAU * f64::from(i) / 64.0;
        let z = 0.2 + 0.1 * f64::from(i) / 64.0;
        text += &format!(
            "G1 X{:.3} Y{:.3} Z{z:.4} E0.1\n",
            60.0 + 30.0 * angle.cos(),
            30.0 * angle.sin()
        );
    }
    text
}

/// Peak RSS (kB), the layer count and the size of report.txt of `simulate` on a spiral of `turns` turns.
fn simulate_spiral(turns: u32) -> (u64, u64, u64) {
    simulate_spiral_with(turns, &[])
}

/// [`simulate_spiral`] with `extra` arguments.
fn simulate_spiral_with(turns: u32, extra: &[&str]) -> (u64, u64, u64) {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("vase.gcode");
    std::fs::write(&input, spiral_vase(turns)).expect("write input");
    let cfg = example_machine("polar");
    let mut child = Command::new(binary())
        .arg("simulate")
        .arg("-c")
        .arg(&cfg)
        .arg("--actual")
        .arg(&cfg)
        .arg(&input)
        .arg("-o")
        .arg(scratch.path().join("report"))
        .args(extra)
        // Nothing read from the child while it runs: its output must not fill a pipe.
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(scratch.path().join("stderr.txt")).expect("stderr file"))
        .spawn()
        .expect("start jointspace");
    let pid = child.id();
    let mut peak = 0;
    while child.try_wait().expect("poll child").is_none() {
        peak = peak.max(peak_rss_kb(pid).unwrap_or(0));
        std::thread::sleep(Duration::from_millis(20));
    }
    let status = child.wait().expect("exit status");
    let stderr = std::fs::read_to_string(scratch.path().join("stderr.txt")).unwrap_or_default();
    assert!(status.success(), "simulate failed: {stderr}");
    let json: serde_json::Value = serde_json::from_slice(
        &std::fs::read(scratch.path().join("report/report.json")).expect("report.json"),
    )
    .expect("json report");
    let layers = json["before"]["layer_count"].as_u64().expect("layer count");
    let text = std::fs::metadata(scratch.path().join("report/report.txt")).expect("report.txt");
    (peak, layers, text.len())
}

#[test]
fn simulate_memory_and_report_stay_flat_on_a_long_spiral() {
    let (small_rss, small_layers, small_text) = simulate_spiral(300);
    let (large_rss, large_layers, large_text) = simulate_spiral(1200);
    println!(
        "spiral 300 turns: {small_layers} layers, peak {:.1} MB, report.txt {small_text} B; 1200 turns: \
         {large_layers} layers, peak {:.1} MB, report.txt {large_text} B",
        small_rss as f64 / 1024.0,
        large_rss as f64 / 1024.0
    );
    // One layer per turn.
    assert!(small_layers.abs_diff(300) <= 1 && large_layers.abs_diff(1200) <= 1);
    assert!(small_rss > 0, "could not read the child's VmHWM");
    // Four times the print: memory and report hardly grow.
    assert!(
        large_rss <= small_rss + small_rss / 4,
        "{small_rss} kB → {large_rss} kB"
    );
    assert!(
        large_text <= small_text + small_text / 4,
        "{small_text} B → {large_text} B"
    );
}

/// `--correct` simulates twice, one path in memory at a time: its peak stays within a third more than one
/// simulation's (the rest is the allocator keeping the first simulation's freed memory), and grows no more
/// with a longer print than one simulation does.
#[test]
fn simulate_correct_holds_one_simulation_at_a_time() {
    let (plain, _, _) = simulate_spiral(300);
    let (corrected, layers, _) = simulate_spiral_with(300, &["--correct"]);
    let (long, _, _) = simulate_spiral_with(1200, &["--correct"]);
    println!(
        "spiral 300 turns: peak {:.1} MB, with --correct {:.1} MB; 1200 turns with --correct {:.1} MB",
        plain as f64 / 1024.0,
        corrected as f64 / 1024.0,
        long as f64 / 1024.0
    );
    assert!(layers.abs_diff(300) <= 1);
    assert!(
        corrected <= plain + plain / 3,
        "{plain} kB → {corrected} kB"
    );
    assert!(
        long <= corrected + corrected / 4,
        "{corrected} kB → {long} kB"
    );
}
