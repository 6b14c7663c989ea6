//! The tree's structural invariants (ARCHITECTURE.md): outside tests no source file over 800 lines, no function
//! over 80 lines (examples included), and no import loop between the modules of a crate (the crate root's re-exports
//! aside).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 800;
const MAX_FN_LINES: usize = 80;

pub(crate) fn crates_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.rs` file below `dir`.
pub(crate) fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The source without comments, string contents and `#[cfg(test)]` items, line by line.
pub(crate) fn code_lines(text: &str) -> Vec<String> {
    code_lines_with(text, false)
}

/// The source without comments and `#[cfg(test)]` items, line by line; string literals kept when `keep_strings`.
pub(crate) fn code_lines_with(text: &str, keep_strings: bool) -> Vec<String> {
    let mut lines = Vec::new();
    let mut skipping: Option<(i64, bool)> = None;
    for raw in text.lines() {
        let line = strip_comment_and_strings(raw, keep_strings);
        if let Some((depth, opened)) = &mut skipping {
            *depth += braces(&line);
            *opened |= line.contains('{');
            let done = (*opened && *depth <= 0) || (!*opened && line.trim_end().ends_with(';'));
            if done {
                skipping = None;
            }
            continue;
        }
        if line.trim_start().starts_with("#[cfg(test)]") {
            skipping = Some((0, false));
            continue;
        }
        lines.push(line);
    }
    lines
}

fn strip_comment_and_strings(line: &str, keep_strings: bool) -> String {
    let mut out = String::with_capacity(line.len());
    let mut in_string = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (in_string, c) {
            (false, '/') if chars.peek() == Some(&'/') => break,
            (false, '"') => {
                in_string = true;
                out.push('"');
            }
            (true, '\\') => {
                if let Some(escaped) = chars.next().filter(|_| keep_strings) {
                    out.extend(['\\', escaped]);
                }
            }
            (true, '"') => {
                in_string = false;
                out.push('"');
            }
            (true, c) if keep_strings => out.push(c),
            (true, _) => {}
            (false, c) => out.push(c),
        }
    }
    out
}

fn braces(line: &str) -> i64 {
    line.chars()
        .map(|c| match c {
            '{' => 1,
            '}' => -1,
            _ => 0,
        })
        .sum()
}

/// Functions longer than the limit: (name, first line, lines).
fn long_functions(lines: &[String]) -> Vec<(String, usize, usize)> {
    let mut found = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let Some(name) = fn_name(line) else { continue };
        let (mut depth, mut opened, mut end) = (0, false, i);
        for (j, l) in lines.iter().enumerate().skip(i) {
            depth += braces(l);
            opened |= l.contains('{');
            end = j;
            if (opened && depth <= 0) || (!opened && l.trim_end().ends_with(';')) {
                break;
            }
        }
        if end + 1 - i > MAX_FN_LINES {
            found.push((name, i + 1, end + 1 - i));
        }
    }
    found
}

fn fn_name(line: &str) -> Option<String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "fn")?;
    let qualifiers = [
        "pub",
        "pub(crate)",
        "pub(super)",
        "const",
        "unsafe",
        "async",
        "extern",
    ];
    if !words[..at]
        .iter()
        .all(|w| qualifiers.contains(w) || w.starts_with("\"") || w.starts_with("pub("))
    {
        return None;
    }
    let name = words.get(at + 1)?;
    Some(name.split(['(', '<']).next().unwrap_or(name).to_string())
}

/// A module's path inside its crate (`a::b` for `src/a/b.rs` or `src/a/b/mod.rs`; empty for the root).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap_or(file).with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("lib" | "main" | "mod")
    ) {
        parts.pop();
    }
    parts
}

/// The paths a file names through `crate::`, `super::` or `self::`, with `use` groups expanded.
fn named_paths(code: &str) -> Vec<Vec<String>> {
    let mut paths = Vec::new();
    for statement in code.split(';') {
        let statement = statement.trim();
        // The crate root's `pub use` is its public face, not a use of the module by the root's code.
        if statement.starts_with("pub use") {
            continue;
        }
        if let Some(tree) = statement.strip_prefix("use ") {
            let tree: String = tree.chars().filter(|c| !c.is_whitespace()).collect();
            expand(&tree, &mut paths);
        }
    }
    let words = code.split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'));
    for word in words {
        if ["crate::", "super::", "self::"]
            .iter()
            .any(|p| word.starts_with(p))
        {
            paths.push(word.split("::").map(str::to_string).collect());
        }
    }
    paths
}

/// `a::{b, c::{d, e}}` → `a::b`, `a::c::d`, `a::c::e`.
fn expand(tree: &str, out: &mut Vec<Vec<String>>) {
    let Some(open) = tree.find('{') else {
        out.push(tree.split("::").map(str::to_string).collect());
        return;
    };
    let head = tree[..open].trim_end_matches(':');
    let body = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
    let (mut depth, mut start) = (0, 0);
    let mut parts = Vec::new();
    for (i, c) in body.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&body[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&body[start..]);
    for part in parts.into_iter().filter(|p| !p.is_empty()) {
        let joined = if head.is_empty() {
            part.to_string()
        } else {
            format!("{head}::{part}")
        };
        expand(&joined, out);
    }
}

/// The module a path leads to: the longest prefix that is a module of the crate.
fn resolve(modules: &BTreeSet<Vec<String>>, here: &[String], path: &[String]) -> Vec<String> {
    let (mut target, rest): (Vec<String>, &[String]) = match path.first().map(String::as_str) {
        Some("crate") => (Vec::new(), &path[1..]),
        _ => (here.to_vec(), path),
    };
    let mut rest = rest;
    while let Some(first) = rest.first() {
        match first.as_str() {
            "super" => {
                target.pop();
            }
            "self" => {}
            _ => break,
        }
        rest = &rest[1..];
    }
    for segment in rest {
        let mut next = target.clone();
        next.push(segment.clone());
        if !modules.contains(&next) {
            break;
        }
        target = next;
    }
    target
}

/// A cycle in the module graph, if there is one (depth-first search with colours).
fn find_cycle(graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Option<Vec<String>> {
    fn visit(
        node: &Vec<String>,
        graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<String>> {
        state.insert(node.clone(), 1);
        stack.push(node.clone());
        for next in graph.get(node).into_iter().flatten() {
            match state.get(next).copied().unwrap_or(0) {
                0 => {
                    if let Some(cycle) = visit(next, graph, state, stack) {
                        return Some(cycle);
                    }
                }
                1 => {
                    let from = stack.iter().position(|m| m == next).unwrap_or(0);
                    return Some(stack[from..].iter().map(|m| m.join("::")).collect());
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(node.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in graph.keys() {
        if state.get(node).copied().unwrap_or(0) == 0
            && let Some(cycle) = visit(node, graph, &mut state, &mut Vec::new())
        {
            return Some(cycle);
        }
    }
    None
}

#[test]
fn files_functions_and_module_imports_stay_within_the_limits() {
    let mut problems = Vec::new();
    let mut crates: Vec<PathBuf> = std::fs::read_dir(crates_dir())
        .expect("crates folder")
        .flatten()
        .map(|e| e.path().join("src"))
        .filter(|src| src.is_dir())
        .collect();
    crates.sort();
    assert!(crates.len() >= 10, "found only {crates:?}");
    for src in &crates {
        let mut files = Vec::new();
        rust_files(src, &mut files);
        let mut code = BTreeMap::new();
        for file in &files {
            let text = std::fs::read_to_string(file).expect("source reads");
            let lines = code_lines(&text);
            if lines.len() > MAX_FILE_LINES {
                problems.push(format!("{}: {} lines", file.display(), lines.len()));
            }
            for (name, line, length) in long_functions(&lines) {
                problems.push(format!(
                    "{}:{line}: fn {name} has {length} lines",
                    file.display()
                ));
            }
            code.insert(module_of(src, file), lines.join("\n"));
        }
        let modules: BTreeSet<Vec<String>> = code.keys().cloned().collect();
        let graph: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = code
            .iter()
            .map(|(module, text)| {
                let targets = named_paths(text)
                    .iter()
                    .map(|path| resolve(&modules, module, path))
                    .filter(|target| target != module)
                    .collect();
                (module.clone(), targets)
            })
            .collect();
        if let Some(cycle) = find_cycle(&graph) {
            problems.push(format!("{}: import loop {cycle:?}", src.display()));
        }
        // Examples are programs too: the same limits on their files and functions.
        let mut examples = Vec::new();
        rust_files(&src.with_file_name("examples"), &mut examples);
        for file in &examples {
            let text = std::fs::read_to_string(file).expect("example reads");
            for (name, line, length) in long_functions(&code_lines(&text)) {
                problems.push(format!(
                    "{}:{line}: fn {name} has {length} lines",
                    file.display()
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_checks_see_what_they_look_for() {
    let text = "fn short() {\n}\n#[cfg(test)]\nmod tests {\n    fn long() {\n    }\n}\n";
    assert_eq!(code_lines(text).len(), 2);
    let long: String = std::iter::once("pub(crate) fn long(a: u8) {\n")
        .chain(std::iter::repeat_n("    let _ = \"}\"; // }\n", 90))
        .chain(std::iter::once("}\n"))
        .collect();
    let found = long_functions(&code_lines(&long));
    assert_eq!(found, [("long".to_string(), 1, 92)]);
    let mut paths = Vec::new();
    expand("crate::{a, b::{c, d}}", &mut paths);
    assert_eq!(paths.len(), 3);
    let modules: BTreeSet<Vec<String>> = [vec![], vec!["a".into()], vec!["b".into()]].into();
    let graph = BTreeMap::from([
        (
            vec!["a".to_string()],
            BTreeSet::from([vec!["b".to_string()]]),
        ),
        (
            vec!["b".to_string()],
            BTreeSet::from([vec!["a".to_string()]]),
        ),
    ]);
    assert!(find_cycle(&graph).is_some());
    let path: Vec<String> = vec!["super".into(), "b".into(), "Thing".into()];
    assert_eq!(resolve(&modules, &["a".to_string()], &path), ["b"]);
}
