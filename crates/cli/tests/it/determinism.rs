//! Determinism across thread counts: `run --steps` with `RAYON_NUM_THREADS=1` and with the default pool
//! must write byte-identical step files (and the same summary apart from the wall time).

use std::path::Path;
use std::process::Command;

use crate::common::{binary, files_under, shared};

/// Runs `run --steps DIR --moves DIR/moves.csv`; returns the summary with its wall-time field removed.
fn run_steps(config: &Path, input: &Path, out: &Path, threads: Option<&str>) -> String {
    let mut command = Command::new(binary());
    command
        .args(["run", "--json", "-c"])
        .arg(config)
        .arg(input)
        .arg("--steps")
        .arg(out)
        .arg("--moves")
        .arg(out.join("moves.csv"));
    match threads {
        Some(n) => command.env("RAYON_NUM_THREADS", n),
        None => command.env_remove("RAYON_NUM_THREADS"),
    };
    let output = command.output().expect("run jointspace");
    assert!(
        output.status.success(),
        "run failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter(|l| !l.contains("wall_time_s"))
        .collect::<Vec<_>>()
        .join("\n")
}

fn check_case(golden: &Path) {
    let scratch = tempfile::tempdir().expect("temp dir");
    let config = golden.join("printer.cfg");
    let input = golden.join("input.gcode");
    let one = scratch.path().join("one");
    let many = scratch.path().join("many");
    let summary_one = run_steps(&config, &input, &one, Some("1"));
    let summary_many = run_steps(&config, &input, &many, None);
    assert_eq!(
        summary_one,
        summary_many,
        "{}: summaries differ",
        golden.display()
    );
    let mut files = files_under(&one);
    files.sort();
    assert!(
        files.len() >= 3,
        "{}: expected step files, found {files:?}",
        golden.display()
    );
    for file in &files {
        let relative = file.strip_prefix(&one).expect("under the output folder");
        let a = std::fs::read(file).expect("read single-thread output");
        let b = std::fs::read(many.join(relative)).expect("the default pool wrote the same file");
        assert!(
            a == b,
            "{}: {} differs between 1 thread and the default pool",
            golden.display(),
            relative.display()
        );
    }
    assert_eq!(
        files.len(),
        files_under(&many).len(),
        "{}: different file sets",
        golden.display()
    );
}

#[test]
fn step_files_are_identical_across_thread_counts() {
    let Some(shared) = shared("step_files_are_identical_across_thread_counts") else {
        return;
    };
    for case in [
        "cartesian-bambu-square-ring",
        "polar-cura-circle",
        "scara-fekt-cura-hex",
    ] {
        check_case(&shared.join("golden").join(case));
    }
}
