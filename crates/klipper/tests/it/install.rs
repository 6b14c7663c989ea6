//! `klipper/install.sh` into fresh git checkouts of Klipper and Kalico, then `--uninstall`: each leaves
//! `git status` clean (Moonraker reports a dirty tree otherwise), and the module lands where the host loads it. Paths
//! with shell characters, a tree inside another repository and a foreign `jointspace.py` are handled without touching
//! what is not install's own.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::hosts::{KLIPPER, install, shared, workspace_root};

pub fn git(tree: &Path, args: &[&str]) -> String {
    let output = Command::new("git")
        .args([
            "-c",
            "user.name=test",
            "-c",
            "user.email=test@invalid",
            "-c",
            "init.defaultBranch=main",
        ])
        .args(args)
        .current_dir(tree)
        .output()
        .expect("git runs");
    assert!(
        output.status.success(),
        "git {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// The plug-in's modules: `jointspace.py` and every `jointspace_*.py` beside it that it loads (all but the stand-in
/// install.sh links as the kinematics modules).
fn plugin_modules() -> Vec<String> {
    let mut modules: Vec<String> =
        std::fs::read_dir(workspace_root().join("klipper/jointspace_klipper"))
            .expect("klipper/jointspace_klipper/")
            .flatten()
            .filter_map(|e| e.file_name().into_string().ok())
            .filter(|n| n.starts_with("jointspace") && n.ends_with(".py"))
            .filter(|n| n != "jointspace_missing_section.py")
            .collect();
    modules.sort();
    assert!(modules.len() > 2, "{modules:?}");
    modules
}

/// `host`'s tarball unpacked under `parent` (`parent/host`), or `None` (a skip, unless CI requires the shared data).
fn unpack(host: &str, parent: &Path) -> Option<PathBuf> {
    let tarball = shared().join(format!("klipper/{host}.tar.gz"));
    if !tarball.is_file() {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            tarball.display()
        );
        println!(
            "install into {host}: skipped: {} is absent",
            tarball.display()
        );
        return None;
    }
    crate::hosts::cargo_build("klipper"); // install.sh --no-build wants the library
    std::fs::create_dir_all(parent).expect("parent folder");
    let unpacked = Command::new("tar")
        .arg("-xzf")
        .arg(&tarball)
        .arg("-C")
        .arg(parent)
        .status()
        .expect("tar runs");
    assert!(unpacked.success());
    Some(parent.join(host))
}

/// `tree` as a git repository of its own, everything committed.
pub fn commit_all(tree: &Path) {
    git(tree, &["init", "-q"]);
    git(tree, &["add", "-A"]);
    git(tree, &["commit", "-qm", "pristine"]);
}

/// install.sh's exit status and everything it printed.
fn run_install(tree: &Path, uninstall: bool) -> (bool, String) {
    let mut command = Command::new(workspace_root().join("klipper/install.sh"));
    command.arg("--host-dir").arg(tree).arg("--no-build");
    if uninstall {
        command.arg("--uninstall");
    }
    let output = command.output().expect("install.sh runs");
    let text = String::from_utf8_lossy(&output.stdout).into_owned()
        + &String::from_utf8_lossy(&output.stderr);
    (output.status.success(), text)
}

/// The names in a folder, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("folder")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn install_and_uninstall(host: &str, module_folder: &str) {
    let dir = tempfile::tempdir().expect("temp dir");
    let Some(tree) = unpack(host, dir.path()) else {
        return;
    };
    commit_all(&tree);
    install_and_uninstall_in(&tree, host, module_folder);
}

/// Installs into a committed tree (twice), then uninstalls: links where the host loads them, `git status` clean
/// throughout, one exclude block in the tree's own repository, nothing of it left after.
fn install_and_uninstall_in(tree: &Path, host: &str, module_folder: &str) {
    install(tree, false);
    let modules = plugin_modules();
    for module in &modules {
        let link = tree.join(module_folder).join(module);
        let target = std::fs::read_link(&link).expect("the module is a symlink");
        assert_eq!(
            target.canonicalize().expect("link target"),
            workspace_root()
                .join("klipper/jointspace_klipper")
                .join(module)
                .canonicalize()
                .expect("module")
        );
    }
    // Python leaves a compiled copy beside the link when the host imports it.
    let cache = tree.join(module_folder).join("__pycache__");
    std::fs::create_dir_all(&cache).expect("cache folder");
    std::fs::write(cache.join("jointspace.cpython-311.pyc"), b"").expect("pyc");
    assert_eq!(
        git(tree, &["status", "--porcelain"]),
        "",
        "{host}: dirty after install"
    );
    install(tree, false); // twice: still one line each in the exclude file
    let exclude = std::fs::read_to_string(tree.join(".git/info/exclude")).expect("exclude");
    for module in &modules {
        assert_eq!(
            exclude.matches(&format!("/{module}")).count(),
            1,
            "{exclude}"
        );
    }

    install(tree, true);
    for module in &modules {
        let link = tree.join(module_folder).join(module);
        assert!(
            !link.exists() && link.symlink_metadata().is_err(),
            "{host}: {module} left behind"
        );
    }
    assert!(!cache.join("jointspace.cpython-311.pyc").exists());
    assert_eq!(
        git(tree, &["status", "--porcelain"]),
        "",
        "{host}: dirty after uninstall"
    );
    let exclude = std::fs::read_to_string(tree.join(".git/info/exclude")).expect("exclude");
    assert!(
        !exclude.contains("jointspace"),
        "{host}: exclude lines left: {exclude}"
    );
}

#[test]
fn install_into_klipper_leaves_git_clean() {
    install_and_uninstall("klipper", "klippy/extras");
}

#[test]
fn install_into_kalico_leaves_git_clean() {
    install_and_uninstall("kalico", "klippy/plugins");
}

/// Host folders whose paths hold characters a shell or `sed` treats specially: the exclude block lands in each tree's
/// own repository, and nothing is written anywhere else.
#[test]
fn install_into_paths_with_shell_characters() {
    let dir = tempfile::tempdir().expect("temp dir");
    let parents = ["amp&ersand", "pi|pe", "with space"];
    for parent in parents {
        let Some(tree) = unpack(KLIPPER, &dir.path().join(parent)) else {
            return;
        };
        commit_all(&tree);
        install_and_uninstall_in(&tree, KLIPPER, "klippy/extras");
        assert_eq!(
            names(&dir.path().join(parent)),
            [KLIPPER],
            "{parent}: written beside the tree"
        );
    }
    assert_eq!(names(dir.path()), parents, "written beside the parents");
}

/// A host tree that is not the top of its own repository (inside another one): the links are made and removed, and
/// the other repository's exclude list is never edited. A tree with its own repository inside another gets its own.
#[test]
fn a_host_inside_another_repository_leaves_that_repository_alone() {
    let outer = tempfile::tempdir().expect("temp dir");
    git(outer.path(), &["init", "-q"]);
    let exclude = outer.path().join(".git/info/exclude");
    let before = std::fs::read_to_string(&exclude).expect("outer exclude");
    let Some(tree) = unpack(KLIPPER, &outer.path().join("plain")) else {
        return;
    };
    let link = tree.join("klippy/extras/jointspace.py");
    let (ok, text) = run_install(&tree, false);
    assert!(ok, "{text}");
    assert!(
        text.contains("is not the top level of its own git repository: no exclude list edited"),
        "{text}"
    );
    assert!(link.symlink_metadata().is_ok(), "no link made");
    assert_eq!(std::fs::read_to_string(&exclude).expect("exclude"), before);
    let (ok, text) = run_install(&tree, true);
    assert!(ok, "{text}");
    assert!(link.symlink_metadata().is_err(), "link left");
    assert_eq!(std::fs::read_to_string(&exclude).expect("exclude"), before);

    let Some(nested) = unpack(KLIPPER, &outer.path().join("nested")) else {
        return;
    };
    commit_all(&nested);
    install_and_uninstall_in(&nested, KLIPPER, "klippy/extras");
    assert_eq!(std::fs::read_to_string(&exclude).expect("exclude"), before);
}

/// A `jointspace.py` that is not install's own link (another plug-in's file, a link elsewhere) stops install before it
/// links anything, and uninstall leaves it as it was.
#[test]
fn a_foreign_jointspace_py_is_left_alone() {
    let dir = tempfile::tempdir().expect("temp dir");
    let Some(tree) = unpack(KLIPPER, dir.path()) else {
        return;
    };
    commit_all(&tree);
    let extras = tree.join("klippy/extras");
    let foreign = extras.join("jointspace.py");
    let elsewhere = dir.path().join("elsewhere.py");
    std::fs::write(&elsewhere, "# someone else's\n").expect("elsewhere");
    for as_link in [false, true] {
        if as_link {
            std::os::unix::fs::symlink(&elsewhere, &foreign).expect("foreign link");
        } else {
            std::fs::write(&foreign, "# another plug-in\n").expect("foreign file");
        }
        let (ok, text) = run_install(&tree, false);
        assert!(!ok, "install replaced {}: {text}", foreign.display());
        assert!(
            text.contains("exists and install.sh did not put it there"),
            "{text}"
        );
        assert!(
            extras
                .join("jointspace_library.py")
                .symlink_metadata()
                .is_err(),
            "install linked something before stopping"
        );
        let (ok, text) = run_install(&tree, true);
        assert!(ok, "{text}");
        assert!(text.contains("install.sh did not put it there"), "{text}");
        if as_link {
            assert_eq!(std::fs::read_link(&foreign).expect("link kept"), elsewhere);
        } else {
            assert_eq!(
                std::fs::read_to_string(&foreign).expect("file kept"),
                "# another plug-in\n"
            );
        }
        std::fs::remove_file(&foreign).expect("remove the foreign file");
    }
}
