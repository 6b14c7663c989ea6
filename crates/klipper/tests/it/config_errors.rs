//! Set-up mistakes a printer owner makes, as Klipper reports them with the plug-in installed: each stops the host
//! with a message that says what to do, never a bare "Error loading kinematics" or a silently different library.

use std::path::Path;

use crate::hosts::{Hosts, KALICO, KLIPPER, tail, workspace_root, write};

fn polar_example(dir: &Path, name: &str, edit: impl Fn(String) -> String) -> std::path::PathBuf {
    let text = std::fs::read_to_string(workspace_root().join("klipper/examples/polar.cfg"))
        .expect("polar example");
    write(dir, name, &edit(text))
}

fn expect_refusal(hosts: &Hosts, host: &str, cfg: &Path, dir: &Path, phrase: &str) {
    let input = write(dir, "home.gcode", "G28\n");
    let out = dir.join(format!(
        "{host}-{}",
        cfg.file_stem().and_then(|s| s.to_str()).unwrap_or("run")
    ));
    let run = hosts.batch(host, false, cfg, &input, &out);
    assert!(!run.success, "{host}: {} started", cfg.display());
    assert!(
        run.log.contains(phrase),
        "{host}: no '{phrase}' in:\n{}",
        tail(&run.log, 15)
    );
    // Raised as the config's error, which the host reports as one ("Config error"), not as an exception it did not
    // expect ("Unhandled exception during connect").
    assert!(
        run.log.contains("Config error") && !run.log.contains("Unhandled exception"),
        "{host}: not reported as a config error:\n{}",
        tail(&run.log, 15)
    );
}

#[test]
fn set_up_mistakes_are_named() {
    let Some(hosts) = Hosts::get("set_up_mistakes_are_named") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let no_section = polar_example(dir.path(), "no-section.cfg", |t| {
        t.replace("[jointspace]\n", "")
    });
    let missing_library = polar_example(dir.path(), "missing-library.cfg", |t| {
        t.replace(
            "[jointspace]\n",
            "[jointspace]\nlibrary: /nonexistent/libjointspace_klipper.so\n",
        )
    });
    let bad_value = polar_example(dir.path(), "bad-value.cfg", |t| {
        t.replace("arm_zero_offset: 0\n", "arm_zero_offset: abc\n")
    });
    let text = std::fs::read_to_string(&bad_value).expect("config");
    let line = 1 + text
        .lines()
        .position(|l| l.starts_with("arm_zero_offset: abc"))
        .expect("the line");
    let place = format!("bad-value.cfg:{line}:18: option 'arm_zero_offset'");
    for host in [KLIPPER, KALICO] {
        // A value the machine cannot read is named at its place in the owner's file.
        expect_refusal(hosts, host, &bad_value, dir.path(), &place);
        expect_refusal(
            hosts,
            host,
            &no_section,
            dir.path(),
            "kinematics: jointspace_polar needs a [jointspace] section in printer.cfg",
        );
        expect_refusal(
            hosts,
            host,
            &missing_library,
            dir.path(),
            "[jointspace] library names /nonexistent/libjointspace_klipper.so, which does not exist",
        );
    }
}

/// A library built from another `jointspace.h` than the plug-in's (the plug-in updated, the library not rebuilt) is
/// refused: the header hash the library was built with equals the plug-in's hash of its own header, and not that of
/// a header with one declaration more.
#[test]
fn a_library_from_another_header_is_refused() {
    let Some(hosts) = Hosts::get("a_library_from_another_header_is_refused") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let plugin = workspace_root().join("klipper/jointspace_klipper");
    for entry in std::fs::read_dir(&plugin)
        .expect("klipper/jointspace_klipper/")
        .flatten()
    {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.ends_with(".py") || name == "jointspace.h" {
            std::fs::copy(entry.path(), dir.path().join(&*name)).expect("copy the plug-in");
        }
    }
    let script = r#"
import sys, types
sys.modules["chelper"] = types.ModuleType("chelper")
sys.modules["stepper"] = types.ModuleType("stepper")
sys.path.insert(0, sys.argv[1])
import cffi, jointspace
class Config:
    def error(self, message):
        return Exception(message)
ffi = cffi.FFI()
ffi.cdef(jointspace.library._cdef_text())
lib = ffi.dlopen(sys.argv[2])
jointspace.library._check_built_from_this_header(Config(), lib, sys.argv[2])
print("accepted")
with open(sys.argv[1] + "/jointspace.h", "a") as f:
    f.write("int jointspace_new_function(void);\n")
try:
    jointspace.library._check_built_from_this_header(Config(), lib, sys.argv[2])
except Exception as e:
    print("refused:", e)
"#;
    let output = std::process::Command::new(hosts.python(KLIPPER))
        .arg("-c")
        .arg(script)
        .arg(dir.path())
        .arg(hosts.library())
        .output()
        .expect("python runs");
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(
        text.contains("accepted") && text.contains("built from another version of jointspace.h"),
        "{text}{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// A shared library answering `jointspace_version` and `jointspace_header_hash` as given, and nothing else.
fn fake_library(dir: &Path, name: &str, version: &str, hash: &str) -> std::path::PathBuf {
    let source = write(
        dir,
        &format!("{name}.c"),
        &format!(
            "const char *jointspace_version(void) {{ return \"{version}\"; }}\n\
             unsigned long long jointspace_header_hash(void) {{ return {hash}ULL; }}\n"
        ),
    );
    let library = dir.join(format!("{name}.so"));
    let built = std::process::Command::new("cc")
        .args(["-shared", "-fPIC", "-o"])
        .arg(&library)
        .arg(&source)
        .status()
        .expect("cc runs");
    assert!(built.success(), "{name} did not compile");
    library
}

/// `[jointspace] library:` may name any file, but the plug-in loads only its own release built from its own header:
/// another version, another header, or a file that is no library at all stops the host with a config error.
#[test]
fn a_named_library_of_another_version_or_abi_is_refused() {
    let Some(hosts) = Hosts::get("a_named_library_of_another_version_or_abi_is_refused") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let ours = concat!("jointspace-klipper ", env!("CARGO_PKG_VERSION"));
    let other_version = fake_library(dir.path(), "other-version", "jointspace-klipper 9.9.9", "0");
    let other_header = fake_library(dir.path(), "other-header", ours, "12345");
    let not_a_library = write(dir.path(), "not-a-library.so", "text\n");
    let cases = [
        (
            &other_version,
            format!("is jointspace-klipper 9.9.9, this plug-in is {ours}"),
        ),
        (
            &other_header,
            "was built from another version of jointspace.h".to_string(),
        ),
        (
            &not_a_library,
            format!("cannot load {} as a library", not_a_library.display()),
        ),
    ];
    for (library, phrase) in cases {
        let cfg = polar_example(
            dir.path(),
            &format!(
                "{}.cfg",
                library.file_stem().and_then(|s| s.to_str()).expect("name")
            ),
            |t| {
                t.replace(
                    "[jointspace]\n",
                    &format!("[jointspace]\nlibrary: {}\n", library.display()),
                )
            },
        );
        for host in [KLIPPER, KALICO] {
            expect_refusal(hosts, host, &cfg, dir.path(), &phrase);
        }
    }
}
