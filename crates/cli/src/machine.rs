//! Loading `printer.cfg` for a command: diagnostics pointing into the file, its warnings on standard error.

use std::path::Path;

use printjob::Machine;

use crate::diag;

/// Load `printer.cfg` and build the machine; the file becomes an input no output may replace.
pub fn load_machine(path: &Path) -> miette::Result<Machine> {
    outfile::register_input(path);
    let (config, notes) =
        Machine::read(path).map_err(|e| miette::Report::new(diag::config_error(&e)))?;
    for note in &notes {
        match &note.span {
            Some(span) => eprintln!("{span}: warning: {}", note.message),
            None => eprintln!("{}: warning: {}", path.display(), note.message),
        }
    }
    Machine::from_config(config, &path.display().to_string())
        .map_err(|e| miette::miette!("{}: {e}", path.display()))
}
