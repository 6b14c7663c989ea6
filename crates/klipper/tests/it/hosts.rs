//! The batch-mode hosts: set up once per test run from `../shared/klipper` (into `target/klipper-hosts`), the
//! plug-in installed into each tree with `klipper/install.sh`, runs of `batch.sh`, and the step files they write.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// Seconds one batch-mode run may take (the longest, the polar bench in exact mode, takes under a minute here).
const BATCH_TIMEOUT: u32 = 600;

/// The hosts `batch.sh` knows.
pub const KLIPPER: &str = "klipper";
pub const KALICO: &str = "kalico";
pub const KALICO_FEKT: &str = "kalico-fekt";

pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// `target/release` (or whichever profile folder this test binary was built into).
pub fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    exe.parent()
        .and_then(Path::parent)
        .expect("target/<profile>/deps/<test>")
        .to_path_buf()
}

pub fn shared() -> PathBuf {
    workspace_root().join("../shared")
}

/// The prepared hosts, or `None` (with a printed note) when `../shared/klipper` is absent.
pub struct Hosts {
    dir: PathBuf,
    library: PathBuf,
    /// Whether runs name `library` (JOINTSPACE_LIBRARY); without it the plug-in loads the library it was installed
    /// with (the installed package's).
    name_library: bool,
}

impl Hosts {
    pub fn get(test: &str) -> Option<&'static Hosts> {
        static HOSTS: OnceLock<Option<Hosts>> = OnceLock::new();
        let hosts = HOSTS.get_or_init(prepare).as_ref();
        if hosts.is_none() {
            assert!(
                std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
                "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
                shared().join("klipper").display()
            );
            println!(
                "{test}: skipped: {} is absent (the Klipper hosts come from there)",
                shared().join("klipper").display()
            );
        }
        hosts
    }

    /// The folder of one host's tree (`exact`: the step-compression-0 copy).
    pub fn tree(&self, host: &str, exact: bool) -> PathBuf {
        self.dir
            .join(format!("{host}{}", if exact { "-exact" } else { "" }))
    }

    /// The Python interpreter of a host's venv (it has cffi).
    pub fn python(&self, host: &str) -> PathBuf {
        self.dir.join(format!("venv-{host}/bin/python"))
    }

    /// The folder the hosts were set up in (`KLIP_DIR` for `batch.sh`).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The same library with host trees from another folder laid out as `dir()` is (a test's altered copy).
    pub fn in_dir(&self, dir: &Path) -> Hosts {
        Hosts {
            dir: dir.to_path_buf(),
            library: self.library.clone(),
            name_library: true,
        }
    }

    /// Host trees from another folder laid out as `dir()` is, whose plug-in loads the library it was installed with.
    pub fn installed_in(dir: &Path) -> Hosts {
        Hosts {
            dir: dir.to_path_buf(),
            library: PathBuf::new(),
            name_library: false,
        }
    }

    /// The library the hosts load.
    pub fn library(&self) -> &Path {
        &self.library
    }

    /// Runs `batch.sh` and returns its result; the output folder holds `queue_step.txt`, `klippy.log` and, in
    /// exact mode, `steps/<stepper>.txt`.
    pub fn batch(&self, host: &str, exact: bool, cfg: &Path, gcode: &Path, out: &Path) -> Run {
        // A host that shuts down in batch mode may never exit: a run gets BATCH_TIMEOUT, then counts as failed.
        let mut command = Command::new("timeout");
        command
            .args(["--kill-after=10", &BATCH_TIMEOUT.to_string()])
            .arg(shared().join("klipper/batch.sh"))
            .args([cfg, gcode, out])
            .arg(host)
            .env("KLIP_DIR", &self.dir)
            .env_remove("JOINTSPACE_LIBRARY");
        if self.name_library {
            command.env("JOINTSPACE_LIBRARY", &self.library);
        }
        if exact {
            command.env("EXACT", "1").env("STEPS", "1");
        }
        let output = command.output().expect("batch.sh runs");
        Run {
            success: output.status.success(),
            log: std::fs::read_to_string(out.join("klippy.log")).unwrap_or_default(),
            out: out.to_path_buf(),
        }
    }
}

fn prepare() -> Option<Hosts> {
    let setup = shared().join("klipper/setup.sh");
    if !setup.is_file() {
        return None;
    }
    let dir = target_dir().join("klipper-hosts");
    let status = Command::new(&setup)
        .arg(&dir)
        .status()
        .expect("setup.sh runs");
    assert!(status.success(), "{} failed", setup.display());
    // `cargo test` builds this crate as an rlib for its tests, not the cdylib the hosts load.
    cargo_build("klipper");
    let library = target_dir().join("libjointspace_klipper.so");
    assert!(library.is_file(), "{} was not built", library.display());
    let hosts = Hosts {
        dir,
        library,
        name_library: true,
    };
    for host in [KLIPPER, KALICO, KALICO_FEKT] {
        for exact in [false, true] {
            install(&hosts.tree(host, exact), false);
        }
    }
    Some(hosts)
}

/// `cargo build -p PACKAGE` into this test binary's profile folder (a no-op when it is up to date).
pub fn cargo_build(package: &str) {
    let mut command = Command::new(env!("CARGO"));
    command.args(["build", "-q", "-p", package]);
    if target_dir().ends_with("release") {
        command.arg("--release");
    }
    let status = command
        .current_dir(workspace_root())
        .status()
        .expect("cargo runs");
    assert!(status.success(), "cargo build -p {package} failed");
}

/// `klipper/install.sh --host-dir TREE --no-build [--uninstall]` (developer mode: the plug-in linked from this source
/// tree), which must succeed.
pub fn install(tree: &Path, uninstall: bool) {
    let mut command = Command::new(workspace_root().join("klipper/install.sh"));
    command.arg("--host-dir").arg(tree).arg("--no-build");
    if uninstall {
        command.arg("--uninstall");
    }
    let output = command.output().expect("install.sh runs");
    assert!(
        output.status.success(),
        "install.sh failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// One batch-mode run.
pub struct Run {
    pub success: bool,
    pub log: String,
    pub out: PathBuf,
}

impl Run {
    pub fn queue_step(&self) -> String {
        std::fs::read_to_string(self.out.join("queue_step.txt")).expect("queue_step.txt")
    }

    /// Exact mode: every stepper's steps.
    pub fn steps(&self) -> BTreeMap<String, Vec<Step>> {
        read_step_dir(&self.out.join("steps"))
    }

    /// Panics with the end of the log unless the run succeeded.
    pub fn expect_success(&self, what: &str) -> &Self {
        assert!(
            self.success,
            "{what}: klippy failed; log ends:\n{}",
            tail(&self.log, 40)
        );
        self
    }
}

pub fn tail(text: &str, lines: usize) -> String {
    let all: Vec<&str> = text.lines().collect();
    all[all.len().saturating_sub(lines)..].join("\n")
}

/// A step: MCU clock and direction (1 = the motor position grows).
pub type Step = (i64, i8);

/// `clock dir` files of a folder (`.txt` or `.txt.gz`), by stepper name.
pub fn read_step_dir(dir: &Path) -> BTreeMap<String, Vec<Step>> {
    let mut steppers = BTreeMap::new();
    for entry in std::fs::read_dir(dir).expect("step folder").flatten() {
        let path = entry.path();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        let Some(stepper) = name
            .strip_suffix(".txt.gz")
            .or_else(|| name.strip_suffix(".txt"))
        else {
            continue;
        };
        let text = if name.ends_with(".gz") {
            let mut text = String::new();
            let file = std::fs::File::open(&path).expect("open step file");
            std::io::Read::read_to_string(&mut flate2::read::GzDecoder::new(file), &mut text)
                .expect("gzip step file");
            text
        } else {
            std::fs::read_to_string(&path).expect("step file")
        };
        let steps = text
            .lines()
            .filter_map(|line| {
                let mut words = line.split_whitespace();
                Some((words.next()?.parse().ok()?, words.next()?.parse().ok()?))
            })
            .collect();
        steppers.insert(stepper.to_string(), steps);
    }
    steppers
}

/// How two step streams of one stepper compare.
#[derive(Debug, PartialEq)]
pub struct StepComparison {
    pub counts: (usize, usize),
    pub same_directions: bool,
    /// Largest |clock difference| (ticks) over steps paired in order.
    pub max_ticks: i64,
    /// Steps more than `tolerance` ticks apart.
    pub beyond_tolerance: usize,
}

pub fn compare(a: &[Step], b: &[Step], tolerance: i64) -> StepComparison {
    let diffs = a.iter().zip(b).map(|(x, y)| (x.0 - y.0).abs());
    StepComparison {
        counts: (a.len(), b.len()),
        same_directions: a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.1 == y.1),
        max_ticks: diffs.clone().max().unwrap_or(0),
        beyond_tolerance: diffs.filter(|d| *d > tolerance).count(),
    }
}

/// Asserts every stepper of `expected` has the same count and directions in `actual` and clocks within
/// `tolerance` ticks; returns the largest difference seen.
pub fn assert_same_steps(
    what: &str,
    expected: &BTreeMap<String, Vec<Step>>,
    actual: &BTreeMap<String, Vec<Step>>,
    tolerance: i64,
) -> i64 {
    let mut worst = 0;
    for (stepper, steps) in expected {
        let ours = actual
            .get(stepper)
            .unwrap_or_else(|| panic!("{what}: no steps for {stepper}"));
        let c = compare(steps, ours, tolerance);
        assert!(
            c.counts.0 == c.counts.1 && c.same_directions && c.beyond_tolerance == 0,
            "{what}: {stepper}: {c:?}"
        );
        assert!(!steps.is_empty(), "{what}: {stepper} made no steps");
        worst = worst.max(c.max_ticks);
    }
    worst
}

/// A config: `base` (a printer.cfg) with whole-line replacements and a `[jointspace]` section appended.
pub fn plugin_config(
    base: &Path,
    replacements: &[(&str, &str)],
    dir: &Path,
    name: &str,
) -> PathBuf {
    let mut text = std::fs::read_to_string(base).expect("base config");
    for (from, to) in replacements {
        let lines: Vec<String> = text
            .lines()
            .map(|l| {
                if l.trim() == *from {
                    to.to_string()
                } else {
                    l.to_string()
                }
            })
            .collect();
        assert!(
            text.lines().any(|l| l.trim() == *from),
            "{} has no line '{from}'",
            base.display()
        );
        text = lines.join("\n") + "\n";
    }
    text.push_str("\n[jointspace]\n");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write config");
    path
}

/// Writes `text` as a file in `dir`.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write file");
    path
}
