//! `klipper/install.sh` into fresh git checkouts of Klipper and Kalico, then `--uninstall`: each leaves
//! `git status` clean (Moonraker reports a dirty tree otherwise), and the module lands where the host loads it.

use std::path::Path;
use std::process::Command;

use crate::hosts::{install, shared, workspace_root};

fn git(tree: &Path, args: &[&str]) -> String {
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
    let mut modules: Vec<String> = std::fs::read_dir(workspace_root().join("klipper"))
        .expect("klipper/")
        .flatten()
        .filter_map(|e| e.file_name().into_string().ok())
        .filter(|n| n.starts_with("jointspace") && n.ends_with(".py"))
        .filter(|n| n != "jointspace_missing_section.py")
        .collect();
    modules.sort();
    assert!(modules.len() > 2, "{modules:?}");
    modules
}

fn install_and_uninstall(host: &str, module_folder: &str) {
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
        return;
    }
    crate::hosts::cargo_build("klipper"); // install.sh --no-build wants the library
    let dir = tempfile::tempdir().expect("temp dir");
    let unpacked = Command::new("tar")
        .arg("-xzf")
        .arg(&tarball)
        .arg("-C")
        .arg(dir.path())
        .status()
        .expect("tar runs");
    assert!(unpacked.success());
    let tree = dir.path().join(host);
    git(&tree, &["init", "-q"]);
    git(&tree, &["add", "-A"]);
    git(&tree, &["commit", "-qm", "pristine"]);

    install(&tree, false);
    let modules = plugin_modules();
    for module in &modules {
        let link = tree.join(module_folder).join(module);
        let target = std::fs::read_link(&link).expect("the module is a symlink");
        assert_eq!(
            target.canonicalize().expect("link target"),
            workspace_root()
                .join("klipper")
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
        git(&tree, &["status", "--porcelain"]),
        "",
        "{host}: dirty after install"
    );
    install(&tree, false); // twice: still one line each in the exclude file
    let exclude = std::fs::read_to_string(tree.join(".git/info/exclude")).expect("exclude");
    for module in &modules {
        assert_eq!(
            exclude.matches(&format!("/{module}")).count(),
            1,
            "{exclude}"
        );
    }

    install(&tree, true);
    for module in &modules {
        let link = tree.join(module_folder).join(module);
        assert!(
            !link.exists() && link.symlink_metadata().is_err(),
            "{host}: {module} left behind"
        );
    }
    assert!(!cache.join("jointspace.cpython-311.pyc").exists());
    assert_eq!(
        git(&tree, &["status", "--porcelain"]),
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
