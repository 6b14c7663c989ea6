//! Ctrl-C (SIGINT), SIGTERM and SIGHUP handling: the signal only sets a flag, and the long-running loops (`run`, `convert`)
//! poll [`requested`] and stop with an error, so every temporary output file is dropped (deleted) instead of
//! being renamed into place. A second signal while the first is still being honoured exits at once with the
//! conventional status 130: the user asked twice, and temp-file guards cannot run then, but nothing partial
//! was renamed into place either.

use std::sync::atomic::{AtomicBool, Ordering};

/// Set by the signal handler; read by the pipelines.
static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Exit status of a process ended by SIGINT (128 + 2), as shells report it.
pub const INTERRUPTED_EXIT_CODE: i32 = 130;

/// Why the handler could not be installed.
#[derive(Debug, thiserror::Error)]
#[error("cannot install the Ctrl-C handler: {0}")]
pub struct InstallError(#[from] ctrlc::Error);

/// Install the handler once, at start-up. Calling it again is harmless (the second call reports that a
/// handler already exists, which this function treats as success).
pub fn install() -> Result<(), InstallError> {
    match ctrlc::set_handler(on_signal) {
        Ok(()) | Err(ctrlc::Error::MultipleHandlers) => Ok(()),
        Err(e) => Err(InstallError(e)),
    }
}

/// Whether the user asked to stop: checked between lines and chunks of work.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// The error message a stopped pipeline reports.
pub const INTERRUPTED_MESSAGE: &str = "interrupted: no output was written";

fn on_signal() {
    if REQUESTED.swap(true, Ordering::Relaxed) {
        // Second Ctrl-C: the pipeline did not stop in time; leave now.
        std::process::exit(INTERRUPTED_EXIT_CODE);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flag_starts_clear_and_install_is_idempotent() {
        assert!(!requested());
        install().expect("first install");
        install().expect("second install is accepted");
        assert!(!requested());
    }
}
