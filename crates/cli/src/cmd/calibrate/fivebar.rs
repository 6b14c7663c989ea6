//! `jointspace calibrate fivebar-pattern` and `calibrate fivebar`: the five-bar's pattern of crosses made through
//! the configured machine's own kinematics, and its geometry identified from the crosses as measured by hand, with
//! the verdict and the corrected `[printer]` keys.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use calibrate::fivebar::{self, FivebarGeometry, Identification};
use calibrate::scara::PatternOptions;
use kinematics::fivebar::Fivebar;

use super::Method;
use crate::report;

#[derive(Debug, clap::Args)]
pub struct PatternArgs {
    /// Configuration of the five-bar.
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// Number of crosses.
    #[arg(long, default_value_t = fivebar::DEFAULT_POSES)]
    pub poses: usize,
    /// Size of each cross, tip to tip (mm).
    #[arg(long, default_value_t = 6.0, value_name = "MM")]
    pub cross: f64,
    /// Output G-code.
    #[arg(short = 'o', long = "out", default_value = "fivebar-pattern.gcode")]
    pub out: PathBuf,
    /// The measurements file to fill in: each cross's motor readings, empty x_mm and y_mm.
    #[arg(long, default_value = "fivebar-measurements.csv", value_name = "CSV")]
    pub template: PathBuf,
}

#[derive(Debug, clap::Args)]
pub struct FitArgs {
    /// Configuration whose geometry starts the fit (and whose working mode the machine has).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// Measurements: the file `calibrate fivebar-pattern` wrote, filled in: CSV
    /// `motor_left_deg,motor_right_deg,x_mm,y_mm` (x, y: the printer's X and Y).
    #[arg(long, value_name = "CSV")]
    pub measurements: PathBuf,
    /// How the cross centres were measured; gives the measurement noise the residuals are judged against.
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// Measurement noise (mm, 1σ per coordinate), instead of the method's (calipers 0.02, scanner 0.03,
    /// microscope 0.005).
    #[arg(long, value_name = "MM")]
    pub noise: Option<f64>,
    /// Result file (JSON).
    #[arg(short = 'o', long = "out", default_value = "fivebar.json")]
    pub out: PathBuf,
    /// Also write the config with the identified keys applied (the config's text and a `[printer]` section with
    /// them at its end, which Klipper's reader merges into the first): only when the fit is trustworthy.
    #[arg(long, value_name = "CFG")]
    pub corrected: Option<PathBuf>,
    /// Print the result as JSON (what the result file holds) instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The five-bar of a config, built as every command builds it, with where homing leaves it.
fn machine_of(path: &Path) -> miette::Result<(Fivebar, Option<[f64; 3]>)> {
    let machine = crate::machine::load_machine(path)?;
    let kin = Fivebar::of(machine.setup.kinematics.as_ref())
        .ok_or_else(|| miette::miette!("{}: not a five-bar machine", path.display()))?;
    Ok((kin.clone(), machine.setup.home_position))
}

pub fn pattern(args: PatternArgs) -> miette::Result<ExitCode> {
    let (kin, home) = machine_of(&args.config)?;
    for path in [&args.out, &args.template] {
        crate::output::refuse_input(path).map_err(super::super::plain)?;
    }
    let options = PatternOptions {
        cross_size: args.cross,
        home,
        ..PatternOptions::default()
    };
    let pattern =
        fivebar::machine_pattern(&kin, args.poses, &options).map_err(|e| miette::miette!("{e}"))?;
    crate::output::write_output(&args.out, |w| Ok(w.write_all(pattern.gcode.as_bytes())?))
        .map_err(super::super::plain)?;
    crate::output::write_output(&args.template, |w| {
        Ok(w.write_all(pattern.template.as_bytes())?)
    })
    .map_err(super::super::plain)?;
    if pattern.poses.len() < args.poses {
        crate::errln!(
            "warning: {} crosses of the {} asked: no more poses of this machine take a whole {} mm cross apart from \
             the others",
            pattern.poses.len(),
            args.poses,
            args.cross
        );
    }
    crate::outln!(
        "{} crosses written to {} (condition number of the poses {:.1}), their motor readings to {}; print it, \
         measure each cross centre, fill in x_mm and y_mm and run `jointspace calibrate fivebar -c {} \
         --measurements {}`",
        pattern.poses.len(),
        args.out.display(),
        pattern.condition_number,
        args.template.display(),
        args.config.display(),
        args.template.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The identified values as `[printer]` keys (zeros in degrees), in [`fivebar::PARAM_NAMES`] order.
fn config_keys(g: &FivebarGeometry) -> Vec<(&'static str, f64)> {
    fivebar::PARAM_NAMES
        .iter()
        .zip(g.to_array())
        .enumerate()
        .map(|(k, (name, v))| (*name, if k % 5 == 4 { v.to_degrees() } else { v }))
        .collect()
}

/// The `[printer]` section of the identified keys.
fn printer_section(g: &FivebarGeometry) -> String {
    let mut s = String::from("[printer]\n");
    for (name, v) in config_keys(g) {
        let _ = writeln!(s, "{name}: {v:.4}");
    }
    s
}

pub fn fit(args: FitArgs) -> miette::Result<ExitCode> {
    let (kin, _) = machine_of(&args.config)?;
    let start = FivebarGeometry::from(kin.params());
    let path = &args.measurements;
    crate::output::register_input(path);
    let name = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|e| miette::miette!("cannot read {name}: {e}"))?;
    let data = fivebar::parse_measurements(&text, &name).map_err(|e| miette::miette!("{e}"))?;
    let noise = super::noise_from(args.noise, args.method, Method::Calipers)?;
    let fit = fivebar::identify(&data, &start).map_err(|e| miette::miette!("{name}: {e}"))?;
    let verdict = fivebar::judge(&data, &fit, &start, noise);
    let json = result_json(&fit, &verdict);
    let mut outputs = vec![args.out.clone()];
    outputs.extend(args.corrected.clone());
    for out in &outputs {
        crate::output::refuse_input(out).map_err(super::super::plain)?;
    }
    crate::output::write_output(&args.out, |w| Ok(serde_json::to_writer_pretty(w, &json)?))
        .map_err(super::super::plain)?;
    if let (Some(out), true) = (&args.corrected, verdict.trustworthy) {
        let config = std::fs::read_to_string(&args.config)
            .map_err(|e| miette::miette!("cannot read {}: {e}", args.config.display()))?;
        let text = format!(
            "{config}\n# identified by jointspace calibrate fivebar from {name}\n{}",
            printer_section(&fit.geometry)
        );
        crate::output::write_output(out, |w| Ok(w.write_all(text.as_bytes())?))
            .map_err(super::super::plain)?;
    }
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&json).unwrap_or_default()
        );
    } else {
        let mut text = report::fivebar_fit(&fit, data.len());
        text += &report::fit_verdict(&verdict, &data);
        if verdict.trustworthy {
            let _ = write!(
                text,
                "  corrected keys for printer.cfg:\n{}",
                printer_section(&fit.geometry)
            );
        }
        if !crate::output::is_stdio(&args.out) {
            let _ = writeln!(text, "  result written to {}", args.out.display());
        }
        crate::out!("{text}");
    }
    Ok(super::judged(&name, &verdict))
}

/// What the result file holds: the keys, their σ, the identifiability in both frames, the verdict.
fn result_json(fit: &Identification, verdict: &calibrate::verdict::Verdict) -> serde_json::Value {
    let keys: serde_json::Map<String, serde_json::Value> = config_keys(&fit.geometry)
        .into_iter()
        .map(|(n, v)| (n.to_string(), v.into()))
        .collect();
    let sigma: serde_json::Map<String, serde_json::Value> = fivebar::PARAM_NAMES
        .iter()
        .zip(fit.sigma)
        .enumerate()
        .map(|(k, (n, s))| {
            (
                n.to_string(),
                (if k % 5 == 4 { s.to_degrees() } else { s }).into(),
            )
        })
        .collect();
    serde_json::json!({
        "printer": keys, "sigma": sigma, "rms_mm": fit.rms,
        "identifiability": fit.identifiability, "free_frame": fit.free_frame, "verdict": verdict,
    })
}
