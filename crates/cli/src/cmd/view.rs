//! `jointspace view`: the planned print as one self-contained HTML page (no server, works offline): the toolpath
//! by layer and in 3D coloured by speed, by the limit that holds each move, by each motor's speed and acceleration
//! against its limits, or by time; refused moves at their lines; the workspace map under the part; the motors
//! against time with their limits; and the estimate's numbers. The print is planned once, by the estimate.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use printjob::PlanOptions;

use crate::machine::{HostArg, load_machine};
use crate::timing::{hms, show_warnings, with_input};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Printer configuration (Klipper's printer.cfg format).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// G-code file (`-` for standard input).
    pub file: PathBuf,
    /// The page to write (default: the G-code file's name with `.html`).
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// The most path segments on the page (consecutive segments that look alike are merged to stay within it;
    /// refused moves, limit hits and slowed moves are always kept).
    #[arg(long, default_value_t = view::Budget::DEFAULT.total)]
    pub max_segments: usize,
    /// Reproduce Klipper's batch-mode flushing (`klippy.py -i`), as `estimate --klipper-batch`.
    #[arg(long)]
    pub klipper_batch: bool,
    /// The host whose planning to reproduce: `klipper`, or `kalico-fekt`.
    #[arg(long, value_enum, default_value_t = HostArg::Klipper)]
    pub host: HostArg,
}

/// The page's path: `--out`, or the G-code file's own name with `.html`.
fn out_path(args: &Args) -> miette::Result<PathBuf> {
    match &args.out {
        Some(out) if outfile::is_stdio(out) => Err(miette::miette!(
            "`-o -`: the page is written to a file (it is one large HTML file); name one"
        )),
        Some(out) => Ok(out.clone()),
        None if outfile::is_stdio(&args.file) => Err(miette::miette!(
            "reading standard input: name the page to write with -o part.html"
        )),
        None => Ok(args.file.with_extension("html")),
    }
}

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let machine = load_machine(&args.config)?;
    let out = out_path(&args)?;
    crate::output::register_input(&args.file);
    crate::output::refuse_input(&out).map_err(super::plain)?;
    if args.max_segments == 0 {
        return Err(miette::miette!("--max-segments must be at least 1"));
    }
    let options = PlanOptions {
        skip_unreachable: true,
        klipper_batch: args.klipper_batch,
        host: args.host.into(),
    };
    let budget = view::Budget {
        total: args.max_segments,
        per_layer: view::Budget::DEFAULT.per_layer.min(args.max_segments),
        ..view::Budget::DEFAULT
    };
    let ((estimate, page), name) = with_input(&machine, &args.file, |open, name| {
        view::plan(&machine, options, open, name, budget)
    })
    .map_err(|f| f.report)?;
    show_warnings(&estimate, &name);
    let meta = view::PageMeta {
        file: name.clone(),
        config: args.config.display().to_string(),
    };
    crate::output::write_atomically(&out, |w| {
        view::write_page(w, &estimate, &page, &meta)
            .map_err(|e| outfile::write_error(&out, e).into())
    })
    .map_err(|e: anyhow::Error| super::plain(e))?;
    crate::outln!("{}", report(&out, &estimate, &page));
    Ok(ExitCode::SUCCESS)
}

/// One paragraph: the page, the print time, what the page holds.
fn report(out: &Path, estimate: &printjob::Estimate, page: &view::View) -> String {
    let c = &page.collected;
    let planned: usize = c.layers.iter().map(|l| l.planned).sum();
    let kept: usize = c.layers.iter().map(|l| l.segments.len()).sum();
    let size = std::fs::metadata(out).map(|m| m.len()).unwrap_or(0);
    let mut text = format!(
        "{}: planned print time {} ({:.3} s); {} layers, {kept} segments drawn of {planned} planned \
         (merged within {} mm), {:.1} MB",
        out.display(),
        hms(estimate.total),
        estimate.total,
        c.layers.len(),
        c.tolerance,
        size as f64 / 1e6
    );
    if c.stride > 1 {
        let which = if c.stride == 2 {
            "every other layer".to_string()
        } else {
            format!("every {}th layer", c.stride)
        };
        text += &format!(
            "; over --max-segments: {which} whole, the others with their limit hits, slowed moves and refusals"
        );
    }
    if c.refused_total > 0 {
        text += &format!("; {} refused moves shown at their lines", c.refused_total);
    }
    if estimate.slowed_total > 0 {
        text += &format!(
            "; {} moves slowed below a quarter of their speed",
            estimate.slowed_total
        );
    }
    text
}
