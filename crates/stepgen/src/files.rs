//! Step files plus statistics for every motor: sinks to hand to [`crate::StepPipeline`] or
//! [`crate::StepGenerator`], and the closing step that renames the files into place.

use std::path::Path;

use crate::error::StepFileError;
use crate::sink::Tee;
use crate::stats::{MotorStats, StepStats};
use crate::writer::StepFileWriter;

/// Statistics for one motor, plus its step file when one is written.
pub type FileAndStats = Tee<StepStats, Option<StepFileWriter>>;

/// One sink per motor name writing `dir/<name>.txt` (or `.txt.gz`) and collecting statistics.
pub fn step_file_sinks(
    dir: &Path,
    names: &[String],
    gzip: bool,
    clock_hz: f64,
) -> Result<Vec<FileAndStats>, StepFileError> {
    let extension = if gzip { "txt.gz" } else { "txt" };
    names
        .iter()
        .map(|name| {
            let writer = StepFileWriter::create(dir.join(format!("{name}.{extension}")))?;
            Ok(Tee(StepStats::new(clock_hz), Some(writer)))
        })
        .collect()
}

/// Close the files of [`step_file_sinks`] (renaming them into place) and return each motor's statistics;
/// `filtered_pairs` is per motor, in the same order (as returned by `StepPipeline::finish`).
pub fn finish_step_files(
    names: &[String],
    sinks: Vec<FileAndStats>,
    filtered_pairs: &[u64],
    clock_hz: f64,
) -> Result<Vec<(String, MotorStats)>, StepFileError> {
    let mut stats = Vec::with_capacity(sinks.len());
    for (index, Tee(collected, writer)) in sinks.into_iter().enumerate() {
        if let Some(writer) = writer {
            writer.finish()?;
        }
        let name = names
            .get(index)
            .cloned()
            .unwrap_or_else(|| format!("motor{index}"));
        let filtered = filtered_pairs.get(index).copied().unwrap_or(0);
        stats.push((name, collected.summary(clock_hz, filtered)));
    }
    Ok(stats)
}
