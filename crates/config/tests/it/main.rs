//! Integration tests of the config crate: golden Klipper configs, example configs, format cases and
//! property tests. Shared data is located at `../shared` from the workspace root and skipped if absent.

mod examples;
mod format;
mod golden;
mod machine;
mod props;

use std::path::PathBuf;

/// `../shared` relative to the workspace root, if present.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared");
    if dir.is_dir() {
        Some(dir)
    } else {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            dir.display()
        );
        println!("SKIPPED: shared data not found at {}", dir.display());
        None
    }
}

/// A committed fixture under `tests/it/fixtures`.
pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/it/fixtures")
        .join(name)
}

/// Independent minimal reader for test expectations: the value of `key` in `[section]` of a plain
/// config text (single-line values, no includes), as written.
pub fn raw_value(text: &str, section: &str, key: &str) -> Option<String> {
    let mut current = String::new();
    let mut found = None;
    for line in text.lines() {
        let line = line.trim();
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            current = name.to_string();
        } else if let Some((k, v)) = line.split_once(':')
            && current == section
            && k.trim() == key
        {
            found = Some(v.trim().to_string());
        }
    }
    found
}

/// `raw_value` parsed as a number.
pub fn raw_f64(text: &str, section: &str, key: &str) -> Option<f64> {
    raw_value(text, section, key).and_then(|v| v.parse().ok())
}
