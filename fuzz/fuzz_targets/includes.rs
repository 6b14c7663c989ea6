//! Fuzz target `includes`: arbitrary bytes as a tree of printer.cfg files that include each other. The input is cut
//! at `\0` into up to 16 files (`f0.cfg` … `f15.cfg`, `f0.cfg` the main one) written into a fresh folder, and the
//! main file is read by the one machine builder (`machine::Machine::load`). Chains, cycles, diamonds, globs
//! (`[include f*.cfg]`) and includes of what is not a file all come from the fuzzer.
//!
//! Invariants: no panic and no hang (libFuzzer's `-timeout`): every include tree is read within the reader's
//! bounds or refused with a reason.
#![no_main]

use libfuzzer_sys::fuzz_target;

/// Files one input may become.
const MAX_FILES: usize = 16;

fuzz_target!(|data: &[u8]| {
    let Ok(dir) = tempfile::tempdir() else {
        return;
    };
    for (i, text) in data.split(|&b| b == 0).take(MAX_FILES).enumerate() {
        if std::fs::write(dir.path().join(format!("f{i}.cfg")), text).is_err() {
            return;
        }
    }
    match machine::Machine::load(&dir.path().join("f0.cfg")) {
        Ok(_) => {}
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
