//! Input for the tests that compare the fast path with the general path: random G-code lines and
//! the files of the shared corpus.

use std::path::{Path, PathBuf};

use proptest::collection::vec;
use proptest::sample::select;
use proptest::strategy::Strategy;

/// Up to `max_lines - 1` lines, each one of `commands`, then up to `max_words - 1` of `words`,
/// then a `\n`, `\r\n` or `\r`.
pub(crate) fn gcode_lines(
    commands: Vec<&'static str>,
    words: Vec<&'static str>,
    max_words: usize,
    max_lines: usize,
) -> impl Strategy<Value = String> {
    let line = (
        select(commands),
        vec(select(words), 0..max_words),
        select(vec!["\n", "\r\n", "\r"]),
    );
    vec(line, 0..max_lines).prop_map(|lines| {
        let mut text = String::new();
        for (command, words, end) in lines {
            text.push_str(command);
            text.extend(words);
            text.push_str(end);
        }
        text
    })
}

/// Calls `check` with each file of `../shared/corpus` and its bytes; prints a note when the corpus
/// is absent.
pub(crate) fn each_corpus_file(mut check: impl FnMut(&Path, &[u8])) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/corpus");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        eprintln!("{} absent: skipped", dir.display());
        return;
    };
    for path in entries.filter_map(Result::ok).map(|e| e.path()) {
        let text = std::fs::read(&path).expect("corpus file reads");
        check(&path, &text);
    }
}
