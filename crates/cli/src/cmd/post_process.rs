//! `jointspace post-process`: a slicer's post-processing step. The file is planned as the printer will plan it,
//! then its `M73` progress lines and the slicer's time comments are rewritten with the planned times, into a
//! new file beside it that replaces it by rename only once complete: the G-code is never left half written, and
//! on any error (no config, a G-code error, a move the machine refuses) the file stays as it was.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use gcode::{Command, Meta};
use printjob::PlanOptions;

use crate::machine::load_machine;
use crate::timing::estimate_file;

/// The environment variable naming the printer config when `-c` is not given.
pub const CONFIG_VARIABLE: &str = "JOINTSPACE_CONFIG";

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Printer configuration (Klipper's printer.cfg format); default: the file named by $JOINTSPACE_CONFIG.
    #[arg(short = 'c', long = "config")]
    pub config: Option<PathBuf>,
    /// The G-code file to rewrite in place (slicers pass it as the last argument).
    pub file: PathBuf,
}

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let config = match (&args.config, std::env::var_os(CONFIG_VARIABLE)) {
        (Some(path), _) => path.clone(),
        (None, Some(path)) if !path.is_empty() => PathBuf::from(path),
        _ => miette::bail!(
            "no printer config: give -c printer.cfg or set {CONFIG_VARIABLE}=/path/to/printer.cfg"
        ),
    };
    if outfile::is_stdio(&args.file) {
        miette::bail!("post-process rewrites a file in place: give its path, not -");
    }
    let machine = load_machine(&config)?;
    let wanted = |c: &Command| match c {
        Command::Other { name } => name == "M73",
        Command::Meta(Meta::TimeElapsed(_) | Meta::PrintTimeEstimate { .. }) => true,
        _ => false,
    };
    let (estimate, _) = estimate_file(&machine, &args.file, PlanOptions::default(), &wanted)
        .map_err(|f| f.report)?;
    let changed = rewrite(&args.file, &estimate.marks, estimate.total)
        .map_err(|e| miette::miette!("{e:#}"))?;
    crate::errln!(
        "{}: planned print time {} ({:.1} s); {changed} time lines rewritten",
        args.file.display(),
        crate::timing::hms(estimate.total),
        estimate.total
    );
    Ok(ExitCode::SUCCESS)
}

/// Rewrite the lines of `marks` (line, planned time there) in `path` through a pending file that replaces it when
/// complete; how many lines changed.
fn rewrite(path: &Path, marks: &[(u64, f64)], total: f64) -> anyhow::Result<usize> {
    let input = std::fs::File::open(path)
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e}", path.display()))?;
    let mut input = BufReader::with_capacity(1 << 16, input);
    let pending = outfile::PendingFile::create(path)?;
    let mut out = std::io::BufWriter::with_capacity(1 << 16, pending.file());
    let (mut line, mut changed, mut next) = (0u64, 0usize, marks.iter().peekable());
    let mut buffer = Vec::new();
    loop {
        buffer.clear();
        let read = input
            .read_until(b'\n', &mut buffer)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
        if read == 0 {
            break;
        }
        line += 1;
        let mut written = false;
        while let Some(&&(mark, time)) = next.peek() {
            if mark > line {
                break;
            }
            next.next();
            if mark == line
                && !written
                && let Ok(text) = std::str::from_utf8(&buffer)
                && let Some(new) = rewrite_line(text, time, total)
            {
                changed += usize::from(new != text);
                out.write_all(new.as_bytes())?;
                written = true;
            }
        }
        if !written {
            out.write_all(&buffer)?;
        }
    }
    out.flush()
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    drop(out);
    pending.commit()?;
    Ok(changed)
}

/// The line (with its line end) with the planned times: `M73 P R` (and Prusa's silent-mode `Q S`) as percent done
/// and minutes left at `time` of `total`, the slicer's total and elapsed-time comments; `None`: not a time line.
pub fn rewrite_line(text: &str, time: f64, total: f64) -> Option<String> {
    let body = text.trim_end_matches(['\n', '\r']);
    let ending = &text[body.len()..];
    let indent = &body[..body.len() - body.trim_start().len()];
    let trimmed = body.trim_start();
    let new = if let Some(comment) = trimmed.strip_prefix(';') {
        time_comment(comment, time, total)?
    } else {
        progress(trimmed, time, total)?
    };
    Some(format!("{indent}{new}{ending}"))
}

/// `M73 P.. R..`: every P/Q the percent of the time done, every R/S the minutes left; other words kept.
fn progress(line: &str, time: f64, total: f64) -> Option<String> {
    let (code, comment) = match line.find(';') {
        Some(at) => (&line[..at], Some(&line[at..])),
        None => (line, None),
    };
    let mut words = code.split_whitespace();
    if !words.next()?.eq_ignore_ascii_case("M73") {
        return None;
    }
    let done = if total > 0.0 {
        (100.0 * time / total).floor().clamp(0.0, 100.0)
    } else {
        100.0
    };
    let left = ((total - time).max(0.0) / 60.0).ceil();
    let mut out = String::from("M73");
    for word in words {
        let letter = word.chars().next()?.to_ascii_uppercase();
        match letter {
            'P' | 'Q' => out += &format!(" {letter}{done:.0}"),
            'R' | 'S' => out += &format!(" {letter}{left:.0}"),
            _ => out += &format!(" {word}"),
        }
    }
    if let Some(comment) = comment {
        out += " ";
        out += comment;
    }
    Some(out)
}

/// A slicer's time comment (the text after `;`) with the planned times.
fn time_comment(comment: &str, time: f64, total: f64) -> Option<String> {
    let text = comment.trim_start();
    let lead = &comment[..comment.len() - text.len()];
    let new = if let Some(at) = text.find(") = ")
        && text.starts_with("estimated printing time (")
    {
        format!("{}{}", &text[..at + 4], dhms(total))
    } else if text.starts_with("TIME_ELAPSED:") {
        format!("TIME_ELAPSED:{time:.6}")
    } else if text.starts_with("TIME:") {
        format!("TIME:{:.0}", total.round())
    } else if text.starts_with("Build time:") {
        let minutes = (total / 60.0).round() as u64;
        format!(
            "Build time: {} hours {} minutes",
            minutes / 60,
            minutes % 60
        )
    } else if text.starts_with("Estimated Build Time:") {
        format!("Estimated Build Time:   {:.2} minutes", total / 60.0)
    } else {
        return None;
    };
    Some(format!(";{lead}{new}"))
}

/// PrusaSlicer's way: `1d 2h 3m 4s`, leading zero parts left out.
fn dhms(seconds: f64) -> String {
    let whole = seconds.max(0.0).round() as u64;
    let parts = [
        (whole / 86_400, 'd'),
        (whole / 3_600 % 24, 'h'),
        (whole / 60 % 60, 'm'),
        (whole % 60, 's'),
    ];
    let first = parts.iter().position(|p| p.0 > 0).unwrap_or(3);
    let words: Vec<String> = parts[first..]
        .iter()
        .map(|(v, unit)| format!("{v}{unit}"))
        .collect();
    words.join(" ")
}

#[cfg(test)]
mod tests {
    use super::rewrite_line;

    #[test]
    fn progress_lines_and_time_comments() {
        let total = 4000.0;
        assert_eq!(
            rewrite_line("M73 P0 R3\n", 2000.0, total).expect("rewritten"),
            "M73 P50 R34\n"
        );
        assert_eq!(
            rewrite_line("M73 Q7 S3\r\n", 4000.0, total).expect("rewritten"),
            "M73 Q100 S0\r\n"
        );
        assert_eq!(
            rewrite_line("M73 P1 ; progress\n", 40.0, total).expect("rewritten"),
            "M73 P1 ; progress\n"
        );
        assert_eq!(
            rewrite_line(
                "; estimated printing time (normal mode) = 3m 41s\n",
                0.0,
                total
            )
            .expect("rewritten"),
            "; estimated printing time (normal mode) = 1h 6m 40s\n"
        );
        assert_eq!(
            rewrite_line(";TIME:1479\n", 0.0, 90_061.0).expect("rewritten"),
            ";TIME:90061\n"
        );
        assert_eq!(
            rewrite_line(";TIME_ELAPSED:12.5\n", 13.25, total).expect("rewritten"),
            ";TIME_ELAPSED:13.250000\n"
        );
        assert_eq!(
            rewrite_line(";   Build time: 0 hours 31 minutes\n", 0.0, 5400.0).expect("rewritten"),
            ";   Build time: 1 hours 30 minutes\n"
        );
        assert_eq!(
            rewrite_line("; Estimated Build Time:   7.01 minutes", 0.0, 450.0).expect("rewritten"),
            "; Estimated Build Time:   7.50 minutes"
        );
        assert_eq!(rewrite_line("G1 X1\n", 0.0, total), None);
        assert_eq!(super::dhms(90_061.0), "1d 1h 1m 1s");
        assert_eq!(super::dhms(34.0), "34s");
    }
}
