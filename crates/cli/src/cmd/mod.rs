//! One module per subcommand.

pub mod calibrate;
pub mod convert;
pub mod demo;
pub mod estimate;
pub mod post_process;
pub mod run;
pub mod simulate;
pub mod stats;
pub mod view;
pub mod workspace;

/// Convert an `anyhow` error into a report (plain message, with its causes).
pub fn plain(e: anyhow::Error) -> miette::Report {
    miette::miette!("{e:#}")
}

/// For `--json`: a failure as JSON on standard output (`{"error": {"file", "line", "column", "message"}}`;
/// line and column when the failure has an input line), beside the diagnostic on standard error.
pub fn print_json_error(file: &str, place: Option<(u64, u32)>, message: &str) {
    let (line, column) = match place {
        Some((line, column)) => (Some(line), Some(column)),
        None => (None, None),
    };
    let value = serde_json::json!({
        "error": { "file": file, "line": line, "column": column, "message": message }
    });
    crate::outln!(
        "{}",
        serde_json::to_string_pretty(&value).unwrap_or_default()
    );
}
