//! `klipper/jointspace_klipper/jointspace.h` against the library it declares: every function the header declares is exported by
//! `crates/klipper/src` with the same arguments, and every exported function is declared. cffi trusts the header
//! blindly (a missing argument or a `double` read as an `int` is a wrong number, not an error), and the header hash
//! only proves the library was built from this header, not that the header says what the library does.

use std::collections::BTreeMap;
use std::path::Path;

use crate::hosts::workspace_root;

/// A C function's signature: return type and argument types, each as normalised C (`const char *`).
#[derive(Debug, Clone, PartialEq, Eq)]
struct Signature {
    returns: String,
    args: Vec<String>,
}

/// C types of the Rust types at the boundary. Pointers are built around these; the machine is an opaque handle
/// whose constness C does not see (the header passes `struct jointspace_machine *` to readers and writers alike).
const RUST_TO_C: &[(&str, &str)] = &[
    ("f64", "double"),
    ("c_int", "int"),
    ("usize", "size_t"),
    ("u64", "unsigned long long"),
    ("c_char", "char"),
    ("c_void", "void"),
    ("()", "void"),
    ("Machine", "struct jointspace_machine"),
    ("StepperKinematics", "struct stepper_kinematics"),
    ("HallScanSettings", "struct jointspace_hall_scan"),
    // Klipper's struct move, which the header hands over untyped.
    ("Move", "void"),
];

const OPAQUE: &[&str] = &["struct jointspace_machine"];

fn words(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    for c in text.chars() {
        if c.is_alphanumeric() || c == '_' {
            word.push(c);
            continue;
        }
        if !word.is_empty() {
            out.push(std::mem::take(&mut word));
        }
        if c == '*' {
            out.push("*".into());
        }
    }
    if !word.is_empty() {
        out.push(word);
    }
    out
}

/// Text without `/* */` and `//` comments.
fn strip_comments(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(i) = rest.find("/*") {
        out.push_str(&rest[..i]);
        rest = rest[i..].find("*/").map_or("", |j| &rest[i + j + 2..]);
    }
    out.push_str(rest);
    out.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every function the header declares (preprocessor lines, struct bodies and comments left out).
fn c_functions(header: &str) -> BTreeMap<String, Signature> {
    let text: String = strip_comments(header)
        .lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .collect::<Vec<_>>()
        .join(" ");
    let mut without_bodies = String::new();
    let mut depth = 0;
    for c in text.chars() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            _ if depth == 0 => without_bodies.push(c),
            _ => {}
        }
    }
    let mut functions = BTreeMap::new();
    for declaration in without_bodies.split(';') {
        let Some((head, args)) = declaration.split_once('(') else {
            continue;
        };
        let mut head = words(head);
        let name = head.pop().expect("a function name");
        let args = args.rsplit_once(')').expect("closing parenthesis").0;
        let args = if args.trim() == "void" {
            Vec::new()
        } else {
            args.split(',').map(c_argument_type).collect()
        };
        let signature = Signature {
            returns: head.join(" "),
            args,
        };
        assert!(
            functions.insert(name.clone(), signature).is_none(),
            "jointspace.h declares {name} twice"
        );
    }
    functions
}

/// `const double *xyz` → `const double *` (the last word is the argument's name).
fn c_argument_type(argument: &str) -> String {
    let mut w = words(argument);
    assert!(
        w.len() > 1 && w.last().is_some_and(|n| n != "*"),
        "an unnamed argument in jointspace.h: '{argument}'"
    );
    w.pop();
    w.join(" ")
}

/// The C type of a Rust type at the boundary (`*const c_char` → `const char *`), or `?Type` when unknown.
fn c_type(rust: &str) -> String {
    let rust = rust.trim();
    for (prefix, constness) in [("*const ", "const "), ("*mut ", "")] {
        if let Some(pointee) = rust.strip_prefix(prefix) {
            let inner = c_type(pointee);
            let constness = if OPAQUE.contains(&inner.as_str()) {
                ""
            } else {
                constness
            };
            return format!("{constness}{inner} *");
        }
    }
    let last = rust.rsplit("::").next().unwrap_or(rust);
    RUST_TO_C
        .iter()
        .find(|(r, _)| *r == last)
        .map_or(format!("?{rust}"), |(_, c)| c.to_string())
}

/// Splits `a: T, b: U,` at the top level.
fn rust_arguments(args: &str) -> Vec<String> {
    args.split(',')
        .map(str::trim)
        .filter(|a| !a.is_empty())
        .map(|a| c_type(a.split_once(':').expect("name: Type").1))
        .collect()
}

/// The attribute lines right before the end of `source` (`#[unsafe(no_mangle)]`, `#[allow(...)]`).
fn attributes(source: &str) -> Vec<&str> {
    source
        .lines()
        .rev()
        .map(str::trim)
        .skip_while(|l| l.is_empty())
        .take_while(|l| l.starts_with("#["))
        .collect()
}

/// Every `pub extern "C" fn` and `pub unsafe extern "C" fn` of a Rust source, with the C types of its
/// arguments; a function exported without `#[unsafe(no_mangle)]` right before it is reported as `?unmangled`.
fn rust_functions(source: &str) -> BTreeMap<String, Signature> {
    let mut functions = BTreeMap::new();
    for marker in ["pub extern \"C\" fn ", "pub unsafe extern \"C\" fn "] {
        let mut from = 0;
        while let Some(i) = source[from..].find(marker) {
            let start = from + i;
            from = start + marker.len();
            let rest = &source[from..];
            let open = rest.find('(').expect("(");
            let name = rest[..open].trim().to_string();
            let close = rest.find(')').expect(")");
            let body = rest.find('{').expect("{");
            let returns = rest[close + 1..body]
                .trim()
                .strip_prefix("->")
                .map_or("void".to_string(), c_type);
            let mangled = !attributes(&source[..start]).contains(&"#[unsafe(no_mangle)]");
            functions.insert(
                name,
                Signature {
                    returns: if mangled {
                        "?unmangled".into()
                    } else {
                        returns
                    },
                    args: rust_arguments(&rest[open + 1..close]),
                },
            );
        }
    }
    functions
}

/// The differences, one line each: declared but not exported, exported but not declared, and different types.
fn mismatches(
    declared: &BTreeMap<String, Signature>,
    exported: &BTreeMap<String, Signature>,
) -> Vec<String> {
    let mut problems = Vec::new();
    for (name, c) in declared {
        match exported.get(name) {
            None => problems.push(format!(
                "{name}: declared in jointspace.h, not exported by the library"
            )),
            Some(rust) if rust != c => problems.push(format!(
                "{name}: jointspace.h has {} ({}), the library {} ({})",
                c.returns,
                c.args.join(", "),
                rust.returns,
                rust.args.join(", ")
            )),
            Some(_) => {}
        }
    }
    for name in exported.keys().filter(|n| !declared.contains_key(*n)) {
        problems.push(format!(
            "{name}: exported by the library, not declared in jointspace.h"
        ));
    }
    problems
}

fn library_functions(src: &Path) -> BTreeMap<String, Signature> {
    let mut functions = BTreeMap::new();
    for entry in std::fs::read_dir(src)
        .expect("crates/klipper/src")
        .flatten()
    {
        let path = entry.path();
        if path.extension().is_some_and(|e| e == "rs") {
            let source = std::fs::read_to_string(&path).expect("source");
            for (name, signature) in rust_functions(&strip_comments(&source)) {
                assert!(
                    functions.insert(name.clone(), signature).is_none(),
                    "{name} exported twice"
                );
            }
        }
    }
    functions
}

#[test]
fn the_header_declares_exactly_what_the_library_exports() {
    let root = workspace_root();
    let header = std::fs::read_to_string(root.join("klipper/jointspace_klipper/jointspace.h"))
        .expect("header");
    let declared = c_functions(&header);
    let exported = library_functions(&root.join("crates/klipper/src"));
    assert!(
        declared.len() > 20,
        "only {} functions found in jointspace.h",
        declared.len()
    );
    let problems = mismatches(&declared, &exported);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The comparison itself, on small sources: each kind of mismatch is found.
#[test]
fn a_mismatch_in_either_direction_is_found() {
    let header = "/* f */\n#include <x.h>\nstruct s { int a; double b; };\n\
                  int f(struct jointspace_machine *m, const double *xyz, size_t n);\n\
                  const char *g(void);\ndouble h(double x);\n";
    let source = "#[unsafe(no_mangle)]\n#[allow(clippy::too_many_arguments)] // why\n\
                  pub unsafe extern \"C\" fn f(m: *const Machine, xyz: *const f64, n: usize) -> c_int {}\n\
                  #[unsafe(no_mangle)]\npub extern \"C\" fn g() -> *const c_char {}\n\
                  #[unsafe(no_mangle)]\npub extern \"C\" fn h(x: f64) -> f64 {}\n";
    let declared = c_functions(header);
    assert_eq!(
        declared["f"].args,
        ["struct jointspace_machine *", "const double *", "size_t"]
    );
    let same = rust_functions(&strip_comments(source));
    assert_eq!(mismatches(&declared, &same), Vec::<String>::new());
    let f_differs = "f: jointspace.h has int (struct jointspace_machine *, const double *, size_t)";
    let cases = [
        (source.replace(", n: usize", ""), f_differs),
        (source.replace("n: usize", "n: c_int"), f_differs),
        (source.replace("*const f64", "*mut f64"), f_differs),
        (source.replace("-> c_int {}", "{}"), f_differs),
        (
            source.replace("-> f64", "-> c_int"),
            "h: jointspace.h has double",
        ),
        (
            source.replace("fn g()", "fn g2()"),
            "g2: exported by the library, not declared",
        ),
        (
            source.replace("fn g()", "fn g2()"),
            "g: declared in jointspace.h, not exported",
        ),
        (
            source.replace(
                "(no_mangle)]\npub extern \"C\" fn g",
                "(inline)]\npub extern \"C\" fn g",
            ),
            "the library ?unmangled",
        ),
    ];
    for (changed, expected) in cases {
        let problems = mismatches(&declared, &rust_functions(&strip_comments(&changed))).join("\n");
        assert!(
            problems.contains(expected),
            "'{expected}' not in: {problems}"
        );
    }
}

/// The body of `opening { … }` in `text` (comments left out).
fn body<'a>(text: &'a str, opening: &str) -> &'a str {
    let start = text
        .find(opening)
        .unwrap_or_else(|| panic!("no '{opening}'"))
        + opening.len();
    let end = start + text[start..].find('}').expect("closing brace");
    &text[start..end]
}

/// `struct jointspace_hall_scan`, which cffi fills field by field, against the library's `#[repr(C)]` mirror: the
/// same fields in the same order with the same C types.
#[test]
fn the_hall_scan_settings_have_the_same_fields() {
    let root = workspace_root();
    let header = strip_comments(
        &std::fs::read_to_string(root.join("klipper/jointspace_klipper/jointspace.h"))
            .expect("header"),
    );
    let mut declared = Vec::new();
    for line in body(&header, "struct jointspace_hall_scan {").split(';') {
        let mut w = words(line);
        let Some(type_word) = w.first().cloned() else {
            continue;
        };
        w.remove(0);
        declared.extend(w.into_iter().map(|name| (name, type_word.clone())));
    }
    let source = strip_comments(
        &std::fs::read_to_string(root.join("crates/klipper/src/scan.rs")).expect("scan.rs"),
    );
    let mirrored: Vec<(String, String)> = body(&source, "pub struct HallScanSettings {")
        .split(',')
        .filter_map(|field| field.trim().strip_prefix("pub "))
        .map(|field| {
            let (name, rust) = field.split_once(':').expect("name: Type");
            (name.trim().to_string(), c_type(rust))
        })
        .collect();
    assert!(declared.len() > 5, "{declared:?}");
    assert_eq!(declared, mirrored);
}
