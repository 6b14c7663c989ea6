//! `jointspace estimate`: the time the printer will take (plan only, no steps), by layer, feature type and machine
//! limit, beside the slicer's own estimate.

use std::path::PathBuf;
use std::process::ExitCode;

use printjob::{Estimate, Part, PlanOptions};

use crate::machine::{HostArg, load_machine};
use crate::timing::{estimate_file, hms};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Printer configuration (Klipper's printer.cfg format).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// G-code file (`-` for standard input).
    pub file: PathBuf,
    /// Print the estimate as JSON (every layer and feature).
    #[arg(long)]
    pub json: bool,
    /// Layers listed in the text report: the slowest ones, when the print has more.
    #[arg(long, default_value_t = 20)]
    pub layers: usize,
    /// Reproduce Klipper's batch-mode flushing (`klippy.py -i`), for comparisons with Klipper's output.
    #[arg(long)]
    pub klipper_batch: bool,
    /// The host whose planning to reproduce: `klipper`, or `kalico-fekt`.
    #[arg(long, value_enum, default_value_t = HostArg::Klipper)]
    pub host: HostArg,
}

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let machine = load_machine(&args.config)?;
    let options = PlanOptions {
        skip_unreachable: false,
        klipper_batch: args.klipper_batch,
        host: args.host.into(),
    };
    let (estimate, name) =
        estimate_file(&machine, &args.file, options, &|_| false).map_err(|f| {
            if args.json {
                super::print_json_error(&args.file.display().to_string(), f.place, &f.message);
            }
            f.report
        })?;
    if args.json {
        let mut value = serde_json::to_value(&estimate).map_err(|e| miette::miette!("{e}"))?;
        value["file"] = name.into();
        value["config"] = args.config.display().to_string().into();
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&value).map_err(|e| miette::miette!("{e}"))?
        );
    } else {
        crate::out!("{}", text(&estimate, &name, args.layers));
    }
    Ok(ExitCode::SUCCESS)
}

fn text(e: &Estimate, name: &str, layers: usize) -> String {
    let mut out = format!(
        "{name}: planned print time {} ({:.3} s)\n",
        hms(e.total),
        e.total
    );
    match e.slicer {
        Some(s) if s > 0.0 => {
            let diff = 100.0 * (e.total - s) / s;
            out += &format!(
                "  slicer's estimate {} ({s:.0} s): the plan is {diff:+.1} %\n",
                hms(s)
            );
        }
        _ => out += "  slicer's estimate: none in the file\n",
    }
    if !e.limits.is_empty() {
        out += &format!(
            "  without the machine's motor limits {}: they add {}\n",
            hms(e.without_motor_limits),
            hms(e.total - e.without_motor_limits)
        );
        for l in &e.limits {
            let value = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v}"));
            out += &format!(
                "    {} (velocity {}, acceleration {}) alone adds {}\n",
                l.motor,
                value(l.max_velocity),
                value(l.max_accel),
                hms(l.lost)
            );
        }
    }
    if let Some(rule) = e.klipper_rule {
        out += &format!(
            "  with Klipper's own rule instead (whole moves slowed near the centre, centre_slowdown: klipper) {}\n",
            hms(rule)
        );
    }
    out += &table("feature", &e.features, e.total, usize::MAX);
    out += &table("layer", &e.layers, e.total, layers);
    if e.slowed_total > 0 {
        out += &format!(
            "  {} moves slowed below a quarter of their speed",
            e.slowed_total
        );
        out += &format!(", the first {}:\n", e.slowed.len().min(10));
        for s in e.slowed.iter().take(10) {
            out += &format!(
                "    {name}:{}: {:.1} mm/s of {:.1} requested\n",
                s.line, s.allowed, s.requested
            );
        }
    }
    out
}

/// Parts as rows: name, time, share and what the motor limits add; at most `most` rows (the slowest, in file order).
fn table(kind: &str, parts: &[Part], total: f64, most: usize) -> String {
    if parts.is_empty() {
        return format!("  by {kind}: no {kind} markers in the file\n");
    }
    let mut shown: Vec<&Part> = parts.iter().collect();
    let mut out = format!("  by {kind} ({}):\n", parts.len());
    if shown.len() > most {
        shown.sort_by(|a, b| b.time.total_cmp(&a.time));
        shown.truncate(most);
        shown.sort_by_key(|p| p.line);
        out = format!(
            "  by {kind}, the {most} slowest of {} (--json lists all):\n",
            parts.len()
        );
    }
    for p in shown {
        let name = p.name.as_deref().unwrap_or("(before the first marker)");
        let share = if total > 0.0 {
            100.0 * p.time / total
        } else {
            0.0
        };
        out += &format!("    {name:<28} {:>12} {share:5.1} %", hms(p.time));
        if p.lost.abs() >= 0.05 {
            out += &format!("  limits add {}", hms(p.lost));
        }
        out += &format!("  (line {})\n", p.line);
    }
    out
}
