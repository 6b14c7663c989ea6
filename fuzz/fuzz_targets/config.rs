//! Fuzz target `config`: arbitrary bytes as a `printer.cfg`, through the one machine builder every front-end
//! uses (`machine::Machine::from_text`: the document reader, the typed configuration, the kinematics and the
//! planner's limits and homing pose): it builds the machine or says why not, and never panics.
//!
//! The file is placed in a folder that does not exist, so `[include …]` lines resolve to nothing and the
//! target never reads the real filesystem.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = machine::Machine::from_text(text, "/nonexistent-jointspace-fuzz/printer.cfg") {
        let _ = e.to_string();
    }
});
