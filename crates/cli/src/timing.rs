//! Planned time of a G-code file for `estimate` and `post-process`: the file planned (more than once when the
//! machine has motor limits, so it is reopened, or held in memory when it is standard input), the config's
//! `centre_slowdown` noted, the reader's and planner's warnings on standard error, errors at their line.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use printjob::{Estimate, EstimateError, Machine, PlanOptions, Reopen};

/// Warnings shown on standard error (`--json` carries them all).
const SHOWN_WARNINGS: usize = 10;

/// A failed estimate: the G-code place when it has one, the message, and the diagnostic.
pub struct Failure {
    pub place: Option<(u64, u32)>,
    pub message: String,
    pub report: miette::Report,
}

/// Plan `file` on `machine` and break its time down; `wanted` picks the lines whose planned time is kept.
pub fn estimate_file(
    machine: &Machine,
    file: &Path,
    options: PlanOptions,
    wanted: &dyn Fn(&gcode::Command) -> bool,
) -> Result<(Estimate, String), Failure> {
    let (estimate, name) = with_input(machine, file, |open, name| {
        printjob::estimate(machine, options, open, name, wanted)
    })?;
    show_warnings(&estimate, &name);
    Ok((estimate, name))
}

/// Run `plan` on the G-code of `file` (reopened for each planning pass; standard input held in memory), with
/// `centre_slowdown` noted and the failures located as the estimate's are; the input's name beside the result.
pub fn with_input<T>(
    machine: &Machine,
    file: &Path,
    plan: impl FnOnce(Reopen<'_>, &str) -> Result<T, EstimateError>,
) -> Result<(T, String), Failure> {
    note_centre_slowdown(machine);
    let plain = |message: String| Failure {
        place: None,
        report: miette::miette!("{message}"),
        message,
    };
    let (name, stdin_text) = if outfile::is_stdio(file) {
        let mut text = Vec::new();
        std::io::stdin()
            .read_to_end(&mut text)
            .map_err(|e| plain(format!("cannot read standard input: {e}")))?;
        ("<stdin>".to_string(), Some(text))
    } else {
        std::fs::File::open(file)
            .map_err(|e| plain(format!("cannot open {}: {e}", file.display())))?;
        (file.display().to_string(), None)
    };
    let open = || -> std::io::Result<Box<dyn BufRead + '_>> {
        Ok(match &stdin_text {
            Some(text) => Box::new(std::io::Cursor::new(text.as_slice())),
            None => Box::new(BufReader::with_capacity(
                1 << 16,
                std::fs::File::open(file)?,
            )),
        })
    };
    let result = plan(&open, &name).map_err(|e| match e {
        EstimateError::Plan(e) => Failure {
            place: Some(e.place()),
            message: e.message(),
            report: crate::diag::pipeline_error(file, e),
        },
        other => plain(other.to_string()),
    })?;
    Ok((result, name))
}

/// The reader's and planner's warnings on standard error, the first few (`--json` carries them all).
pub fn show_warnings(estimate: &Estimate, name: &str) {
    for w in estimate.warnings.iter().take(SHOWN_WARNINGS) {
        crate::errln!("{name}:{}:{}: warning: {}", w.line, w.column, w.message);
    }
    if estimate.warnings.len() > SHOWN_WARNINGS {
        let more = estimate.warnings.len() - SHOWN_WARNINGS;
        crate::errln!("{name}: {more} more warnings (`jointspace check` lists them all)");
    }
}

/// `centre_slowdown: klipper` in `[printer]` is read by the plug-in only (its `check_move` then slows whole moves by
/// Klipper's rule); `check`, `run` and the estimate plan jointspace's exact rule, so the printer may take longer.
fn note_centre_slowdown(machine: &Machine) {
    let entry = machine
        .config
        .document
        .section("printer")
        .and_then(|s| s.entry("centre_slowdown"));
    if let Some(entry) = entry.filter(|e| e.value().trim() == "klipper") {
        crate::errln!(
            "{}: warning: centre_slowdown: klipper makes the plug-in slow whole moves near the centre by Klipper's \
             rule; this estimate plans the exact rule (check and run do too), so the printer may take longer",
            entry.value_span()
        );
    }
}

/// `1h 02m 03s`, `4m 05s`, `12.3s`.
pub fn hms(seconds: f64) -> String {
    if !seconds.is_finite() {
        return format!("{seconds} s");
    }
    let sign = if seconds < 0.0 { "-" } else { "" };
    let s = seconds.abs();
    if s < 60.0 {
        return format!("{sign}{s:.1}s");
    }
    let whole = s.round() as u64;
    let (h, m, s) = (whole / 3600, whole / 60 % 60, whole % 60);
    if h > 0 {
        format!("{sign}{h}h {m:02}m {s:02}s")
    } else {
        format!("{sign}{m}m {s:02}s")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn durations_read_as_slicers_write_them() {
        assert_eq!(super::hms(12.34), "12.3s");
        assert_eq!(super::hms(245.0), "4m 05s");
        assert_eq!(super::hms(3723.4), "1h 02m 03s");
        assert_eq!(super::hms(-61.0), "-1m 01s");
    }
}
