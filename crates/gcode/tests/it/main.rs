//! Integration tests of the gcode crate: the slicer corpus, round trips, malformed input, properties.

mod corpus;
mod malformed;
mod naive;
mod properties;
mod roundtrip;

use std::path::PathBuf;

/// `../shared/corpus` next to the workspace, or `None` (with a message) when absent.
pub fn corpus_files() -> Option<Vec<PathBuf>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/corpus");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            dir.display()
        );
        println!("SKIPPED: corpus directory {} not found", dir.display());
        return None;
    };
    let mut files: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "gcode"))
        .collect();
    files.sort();
    // A corpus loop over fewer files than the corpus holds would pass by not looking.
    assert!(
        files.len() >= 10,
        "{} corpus files, the corpus holds 10",
        files.len()
    );
    Some(files)
}

pub fn file_name(path: &std::path::Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}
