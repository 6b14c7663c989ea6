// The commit jointspace is built from, as `JOINTSPACE_COMMIT` for `env!`: the library reports it
// (`jointspace_commit`, the plug-in's `printer.jointspace` status) and `jointspace --version` prints it (crates/cli's
// build script is this file). Taken from the environment variable JOINTSPACE_COMMIT when it holds a commit hash (a
// release build from an sdist), else from `git rev-parse` when the workspace is the top of its own git checkout,
// else "unknown": never a failed build (no git, an sdist, an sdist unpacked inside another repository).
use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-env-changed=JOINTSPACE_COMMIT");
    println!("cargo:rerun-if-changed=build.rs");
    let given = std::env::var("JOINTSPACE_COMMIT")
        .ok()
        .filter(|c| (7..=40).contains(&c.len()) && c.bytes().all(|b| b.is_ascii_hexdigit()));
    let commit = given
        .map(|c| c[..c.len().min(12)].to_ascii_lowercase())
        .or_else(git_commit)
        .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=JOINTSPACE_COMMIT={commit}");
}

/// `git ARGS` in `dir`: its first output line, or `None` (no git, not a repository, any failure).
fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let output = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    let text = String::from_utf8(output.stdout).ok()?;
    let line = text.lines().next()?.trim().to_string();
    (output.status.success() && !line.is_empty()).then_some(line)
}

/// The short commit of the checkout the workspace is the top of; asks cargo to build again when HEAD moves.
fn git_commit() -> Option<String> {
    let root = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR")?)
        .join("../..")
        .canonicalize()
        .ok()?;
    let top = PathBuf::from(git(&root, &["rev-parse", "--show-toplevel"])?);
    if top.canonicalize().ok()? != root {
        return None;
    }
    let branch = git(&root, &["symbolic-ref", "-q", "HEAD"]);
    for name in ["HEAD", "packed-refs"].into_iter().chain(branch.as_deref()) {
        if let Some(path) = git(&root, &["rev-parse", "--git-path", name]) {
            let path = root.join(path);
            if path.exists() {
                println!("cargo:rerun-if-changed={}", path.display());
            }
        }
    }
    git(&root, &["rev-parse", "--short=12", "HEAD"])
}
