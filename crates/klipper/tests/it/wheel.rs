//! The plug-in's Python package (`jointspace-klipper`, pyproject.toml): its sdist built with maturin, the wheel built
//! from that sdist (so the sdist is complete and builds with cargo and no git), the wheel's metadata and tags, a
//! virtualenv whose Python is too old refused with a clear message, and the release workflow's jobs and targets.
//! `wheel_hosts.rs` installs the wheel into each pinned host. The tools: `maturin` ($JOINTSPACE_MATURIN, else on
//! PATH) with a Python beside it that has cffi and PyYAML (.ci/run makes that virtualenv); without them the tests
//! skip, unless JOINTSPACE_REQUIRE_SHARED says they must run (CI).

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use crate::hosts::{target_dir, workspace_root};

/// maturin and the Python beside it (cffi for maturin's bindings, PyYAML for the workflow, pip).
#[derive(Debug)]
pub struct Tools {
    pub maturin: PathBuf,
    pub python: PathBuf,
}

/// The tools, or `None` (a printed skip) when they are missing and CI does not require them.
pub fn tools(test: &str) -> Option<Tools> {
    let maturin = std::env::var_os("JOINTSPACE_MATURIN")
        .map(PathBuf::from)
        .or_else(|| which("maturin"));
    let found = maturin.and_then(|maturin| {
        let python = maturin.parent()?.join("python3");
        let usable = Command::new(&python)
            .args(["-c", "import cffi, yaml"])
            .status()
            .is_ok_and(|s| s.success());
        usable.then_some(Tools { maturin, python })
    });
    if found.is_none() {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{test}: maturin with cffi and PyYAML beside it is missing (set JOINTSPACE_MATURIN; .ci/run installs \
             them), and JOINTSPACE_REQUIRE_SHARED says the wheel tests must run"
        );
        println!("{test}: skipped: no maturin with cffi and PyYAML beside it (JOINTSPACE_MATURIN)");
    }
    found
}

fn which(name: &str) -> Option<PathBuf> {
    std::env::split_paths(&std::env::var_os("PATH")?)
        .map(|dir| dir.join(name))
        .find(|path| path.is_file())
}

/// Runs a command to success; its standard output.
pub fn run(command: &mut Command, what: &str) -> String {
    let output = command.output().unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(
        output.status.success(),
        "{what} failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// The commit the library reports: this clone's HEAD (12 hex digits), or "unknown" outside git.
pub fn expected_commit() -> String {
    Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .current_dir(workspace_root())
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".to_string())
}

/// The wheel, built once per test run: `maturin sdist`, unpacked under target/, `maturin build --release` inside it
/// (its own cargo target folder, kept between runs), with the commit handed over as the release workflow does.
pub fn wheel(tools: &Tools) -> &'static Path {
    static WHEEL: OnceLock<PathBuf> = OnceLock::new();
    WHEEL.get_or_init(|| {
        let work = target_dir().join("wheel-test");
        let _ = std::fs::remove_dir_all(work.join("sdist"));
        let _ = std::fs::remove_dir_all(work.join("dist"));
        std::fs::create_dir_all(work.join("sdist")).expect("wheel-test folder");
        run(
            Command::new(&tools.maturin)
                .args(["sdist", "--out"])
                .arg(work.join("sdist"))
                .current_dir(workspace_root()),
            "maturin sdist",
        );
        let sdist = only_file(&work.join("sdist"), ".tar.gz");
        run(
            Command::new("tar")
                .arg("-xzf")
                .arg(&sdist)
                .arg("-C")
                .arg(work.join("sdist")),
            "unpack the sdist",
        );
        let unpacked = work.join("sdist").join(
            sdist
                .file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_suffix(".tar.gz"))
                .expect("sdist name"),
        );
        let commit = expected_commit();
        let mut build = Command::new(&tools.maturin);
        build
            .args(["build", "--release", "--out"])
            .arg(work.join("dist"))
            .arg("-i")
            .arg(&tools.python)
            .current_dir(&unpacked)
            .env("CARGO_TARGET_DIR", work.join("cargo"));
        if commit != "unknown" {
            build.env("JOINTSPACE_COMMIT", &commit);
        }
        run(&mut build, "maturin build from the sdist");
        only_file(&work.join("dist"), ".whl")
    })
}

fn only_file(dir: &Path, suffix: &str) -> PathBuf {
    let files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("folder")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.to_string_lossy().ends_with(suffix))
        .collect();
    assert_eq!(files.len(), 1, "{}: {files:?}", dir.display());
    files.into_iter().next().expect("one file")
}

/// Python's answer to `script` (argv[1] is `arg`).
fn python(tools: &Tools, script: &str, arg: &Path) -> String {
    run(
        Command::new(&tools.python).args(["-c", script]).arg(arg),
        "python",
    )
}

/// The oldest Python install.sh accepts (its MIN_PYTHON), which must be pyproject.toml's requires-python.
fn install_sh_min_python() -> String {
    let text =
        std::fs::read_to_string(workspace_root().join("klipper/install.sh")).expect("install.sh");
    text.lines()
        .find_map(|l| l.strip_prefix("MIN_PYTHON="))
        .expect("MIN_PYTHON in install.sh")
        .to_string()
}

const WHEEL_FACTS: &str = r#"
import sys, zipfile
w = zipfile.ZipFile(sys.argv[1])
for name in w.namelist():
    print("file", name)
    if name.endswith(".dist-info/METADATA") or name.endswith(".dist-info/WHEEL"):
        for line in w.read(name).decode().splitlines():
            if ": " in line:
                print("meta", line)
    if name.endswith("native/libnative.so"):
        print("library_size", w.getinfo(name).file_size)
"#;

/// The wheel holds the plug-in's modules, its header and licence, the loader and the library (stripped), nothing
/// compiled by Python; tagged py3-none-manylinux for this machine; no runtime dependency (the plug-in uses Klipper's
/// cffi: a dependency would let Moonraker's eager upgrade replace the cffi Klipper pins); requires-python as
/// install.sh checks it.
#[test]
fn the_wheel_holds_the_plugin_and_says_what_it_needs() {
    let Some(tools) = tools("the_wheel_holds_the_plugin_and_says_what_it_needs") else {
        return;
    };
    let wheel = wheel(&tools);
    let name = wheel.file_name().and_then(|n| n.to_str()).expect("name");
    let arch = std::env::consts::ARCH;
    let version = env!("CARGO_PKG_VERSION");
    assert!(
        name.starts_with(&format!("jointspace_klipper-{version}-py3-none-manylinux_"))
            && name.ends_with(&format!("_{arch}.whl")),
        "{name}"
    );
    let facts = python(&tools, WHEEL_FACTS, wheel);
    let files: Vec<&str> = facts
        .lines()
        .filter_map(|l| l.strip_prefix("file "))
        .collect();
    let meta: Vec<&str> = facts
        .lines()
        .filter_map(|l| l.strip_prefix("meta "))
        .collect();
    let plugin = workspace_root().join("klipper/jointspace_klipper");
    for entry in std::fs::read_dir(&plugin)
        .expect("plug-in folder")
        .flatten()
    {
        let file = format!("jointspace_klipper/{}", entry.file_name().to_string_lossy());
        if entry.path().is_file() {
            assert!(
                files.contains(&file.as_str()),
                "{file} not in the wheel: {files:?}"
            );
        }
    }
    assert!(
        files.contains(&"jointspace_klipper/native/libnative.so"),
        "{files:?}"
    );
    assert!(
        !files
            .iter()
            .any(|f| f.contains("__pycache__") || f.ends_with(".pyc")),
        "{files:?}"
    );
    let size: u64 = facts
        .lines()
        .find_map(|l| l.strip_prefix("library_size "))
        .and_then(|s| s.parse().ok())
        .expect("library size");
    assert!(
        size < 8_000_000,
        "the library is {size} bytes: not stripped?"
    );
    let min = install_sh_min_python();
    for needed in [
        "Name: jointspace-klipper".to_string(),
        format!("Version: {version}"),
        format!("Requires-Python: >={min}"),
        "Root-Is-Purelib: false".to_string(),
        "License-Expression: GPL-3.0-or-later AND (MIT OR Apache-2.0)".to_string(),
    ] {
        assert!(meta.contains(&needed.as_str()), "{needed} not in {meta:?}");
    }
    let requires: Vec<&&str> = meta
        .iter()
        .filter(|l| l.starts_with("Requires-Dist:"))
        .collect();
    assert!(
        requires.iter().all(|r| r.contains("extra ==")),
        "a runtime dependency: {requires:?}"
    );
    assert!(
        meta.iter()
            .any(|l| l.starts_with("Tag: py3-none-manylinux_") && l.ends_with(arch)),
        "{meta:?}"
    );
}

/// install.sh refuses a virtualenv whose Python is older than requires-python before pip runs, with what to do,
/// writing nothing into the host tree; with a real Python 3.7 at hand (`python3.7` on PATH, or
/// $JOINTSPACE_OLD_PYTHON), pip in its virtualenv refuses the wheel too, naming the requirement. No upper bound: the
/// wheel is py3-none (a C library, no Python C API), so a newer Python 3 takes it.
#[test]
fn a_python_older_than_the_wheel_supports_is_refused_clearly() {
    let Some(tools) = tools("a_python_older_than_the_wheel_supports_is_refused_clearly") else {
        return;
    };
    let wheel = wheel(&tools);
    let dir = tempfile::tempdir().expect("temp dir");
    let old = std::env::var_os("JOINTSPACE_OLD_PYTHON")
        .map(PathBuf::from)
        .or_else(|| which("python3.7"))
        .filter(|p| {
            Command::new(p)
                .arg("-V")
                .output()
                .is_ok_and(|o| o.status.success())
        });
    if let Some(old) = old {
        let venv = dir.path().join("venv37");
        run(
            Command::new(&old).args(["-m", "venv"]).arg(&venv),
            "venv with the old Python",
        );
        let out = Command::new(venv.join("bin/python"))
            .args([
                "-m",
                "pip",
                "install",
                "--no-index",
                "--disable-pip-version-check",
                "--find-links",
            ])
            .arg(wheel.parent().expect("dist"))
            .arg("jointspace-klipper")
            .output()
            .expect("pip runs");
        let text = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && text.contains("requires a different Python"),
            "{text}"
        );
    } else {
        println!("no Python 3.7 at hand: pip's own refusal not run (install.sh's is, below)");
    }

    // A virtualenv of Python 2.7 (as old KIAUH installs made): its interpreter answers the version question only.
    let venv = dir.path().join("klippy-env");
    let tree = dir.path().join("klipper");
    std::fs::create_dir_all(venv.join("bin")).expect("venv");
    std::fs::create_dir_all(tree.join("klippy/extras")).expect("tree");
    std::fs::write(tree.join("klippy/klippy.py"), "").expect("klippy.py");
    let interpreter = venv.join("bin/python");
    std::fs::write(&interpreter, "#!/bin/sh\necho 2.7\n").expect("python");
    std::fs::set_permissions(&interpreter, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    let output = Command::new(workspace_root().join("klipper/install.sh"))
        .arg("--wheel")
        .arg(wheel)
        .arg("--venv")
        .arg(&venv)
        .arg("--host-dir")
        .arg(&tree)
        .output()
        .expect("install.sh runs");
    let text = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{text}");
    assert!(
        text.contains("runs Python 2.7; jointspace-klipper needs Python 3.8 or newer"),
        "{text}"
    );
    assert_eq!(
        std::fs::read_dir(tree.join("klippy/extras"))
            .expect("extras")
            .count(),
        0,
        "install.sh wrote into the tree"
    );
    assert_eq!(install_sh_min_python(), "3.8");
}

const WORKFLOW_AS_JSON: &str = r#"
import json, sys, yaml
print(json.dumps(yaml.safe_load(open(sys.argv[1])), default=str))
"#;

/// The release workflow parses, builds the wheel for x86_64, aarch64 and armv7 in the manylinux2014 images with the
/// maturin CI pins, checks the tags, loads the aarch64 wheel on an ARM runner, builds the sdist, and publishes only
/// from a version tag after all of them.
#[test]
fn the_release_workflow_builds_every_printer_s_wheel() {
    let Some(tools) = tools("the_release_workflow_builds_every_printer_s_wheel") else {
        return;
    };
    let path = workspace_root().join(".github/workflows/release.yml");
    let json = python(&tools, WORKFLOW_AS_JSON, &path);
    let doc: serde_json::Value = serde_json::from_str(&json).expect("workflow as JSON");
    let jobs = &doc["jobs"];
    let ci = std::fs::read_to_string(workspace_root().join(".ci/run")).expect(".ci/run");
    let pin = ci
        .split_whitespace()
        .find_map(|w| w.strip_prefix("maturin=="))
        .expect("maturin pinned in .ci/run");
    assert_eq!(doc["env"]["MATURIN_VERSION"], pin);
    let pyproject =
        std::fs::read_to_string(workspace_root().join("pyproject.toml")).expect("pyproject");
    assert!(pyproject.contains(r#"requires = ["maturin>=1.9,<2", "cffi"]"#));
    assert!(
        pin.starts_with("1.")
            && pin.split('.').nth(1).and_then(|m| m.parse::<u32>().ok()) >= Some(9)
    );

    let wheels = &jobs["wheels"];
    assert_eq!(
        wheels["strategy"]["matrix"]["target"],
        serde_json::json!(["x86_64", "aarch64", "armv7"])
    );
    let steps = wheels["steps"].as_array().expect("steps");
    let build = steps
        .iter()
        .find(|s| {
            s["uses"]
                .as_str()
                .is_some_and(|u| u.starts_with("PyO3/maturin-action@"))
        })
        .expect("maturin-action step");
    assert_eq!(build["with"]["manylinux"], "2014");
    assert_eq!(build["with"]["target"], "${{ matrix.target }}");
    assert_eq!(
        build["with"]["maturin-version"],
        "${{ env.MATURIN_VERSION }}"
    );
    assert!(
        build["with"]["before-script-linux"]
            .as_str()
            .is_some_and(|s| s.contains("cffi"))
    );
    assert!(
        build["with"]["args"]
            .as_str()
            .is_some_and(|s| s.contains("--release"))
    );
    assert_eq!(build["env"]["JOINTSPACE_COMMIT"], "${{ github.sha }}");
    let tags = steps
        .iter()
        .filter_map(|s| s["run"].as_str())
        .collect::<String>();
    assert!(
        tags.contains("armv7l") && tags.contains("py3-none-manylinux_2_17_"),
        "{tags}"
    );

    assert_eq!(jobs["smoke-aarch64"]["runs-on"], "ubuntu-24.04-arm");
    let smoke = jobs["smoke-aarch64"].to_string();
    assert!(
        smoke.contains("wheel-aarch64") && smoke.contains("jointspace_commit"),
        "{smoke}"
    );
    assert!(jobs["sdist"].to_string().contains(r#""command":"sdist""#));
    let publish = &jobs["publish"];
    assert_eq!(
        publish["needs"],
        serde_json::json!(["wheels", "smoke-aarch64", "sdist"])
    );
    assert_eq!(publish["if"], "startsWith(github.ref, 'refs/tags/v')");
    assert!(publish.to_string().contains("pypa/gh-action-pypi-publish"));
    // PyYAML reads `on:` as YAML 1.1's true.
    assert_eq!(doc["true"]["push"]["tags"], serde_json::json!(["v*"]));
}

/// klipper/moonraker.conf's documented section is Moonraker's `type: python` updater of this package in Klipper's
/// virtualenv, restarting Klipper; the git_repo alternative names no made-up origin, and the release its
/// requirements file installs is this crate's; nothing Python or cargo writes is tracked.
#[test]
fn moonraker_updates_the_package_and_the_clone_tracks_no_build_output() {
    let root = workspace_root();
    let conf =
        std::fs::read_to_string(root.join("klipper/moonraker.conf")).expect("moonraker.conf");
    let active: Vec<&str> = conf
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .collect();
    assert_eq!(
        active,
        [
            "[update_manager jointspace]",
            "type: python",
            "virtualenv: ~/klippy-env",
            "project_name: jointspace-klipper",
            "managed_services: klipper",
        ]
    );
    assert!(!conf.contains("example.invalid"), "{conf}");
    assert!(
        conf.contains("#requirements: klipper/requirements.txt"),
        "{conf}"
    );
    let requirements =
        std::fs::read_to_string(root.join("klipper/requirements.txt")).expect("requirements");
    let pins: Vec<&str> = requirements
        .lines()
        .filter(|l| !l.starts_with('#'))
        .collect();
    assert_eq!(
        pins,
        [format!("jointspace-klipper=={}", env!("CARGO_PKG_VERSION"))]
    );
    let tracked = crate::install::git(&root, &["ls-files"]);
    let built: Vec<&str> = tracked
        .lines()
        .filter(|f| {
            f.contains("__pycache__/")
                || f.ends_with(".pyc")
                || f.ends_with(".so")
                || f.ends_with(".whl")
        })
        .filter(|f| !f.starts_with("fuzz/"))
        .collect();
    assert!(built.is_empty(), "tracked build output: {built:?}");
    let ignore = std::fs::read_to_string(root.join(".gitignore")).expect(".gitignore");
    for pattern in ["target/", "__pycache__/", "*.py[cod]", "*.whl", "/dist/"] {
        assert!(
            ignore.lines().any(|l| l == pattern),
            "{pattern} not in .gitignore"
        );
    }
}
