//! The bad-input catalogue: every folder under `tests/catalogue/` is one case (`input.gcode` and/or
//! `printer.cfg`, plus `expect.txt`). Each case runs the binary in a scratch copy of its folder and checks the
//! exit code, the `file:line:col` and phrases of the diagnostic, that nothing panicked, that no NaN or
//! infinity was printed or written, and that a failed run left no file behind.
//!
//! `expect.txt` holds `key: value` lines (`#` starts a comment):
//! - `command`: `run` (default; with `--steps out/steps --moves out/moves.csv`), `check`, `stats`,
//!   `convert` (with `-o out/converted.gcode`) or `calibrate-scan` (`calibrate scara --image FILE --dpi 600`, with
//!   `-o out/scara.json --plot out/found.png`) or `calibrate-fivebar` (`calibrate fivebar --measurements FILE`,
//!   with `-o out/fivebar.json --corrected out/fixed.cfg`);
//! - `exit`: the expected exit code (`1` for every error; `0` for the documented cases that only warn);
//! - `machine`: `cartesian`/`polar`/`scara`/`fivebar` (an example machine) or a file name in the case folder; without
//!   it, the case's `printer.cfg` if it has one, else the example Cartesian machine;
//! - `file`: the G-code argument (default `input.gcode`); `stdin: yes` pipes `input.gcode` through `-`;
//! - `generate`: `long-line` or `many-lines`, inputs too big to store, written at test time;
//! - `diagnostic`: a substring the output must contain (normally `input.gcode:LINE:COL`);
//! - `phrase`: further substrings (any number of lines).

use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use crate::common::{binary, example_machine, files_under, non_finite_words};

/// What one case expects.
#[derive(Debug, Default)]
struct Expect {
    command: String,
    exit: i32,
    machine: Option<String>,
    file: Option<String>,
    stdin: bool,
    generate: Option<String>,
    diagnostic: Option<String>,
    phrases: Vec<String>,
}

fn parse_expect(text: &str) -> Result<Expect, String> {
    let mut expect = Expect {
        command: "run".into(),
        exit: 1,
        ..Expect::default()
    };
    for (number, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (key, value) = line
            .split_once(':')
            .ok_or(format!("line {}: expected `key: value`", number + 1))?;
        let value = value.trim().to_string();
        match key.trim() {
            "command" => expect.command = value,
            "exit" => {
                expect.exit = value
                    .parse()
                    .map_err(|_| format!("line {}: exit must be a number", number + 1))?
            }
            "machine" => expect.machine = Some(value),
            "file" => expect.file = Some(value),
            "stdin" => expect.stdin = value == "yes",
            "generate" => expect.generate = Some(value),
            "diagnostic" => expect.diagnostic = Some(value),
            "phrase" => expect.phrases.push(value),
            other => return Err(format!("line {}: unknown key `{other}`", number + 1)),
        }
    }
    Ok(expect)
}

fn catalogue_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/catalogue")
}

/// Writes the inputs too big to keep in the repository.
fn generate(kind: &str, dir: &Path) -> Result<(), String> {
    let mut text = String::from("G28\nG90\n");
    match kind {
        // Line 3 is 40 MB long: past the reader's 32 MiB line limit.
        "long-line" => {
            text += "G1 X10 Y10 ;";
            text.extend(std::iter::repeat_n('a', 40 << 20));
            text += "\nG1 X20\n";
        }
        // 300 000 tiny moves on lines 4..=300003, then an unreachable one on line 300004.
        "many-lines" => {
            text += "G1 X10 Y10 F6000\n";
            for i in 0..300_000 {
                text += if i % 2 == 0 { "G1 X10.1\n" } else { "G1 X10\n" };
            }
            text += "G1 X500\n";
        }
        other => return Err(format!("unknown generator `{other}`")),
    }
    std::fs::write(dir.join("input.gcode"), text).map_err(|e| e.to_string())
}

fn copy_case(from: &Path, to: &Path) -> Result<(), String> {
    std::fs::create_dir_all(to).map_err(|e| e.to_string())?;
    for entry in std::fs::read_dir(from)
        .map_err(|e| e.to_string())?
        .flatten()
    {
        std::fs::copy(entry.path(), to.join(entry.file_name())).map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn listing(dir: &Path) -> BTreeSet<PathBuf> {
    files_under(dir).into_iter().collect()
}

/// Runs one case; `Err` describes every way it failed.
fn run_case(case: &Path) -> Result<(), String> {
    let text =
        std::fs::read_to_string(case.join("expect.txt")).map_err(|e| format!("expect.txt: {e}"))?;
    let expect = parse_expect(&text)?;
    let scratch = tempfile::tempdir().map_err(|e| e.to_string())?;
    let work = scratch.path().join("work");
    copy_case(case, &work)?;
    if let Some(kind) = &expect.generate {
        generate(kind, &work)?;
    }
    let before = listing(&work);
    let out = scratch.path().join("out");
    std::fs::create_dir_all(&out).map_err(|e| e.to_string())?;

    let config = match expect.machine.as_deref() {
        Some(name @ ("cartesian" | "polar" | "scara" | "fivebar")) => example_machine(name),
        Some(file) => PathBuf::from(file),
        None if work.join("printer.cfg").exists() => PathBuf::from("printer.cfg"),
        None => example_machine("cartesian"),
    };
    let input = if expect.stdin {
        "-".to_string()
    } else {
        expect.file.clone().unwrap_or("input.gcode".into())
    };
    let mut command = Command::new(binary());
    command.current_dir(&work);
    match expect.command.as_str() {
        "run" => {
            command.arg("run").arg("-c").arg(&config).arg(&input);
            command
                .arg("--steps")
                .arg(out.join("steps"))
                .arg("--moves")
                .arg(out.join("moves.csv"));
        }
        "check" => {
            command.arg("check").arg("-c").arg(&config).arg(&input);
        }
        "convert" => {
            command.arg("convert").arg("-c").arg(&config).arg(&input);
            command.arg("-o").arg(out.join("converted.gcode"));
        }
        "stats" => {
            command.arg("stats").arg(&input);
        }
        "calibrate-scan" => {
            command.args(["calibrate", "scara", "-c"]).arg(&config);
            command
                .args(["--image", &input, "--dpi", "600", "-o"])
                .arg(out.join("scara.json"));
            command.arg("--plot").arg(out.join("found.png"));
        }
        "calibrate-fivebar" => {
            command.args(["calibrate", "fivebar", "-c"]).arg(&config);
            command.args(["--measurements", &input, "-o"]);
            command.arg(out.join("fivebar.json"));
            command.arg("--corrected").arg(out.join("fixed.cfg"));
        }
        other => return Err(format!("unknown command `{other}`")),
    }
    command.stdin(if expect.stdin {
        Stdio::piped()
    } else {
        Stdio::null()
    });
    // Output goes to files (beside, not inside, the checked folders) so a hung case can be killed and read.
    let stdout_path = scratch.path().join("stdout.txt");
    let stderr_path = scratch.path().join("stderr.txt");
    let file = |p: &Path| std::fs::File::create(p).map_err(|e| e.to_string());
    command
        .stdout(file(&stdout_path)?)
        .stderr(file(&stderr_path)?);
    let mut child = command
        .spawn()
        .map_err(|e| format!("cannot start the binary: {e}"))?;
    if expect.stdin {
        let data = std::fs::read(work.join("input.gcode")).map_err(|e| e.to_string())?;
        if let Some(mut stdin) = child.stdin.take() {
            // The binary may stop reading at the first error: a broken pipe is expected then.
            let _ = stdin.write_all(&data);
        }
    }
    let status = wait_at_most(&mut child, CASE_TIME_LIMIT)?;
    let stdout = std::fs::read_to_string(&stdout_path).unwrap_or_default();
    let stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
    let all = format!("{stdout}\n{stderr}");

    let mut problems = Vec::new();
    match status.code() {
        Some(code) if code == expect.exit => {}
        code => problems.push(format!("exit code {code:?}, expected {}", expect.exit)),
    }
    if all.contains("panicked") {
        problems.push("the binary panicked".into());
    }
    for wanted in expect.diagnostic.iter().chain(&expect.phrases) {
        if !all.contains(wanted.as_str()) {
            problems.push(format!("output lacks `{wanted}`"));
        }
    }
    // A non-finite word is allowed only where the input spelt it (the diagnostic echoes the line).
    let input_words: BTreeSet<String> = before
        .iter()
        .filter_map(|p| std::fs::read(p).ok())
        .flat_map(|bytes| non_finite_words(&String::from_utf8_lossy(&bytes)))
        .collect();
    let printed: Vec<String> = non_finite_words(&all)
        .into_iter()
        .filter(|w| !input_words.contains(w))
        .collect();
    if !printed.is_empty() {
        problems.push(format!("non-finite numbers printed: {printed:?}"));
    }
    let left = files_under(&out);
    if expect.exit != 0 && !left.is_empty() {
        problems.push(format!("files left behind by a failed run: {left:?}"));
    }
    for file in &left {
        let text = std::fs::read(file).map(|b| String::from_utf8_lossy(&b).into_owned());
        if text.is_ok_and(|t| !non_finite_words(&t).is_empty()) {
            problems.push(format!("{} holds non-finite numbers", file.display()));
        }
    }
    let stray: Vec<_> = listing(&work).difference(&before).cloned().collect();
    if !stray.is_empty() {
        problems.push(format!("files created beside the inputs: {stray:?}"));
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{}\n  --- output ---\n{}",
            problems.join("\n  "),
            indent(&all)
        ))
    }
}

/// No case needs more than a few seconds; a hang is a finding, reported rather than waited for.
const CASE_TIME_LIMIT: Duration = Duration::from_secs(60);

/// The child's exit status, or an error (after killing it) when it runs past `limit`.
fn wait_at_most(child: &mut Child, limit: Duration) -> Result<ExitStatus, String> {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            return Ok(status);
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("still running after {limit:?}: killed"));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn indent(text: &str) -> String {
    text.lines()
        .take(30)
        .map(|l| format!("    {l}\n"))
        .collect()
}

#[test]
fn every_catalogue_case_fails_cleanly_with_its_place() {
    let mut cases: Vec<PathBuf> = std::fs::read_dir(catalogue_dir())
        .expect("tests/catalogue exists")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("expect.txt").exists())
        .collect();
    cases.sort();
    assert!(
        cases.len() >= 60,
        "the catalogue holds {} cases; it must hold at least 60",
        cases.len()
    );
    let failures: Vec<String> = cases
        .iter()
        .filter_map(|case| {
            let name = case
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            run_case(case).err().map(|e| format!("{name}: {e}"))
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

#[test]
fn expect_files_parse() {
    let expect =
        parse_expect("# why\ncommand: check\nexit: 0\nphrase: a: b\nphrase: c\n").expect("valid");
    assert_eq!(expect.command, "check");
    assert_eq!(expect.exit, 0);
    assert_eq!(expect.phrases, vec!["a: b".to_string(), "c".to_string()]);
    assert!(parse_expect("bogus: 1\n").is_err());
}
