//! `jointspace stats FILE`: a streaming summary of a G-code file.

use crate::{diag, input};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// G-code file (`-` for standard input).
    pub file: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let (reader, name, bar) = input::open_gcode(&args.file).map_err(super::plain)?;
    let stats = gcode::file_stats(reader, name.as_str())
        .map_err(|e| miette::Report::new(diag::gcode_error(&e)))?;
    bar.finish_and_clear();
    if args.json {
        let text = serde_json::to_string_pretty(&stats).map_err(|e| miette::miette!("{e}"))?;
        crate::outln!("{text}");
    } else {
        crate::out!("{}", render(&name, &stats));
    }
    Ok(ExitCode::SUCCESS)
}

/// The human-readable summary.
pub fn render(name: &str, s: &gcode::Stats) -> String {
    let mut out = format!("{name}\n");
    out += &format!("  lines            {}\n", s.lines);
    out += &format!(
        "  moves            {} straight, {} arcs, {} extruding\n",
        s.moves, s.arcs, s.extruding_moves
    );
    out += &format!(
        "  filament         {:.3} mm pushed, {:.3} mm retracted\n",
        s.total_extrusion, s.total_retraction
    );
    out += &format!("  XY travel        {:.1} mm\n", s.xy_travel);
    if let Some(b) = &s.extrusion_bbox {
        out += &format!(
            "  printed box      X {:.3}..{:.3}  Y {:.3}..{:.3}  Z {:.3}..{:.3}\n",
            b.min[0], b.max[0], b.min[1], b.max[1], b.min[2], b.max[2]
        );
    }
    out += &format!("  layers           {}\n", s.layers);
    if !s.features.is_empty() {
        let features: Vec<&str> = s.features.iter().map(String::as_str).collect();
        out += &format!("  features         {}\n", features.join(", "));
    }
    let mut commands: Vec<(&String, &u64)> = s.commands.iter().collect();
    commands.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    let listed: Vec<String> = commands
        .iter()
        .take(12)
        .map(|(k, v)| format!("{k}×{v}"))
        .collect();
    out += &format!("  commands         {}\n", listed.join(" "));
    if s.warnings > 0 {
        out += &format!("  warnings         {}\n", s.warnings);
    }
    out
}
