//! ARCHITECTURE.md's invariants about where a machine's knowledge lives, checked on the source (tests aside):
//! machines are built by the machine builder, machine roles never come from stepper names, machine kinds are switched
//! on only where a tool acts on one kind's own parameters, and every distance that decides "at the polar centre" is
//! the kinematics'.

use std::path::{Path, PathBuf};

use crate::structure::{code_lines, code_lines_with, crates_dir, rust_files};

/// Crates that own names and kinds: `config` reads the sections, `kinematics` are the machine files, `machine`
/// builds the machine from both.
const OWNERS: [&str; 3] = ["config", "kinematics", "machine"];

/// Where a kind is switched on outside the owners, and why: each acts on one kind's own parameters.
const KIND_SWITCHES: [(&str, &str); 4] = [
    (
        "cli/src/cmd/convert.rs",
        "centre correction rewrites a polar machine's arm offsets",
    ),
    (
        "cli/src/cmd/calibrate/mod.rs",
        "SCARA identification fits a SCARA's lengths, offsets and zeros",
    ),
    (
        "sim/src/correction.rs",
        "the simulated machine's calibration fits each kind's own parameters",
    ),
    (
        "klipper/src/machine.rs",
        "the plug-in asks for one kind's own parameters by key (`printer_value`)",
    ),
];

/// Where a stepper's name is written outside the owners, and why.
const NAME_LITERALS: [(&str, &str); 1] = [(
    "sim/src/scenario.rs",
    "the documented scenarios are key overrides written into config text",
)];

/// Where kinematics are built outside the machine builder, and why.
const KINEMATICS_BUILT: [(&str, &str); 1] = [(
    "sim/src/machine.rs",
    "the simulated machine as built: its true geometry, which no front-end plans with",
)];

/// Every non-test source file of the workspace's crates, with its path below `crates/`.
fn sources() -> Vec<(String, PathBuf)> {
    let root = crates_dir();
    let mut files = Vec::new();
    for entry in std::fs::read_dir(&root).expect("crates folder").flatten() {
        rust_files(&entry.path().join("src"), &mut files);
    }
    let mut named: Vec<(String, PathBuf)> = files
        .into_iter()
        .map(|f| (relative(&root, &f), f))
        .collect();
    named.sort();
    assert!(named.len() > 100, "found only {} files", named.len());
    named
}

fn relative(root: &Path, file: &Path) -> String {
    let path = file.strip_prefix(root).unwrap_or(file);
    path.to_string_lossy().replace('\\', "/")
}

fn owned(path: &str) -> bool {
    OWNERS.iter().any(|c| path.starts_with(&format!("{c}/")))
}

fn listed(path: &str, list: &[(&str, &str)]) -> bool {
    list.iter().any(|(p, _)| *p == path)
}

/// `file:line: text` of every line of `lines` that `matches`.
fn offending(path: &str, lines: &[String], matches: impl Fn(&str) -> bool) -> Vec<String> {
    lines
        .iter()
        .enumerate()
        .filter(|(_, l)| matches(l))
        .map(|(i, l)| format!("{path}:{}: {}", i + 1, l.trim()))
        .collect()
}

/// A stepper section's name as a string (`"stepper_z"`, `"stepper_bed"`), not a longer word that starts alike
/// (`"stepper_kinematics"`, Klipper's C struct).
fn stepper_literal(line: &str) -> bool {
    line.match_indices("\"stepper_").any(|(at, found)| {
        let rest = &line[at + found.len()..];
        rest.find('"').is_some_and(|end| {
            (1..=4).contains(&end) && rest[..end].chars().all(|c| c.is_ascii_alphanumeric())
        })
    })
}

fn kind_switch(line: &str) -> bool {
    [
        "MachineParams::Polar",
        "MachineParams::Scara",
        "MachineParams::Cartesian",
        "MachineParams::Fivebar",
    ]
    .iter()
    .any(|k| line.contains(k))
}

/// A machine's kinematics built from parameters, not taken from the machine builder.
fn builds_kinematics(line: &str) -> bool {
    line.contains("kinematics::build(")
}

/// A constant of its own about the centre (`const NEAR_CENTRE`, `const CENTRE_GAP`…).
fn centre_constant(line: &str) -> bool {
    let line = line.trim_start();
    let line = line.strip_prefix("pub ").unwrap_or(line);
    let line = line.strip_prefix("pub(crate) ").unwrap_or(line);
    line.strip_prefix("const ")
        .and_then(|rest| rest.split(':').next())
        .is_some_and(|name| name.contains("CENTRE") || name.contains("CENTER"))
}

#[test]
fn roles_kinds_and_centre_distances_live_with_the_machine() {
    let mut problems = Vec::new();
    let mut seen_listed = 0;
    for (path, file) in sources() {
        if owned(&path) {
            continue;
        }
        let text = std::fs::read_to_string(&file).expect("source reads");
        let code = code_lines(&text);
        let with_strings = code_lines_with(&text, true);
        if listed(&path, &NAME_LITERALS) {
            seen_listed += 1;
        } else {
            problems.extend(offending(&path, &with_strings, stepper_literal));
        }
        if listed(&path, &KIND_SWITCHES) {
            seen_listed += 1;
        } else {
            problems.extend(offending(&path, &code, kind_switch));
        }
        if !path.starts_with("kinematics/") {
            problems.extend(offending(&path, &code, centre_constant));
        }
        if listed(&path, &KINEMATICS_BUILT) {
            seen_listed += 1;
        } else if !path.starts_with("machine/") {
            problems.extend(offending(&path, &code, builds_kinematics));
        }
    }
    let listed_files = KIND_SWITCHES.len() + NAME_LITERALS.len() + KINEMATICS_BUILT.len();
    assert_eq!(seen_listed, listed_files, "a listed file is gone");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_invariant_checks_see_what_they_look_for() {
    let text = "let z = \"stepper_z\"; // \"stepper_a\"\nconst NEAR_CENTRE: f64 = 1e-3;\n\
                #[cfg(test)]\nmod tests { const CENTRE_X: f64 = 0.0; }\n";
    let with_strings = code_lines_with(text, true);
    assert_eq!(offending("a.rs", &with_strings, stepper_literal).len(), 1);
    assert!(offending("a.rs", &code_lines(text), stepper_literal).is_empty());
    assert_eq!(
        offending("a.rs", &code_lines(text), centre_constant).len(),
        1
    );
    assert!(kind_switch("if let MachineParams::Scara(p) = params {"));
    assert!(!kind_switch("params: &MachineParams,"));
    assert!(stepper_literal("endstop(machine, \"stepper_bed\")"));
    assert!(!stepper_literal("\"stepper_kinematics\" => Some(layout),"));
    assert!(!centre_constant("let near_centre = 1.0;"));
    assert!(builds_kinematics("let kin = kinematics::build(&params)?;"));
}
