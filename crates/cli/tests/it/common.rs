//! Shared helpers: the binary, the example machines, `../shared`, and output checks every test applies.

use std::path::{Path, PathBuf};

/// The `jointspace` binary under test.
pub fn binary() -> &'static str {
    env!("CARGO_BIN_EXE_jointspace")
}

/// The workspace root (two levels above this crate).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs the binary in `dir` with `args` and no standard input.
pub fn jointspace_in(dir: &Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(binary())
        .current_dir(dir)
        .args(args)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run jointspace")
}

/// An example machine's printer.cfg (`cartesian`, `polar`, `scara`).
pub fn example_machine(name: &str) -> PathBuf {
    workspace_root()
        .join("examples/machines")
        .join(format!("{name}.cfg"))
}

/// `../shared` beside the workspace, or `None` with a printed reason.
pub fn shared(test: &str) -> Option<PathBuf> {
    let dir = workspace_root().join("../shared");
    if dir.is_dir() {
        Some(dir)
    } else {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            dir.display()
        );
        println!("{test}: skipped: {} is absent", dir.display());
        None
    }
}

/// Words in `text` that spell a non-finite number (`NaN`, `inf`, `-inf`, `infinity`, any case). Words are
/// split on whitespace and punctuation other than the characters of a number, so `XNaN` echoed from an input
/// line does not count but `(NaN, 0.000)` does.
pub fn non_finite_words(text: &str) -> Vec<String> {
    text.split(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '+' | '-')))
        .map(|w| w.trim_start_matches(['+', '-']).to_ascii_lowercase())
        .filter(|w| matches!(w.as_str(), "nan" | "inf" | "infinity"))
        .collect()
}

/// Every file (not directory) under `dir`, recursively.
pub fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return found;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            found.extend(files_under(&path));
        } else {
            found.push(path);
        }
    }
    found
}

#[test]
fn non_finite_words_finds_numbers_not_letters_inside_words() {
    assert_eq!(
        non_finite_words("move to (NaN, 1.0) then -inf"),
        vec!["nan", "inf"]
    );
    assert!(non_finite_words("G1 XNaN information infinite").is_empty());
}

/// A G-code print generated on the fly: the nozzle circles (radius 2 mm, 126 chords of 0.1 mm) around one
/// point, extruding. About 28 bytes per line; nothing is stored.
#[derive(Debug)]
pub struct CircleStream {
    header: Vec<u8>,
    block: Vec<u8>,
}

impl CircleStream {
    /// Circles around the middle of the example Cartesian bed (110, 110).
    pub fn new() -> Self {
        CircleStream::around([110.0, 110.0])
    }

    /// Circles around `centre` (mm).
    pub fn around(centre: [f64; 2]) -> Self {
        let [x, y] = centre;
        let header = format!("G28\nG90\nM83\nG1 X{:.3} Y{y:.3} Z0.3 F3000\n", x + 2.0).into_bytes();
        let chords = 126;
        let mut block = String::new();
        for i in 1..=chords {
            let angle = std::f64::consts::TAU * f64::from(i) / f64::from(chords);
            block += &format!(
                "G1 X{:.3} Y{:.3} E0.004\n",
                x + 2.0 * angle.cos(),
                y + 2.0 * angle.sin()
            );
        }
        CircleStream {
            header,
            block: block.into_bytes(),
        }
    }

    /// Writes at least `bytes` bytes of the print into `out` (whole lines); stops quietly when the reader
    /// goes away (an error exit or an interrupted run closes the pipe).
    pub fn write_to(&self, out: &mut impl std::io::Write, bytes: u64) -> u64 {
        if out.write_all(&self.header).is_err() {
            return 0;
        }
        let mut written = self.header.len() as u64;
        while written < bytes {
            if out.write_all(&self.block).is_err() {
                break;
            }
            written += self.block.len() as u64;
        }
        written
    }

    /// The whole print of at least `bytes` bytes, in memory (for small inputs).
    pub fn to_vec(&self, bytes: u64) -> Vec<u8> {
        let mut text = Vec::new();
        self.write_to(&mut text, bytes);
        text
    }
}

/// Peak resident memory (`VmHWM`, kB) of a running process, from `/proc`.
pub fn peak_rss_kb(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
