//! The library's `struct stepper_kinematics` and `struct move` are each host's: a C program built against the
//! host's own `itersolve.h` and `trapq.h` reports the sizes and offsets of the fields the library names, and they
//! must be the library's. And the plug-in checks the same at load: a host whose headers lay either struct out
//! otherwise is refused, naming the host's version.

use std::path::Path;
use std::process::Command;

use jointspace_klipper::jointspace_struct_layout;

use crate::hosts::{Hosts, KALICO, KALICO_FEKT, KLIPPER, tail, workspace_root, write};

/// The library's layout of Klipper's struct `name`: its size line (if any) and `(field, offset, size)`.
fn library_layout(name: &str) -> (Option<usize>, Vec<(String, usize, usize)>) {
    let name = std::ffi::CString::new(name).expect("name");
    // SAFETY: a NUL-terminated name; the answer is a static string or null.
    let text = unsafe { jointspace_struct_layout(name.as_ptr()) };
    assert!(!text.is_null(), "no layout for {name:?}");
    // SAFETY: non-null, NUL-terminated, static.
    let text = unsafe { std::ffi::CStr::from_ptr(text) }.to_string_lossy();
    let mut size = None;
    let mut fields = Vec::new();
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let number = |i: usize| words[i].parse::<usize>().expect("a number");
        match words[..] {
            ["size", _] => size = Some(number(1)),
            [field, _, _] => fields.push((field.to_string(), number(1), number(2))),
            _ => panic!("layout line {line:?}"),
        }
    }
    (size, fields)
}

/// C source printing, for each struct, the size line and the fields in the library's format.
fn probe_source() -> String {
    let mut body = String::new();
    for name in ["stepper_kinematics", "move"] {
        let (size, fields) = library_layout(name);
        body += &format!("    printf(\"struct {name}\\n\");\n");
        if size.is_some() {
            body += &format!("    printf(\"size %zu\\n\", sizeof(struct {name}));\n");
        }
        for (field, _, _) in fields {
            body += &format!(
                "    printf(\"{field} %zu %zu\\n\", offsetof(struct {name}, {field}), \
                 sizeof(((struct {name} *)0)->{field}));\n"
            );
        }
    }
    format!(
        "#include <stdio.h>\n#include <stddef.h>\n#include \"itersolve.h\"\n#include \"trapq.h\"\n\
         int main(void) {{\n{body}    return 0;\n}}\n"
    )
}

/// The probe's expected output: the library's own layouts in the same format.
fn library_text() -> String {
    let mut text = String::new();
    for name in ["stepper_kinematics", "move"] {
        let (size, fields) = library_layout(name);
        text += &format!("struct {name}\n");
        if let Some(size) = size {
            text += &format!("size {size}\n");
        }
        for (field, offset, width) in fields {
            text += &format!("{field} {offset} {width}\n");
        }
    }
    text
}

#[test]
fn shared_structs_are_laid_out_as_each_host_declares_them() {
    let Some(hosts) = Hosts::get("shared_structs_are_laid_out_as_each_host_declares_them") else {
        return;
    };
    let (size, fields) = library_layout("stepper_kinematics");
    assert_eq!(size, Some(88), "x86-64/aarch64 struct stepper_kinematics");
    assert_eq!(fields.len(), 11, "every field of struct stepper_kinematics");
    let dir = tempfile::tempdir().expect("temp dir");
    let source = dir.path().join("probe.c");
    std::fs::write(&source, probe_source()).expect("write probe");
    for host in [KLIPPER, KALICO, KALICO_FEKT] {
        let binary = dir.path().join(host);
        let include = hosts.tree(host, false).join("klippy/chelper");
        let built = Command::new("cc")
            .arg("-I")
            .arg(&include)
            .arg(&source)
            .arg("-o")
            .arg(&binary)
            .status()
            .expect("cc runs");
        assert!(built.success(), "{host}: probe did not compile");
        let output = Command::new(&binary).output().expect("probe runs");
        assert_eq!(
            String::from_utf8_lossy(&output.stdout),
            library_text(),
            "{host}: the host's layout (left) against the library's"
        );
    }
}

/// A copy of `host`'s tree under `dir` (with the hosts' venv and dictionaries), `header` edited by `edit`.
fn altered_host(hosts: &Hosts, dir: &Path, host: &str, header: &str, edit: (&str, &str)) {
    let copied = Command::new("cp")
        .arg("-a")
        .arg(hosts.tree(host, false))
        .arg(dir.join(host))
        .status()
        .expect("cp runs");
    assert!(copied.success(), "copy of {host}");
    for shared in [format!("venv-{host}"), "dict".to_string()] {
        std::os::unix::fs::symlink(hosts.dir().join(&shared), dir.join(&shared)).expect("link");
    }
    let path = dir.join(host).join("klippy/chelper").join(header);
    let text = std::fs::read_to_string(&path).expect("header");
    assert!(
        text.contains(edit.0),
        "{host}: {header} has no {:?}",
        edit.0
    );
    std::fs::write(&path, text.replacen(edit.0, edit.1, 1)).expect("edit header");
}

#[test]
fn a_host_declaring_the_structs_otherwise_is_refused() {
    let Some(hosts) = Hosts::get("a_host_declaring_the_structs_otherwise_is_refused") else {
        return;
    };
    let cases = [
        (
            KLIPPER,
            "itersolve.h",
            (
                "double step_dist, commanded_pos;",
                "double step_dist, extra, commanded_pos;",
            ),
            "Klipper version",
            "declares struct stepper_kinematics",
            "field extra at offset 8, unknown to the library",
        ),
        (
            KALICO,
            "trapq.h",
            (
                "double start_v, half_accel;",
                "double start_v, extra, half_accel;",
            ),
            "Kalico version",
            "declares struct move",
            "half_accel at offset 32 size 8, the library's at 24 size 8",
        ),
    ];
    let work = tempfile::tempdir().expect("temp dir");
    let cfg = write(
        work.path(),
        "printer.cfg",
        &std::fs::read_to_string(workspace_root().join("klipper/examples/polar.cfg"))
            .expect("polar example"),
    );
    let input = write(work.path(), "home.gcode", "G28\n");
    for (host, header, edit, version, what, detail) in cases {
        let dir = work.path().join(format!("{host}-altered"));
        std::fs::create_dir(&dir).expect("host dir");
        altered_host(hosts, &dir, host, header, edit);
        let run = hosts
            .in_dir(&dir)
            .batch(host, false, &cfg, &input, &dir.join("out"));
        assert!(!run.success, "{host} with another {header} started");
        for phrase in [version, what, detail, "Config error"] {
            assert!(
                run.log.contains(phrase),
                "{host}: no '{phrase}' in:\n{}",
                tail(&run.log, 15)
            );
        }
    }
}
