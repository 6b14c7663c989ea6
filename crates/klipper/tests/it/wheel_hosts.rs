//! The wheel as a printer owner installs it: `klipper/install.sh --wheel` into a fresh copy of each pinned host's
//! tree (a git repository of its own) and virtualenv, an example printed from the installed package (the library the
//! plug-in loads is the package's, not this tree's; `printer.jointspace` reports the version and commit), then
//! `--uninstall`: the host tree, the virtualenv (`pip freeze` and every file) and this clone (`git status`) are as they
//! were, but for the host's own bytecode caches its run wrote. A wheel for another machine is refused first.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::hosts::{Hosts, KALICO, KALICO_FEKT, KLIPPER, install, workspace_root, write};
use crate::install::{commit_all, git};
use crate::wheel::{expected_commit, run, tools, wheel};

const POLAR: &str = "G28\nG90\nM83\nSHOW_JOINTSPACE\nG1 Z0.3 F600\nG1 X50 Y0 F6000\nG2 X50 Y0 I-50 J0 E10 F3000\nM400\n";
const SCARA: &str = "G28\nG90\nM83\nSHOW_JOINTSPACE\nG1 Z0.3 F600\nG1 X20 Y130 F6000\nG2 X20 Y130 I-20 J0 E5 F3000\nM400\n";

/// Every path below `dir` (not following links, `.git` left out) with what it is: "dir", "link TARGET" or "file SIZE".
fn listing(dir: &Path) -> BTreeSet<(String, String)> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeSet<(String, String)>) {
        for entry in std::fs::read_dir(dir).expect("folder").flatten() {
            let path = entry.path();
            let relative = path
                .strip_prefix(root)
                .expect("below root")
                .to_string_lossy()
                .into_owned();
            if relative == ".git" {
                continue;
            }
            let meta = std::fs::symlink_metadata(&path).expect("metadata");
            let what = if meta.file_type().is_symlink() {
                format!(
                    "link {}",
                    std::fs::read_link(&path).expect("link").display()
                )
            } else if meta.is_dir() {
                walk(root, &path, out);
                "dir".to_string()
            } else {
                format!("file {}", meta.len())
            };
            out.insert((relative, what));
        }
    }
    let mut out = BTreeSet::new();
    walk(dir, dir, &mut out);
    out
}

/// What can be compared before install and after uninstall.
#[derive(Debug, PartialEq)]
struct State {
    tree: BTreeSet<(String, String)>,
    venv: BTreeSet<(String, String)>,
    freeze: String,
    exclude: String,
    clone_status: String,
}

fn state(tree: &Path, venv: &Path) -> State {
    State {
        tree: listing(tree),
        venv: listing(venv),
        freeze: run(
            Command::new(venv.join("bin/python")).args([
                "-m",
                "pip",
                "freeze",
                "--disable-pip-version-check",
            ]),
            "pip freeze",
        ),
        exclude: std::fs::read_to_string(tree.join(".git/info/exclude")).unwrap_or_default(),
        clone_status: git(&workspace_root(), &["status", "--porcelain"]),
    }
}

/// `after` is `before` but for bytecode caches of the host's own modules (written by its run; never one of ours).
fn assert_as_before(host: &str, before: &State, after: &State) {
    assert_eq!(before.freeze, after.freeze, "{host}: pip freeze");
    assert_eq!(before.exclude, after.exclude, "{host}: .git/info/exclude");
    assert_eq!(
        before.clone_status, after.clone_status,
        "{host}: this clone's git status"
    );
    for (what, b, a) in [
        ("tree", &before.tree, &after.tree),
        ("venv", &before.venv, &after.venv),
    ] {
        let gone: Vec<_> = b.difference(a).collect();
        assert!(
            gone.is_empty(),
            "{host}: {what}: removed or changed: {gone:?}"
        );
        let added: Vec<_> = a
            .difference(b)
            .filter(|(path, _)| {
                let host_cache = path.split('/').any(|c| c == "__pycache__")
                    && !path.contains("jointspace")
                    && (path.ends_with(".pyc") || path.ends_with("__pycache__"));
                !host_cache
            })
            .collect();
        assert!(added.is_empty(), "{host}: {what}: left behind: {added:?}");
    }
}

fn copy(from: &Path, to: &Path) {
    run(Command::new("cp").arg("-a").arg(from).arg(to), "cp -a");
}

fn install_sh(args: &[&std::ffi::OsStr]) -> (bool, String) {
    let output = Command::new(workspace_root().join("klipper/install.sh"))
        .args(args)
        .output()
        .expect("install.sh runs");
    let text = String::from_utf8_lossy(&output.stdout).into_owned()
        + &String::from_utf8_lossy(&output.stderr);
    (output.status.success(), text)
}

/// A folder holding the wheel renamed for another machine (pip chooses by the name's tags).
fn foreign_wheel(wheel: &Path, dir: &Path) -> PathBuf {
    let name = wheel.file_name().and_then(|n| n.to_str()).expect("name");
    let (ours, other) = if name.contains("x86_64") {
        ("x86_64", "aarch64")
    } else {
        (std::env::consts::ARCH, "x86_64")
    };
    let folder = dir.join("foreign");
    std::fs::create_dir_all(&folder).expect("folder");
    std::fs::copy(wheel, folder.join(name.replace(ours, other))).expect("copy wheel");
    folder
}

fn installed_wheel_runs(host: &str, example: &str, gcode: &str) {
    let test = format!("installed_wheel_runs_in_{host}");
    let (Some(hosts), Some(tools)) = (Hosts::get(&test), tools(&test)) else {
        return;
    };
    let wheel = wheel(&tools);
    let dir = tempfile::tempdir().expect("temp dir");
    let (tree, venv) = (
        dir.path().join(host),
        dir.path().join(format!("venv-{host}")),
    );
    copy(&hosts.tree(host, false), &tree);
    copy(&hosts.dir().join(format!("venv-{host}")), &venv);
    std::os::unix::fs::symlink(hosts.dir().join("dict"), dir.path().join("dict")).expect("dict");
    install(&tree, true); // the prepared tree's developer-mode links
    commit_all(&tree);
    let before = state(&tree, &venv);
    let (t, v) = (tree.as_os_str(), venv.as_os_str());
    let common = [
        std::ffi::OsStr::new("--host-dir"),
        t,
        std::ffi::OsStr::new("--venv"),
        v,
    ];

    let foreign = foreign_wheel(wheel, dir.path());
    let (ok, text) = install_sh(
        &[
            &[std::ffi::OsStr::new("--wheel"), foreign.as_os_str()],
            &common[..],
        ]
        .concat(),
    );
    assert!(!ok && text.contains("fits this host"), "{host}: {text}");
    assert_eq!(
        state(&tree, &venv),
        before,
        "{host}: a refused install changed something"
    );

    let (ok, text) = install_sh(
        &[
            &[std::ffi::OsStr::new("--wheel"), wheel.as_os_str()],
            &common[..],
        ]
        .concat(),
    );
    assert!(ok, "{host}: {text}");
    let dest = if tree.join("klippy/plugins").is_dir() {
        "klippy/plugins"
    } else {
        "klippy/extras"
    };
    let other = if dest == "klippy/plugins" {
        "klippy/extras"
    } else {
        "klippy/plugins"
    };
    let loader = tree.join(dest).join("jointspace.py");
    assert!(
        loader.symlink_metadata().expect("loader").is_file(),
        "{host}: the loader is a copy"
    );
    assert!(
        !tree.join(other).join("jointspace.py").exists(),
        "{host}: a loader in {other} too"
    );
    assert_eq!(
        git(&tree, &["status", "--porcelain"]),
        "",
        "{host}: dirty after install"
    );

    let config = dir.path().join("printer.cfg");
    let mut text =
        std::fs::read_to_string(workspace_root().join(format!("klipper/examples/{example}.cfg")))
            .expect("example");
    text.push_str(
        "\n[gcode_macro SHOW_JOINTSPACE]\ngcode:\n  {action_respond_info(\"jointspace status %s %s\" % (\
         printer.jointspace.version, printer.jointspace.commit))}\n",
    );
    std::fs::write(&config, text).expect("config");
    let input = write(dir.path(), "print.gcode", gcode);
    let run = Hosts::installed_in(dir.path()).batch(
        host,
        false,
        &config,
        &input,
        &dir.path().join("out"),
    );
    run.expect_success(&format!("{example} on {host} from the installed wheel"));
    let venv_real = venv.canonicalize().expect("venv");
    let loaded = run
        .log
        .lines()
        .find(|l| l.contains("jointspace: loaded "))
        .expect("loaded line");
    assert!(
        loaded.contains(&format!("{}/lib/", venv_real.display()))
            && loaded.contains("site-packages/jointspace_klipper/native/libnative.so"),
        "{host}: not the package's library: {loaded}"
    );
    let status = format!(
        "jointspace status {} {}",
        env!("CARGO_PKG_VERSION"),
        expected_commit()
    );
    assert!(
        run.log.contains(&status),
        "{host}: no '{status}' in the log"
    );
    let steps = run
        .queue_step()
        .lines()
        .filter(|l| l.starts_with("queue_step"))
        .count();
    assert!(steps > 50, "{host}: only {steps} step messages");

    let (ok, text) = install_sh(&[&[std::ffi::OsStr::new("--uninstall")], &common[..]].concat());
    assert!(ok, "{host}: {text}");
    assert_eq!(
        git(&tree, &["status", "--porcelain"]),
        "",
        "{host}: dirty after uninstall"
    );
    assert_as_before(host, &before, &state(&tree, &venv));
}

#[test]
fn installed_wheel_runs_in_klipper() {
    installed_wheel_runs(KLIPPER, "polar", POLAR);
}

#[test]
fn installed_wheel_runs_in_kalico() {
    installed_wheel_runs(KALICO, "polar", POLAR);
}

#[test]
fn installed_wheel_runs_in_the_fekt_fork() {
    installed_wheel_runs(KALICO_FEKT, "scara", SCARA);
}
