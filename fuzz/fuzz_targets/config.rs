//! Fuzz target `config`: arbitrary bytes as a `printer.cfg`, through the document reader and the machine
//! builder (and, when it is valid, through the kinematics constructor).
//!
//! The file is placed in a folder that does not exist, so `[include …]` lines resolve to nothing and the
//! target never reads the real filesystem.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match config::MachineConfig::from_str(text, "/nonexistent-jointspace-fuzz/printer.cfg") {
        Ok(machine) => {
            // A configuration that parses must either build a machine or say why not.
            let _ = motion::machine::MachineSetup::from_config(&machine);
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
