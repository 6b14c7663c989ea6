//! `jointspace calibrate`: the polar bed's rotation centre from a Hall-sensor magnet scan (simulated or logged),
//! SCARA arm geometry from measured nozzle positions or from a flatbed scan of the printed pattern (`scan`), and a
//! five-bar's geometry from its measured pattern (`fivebar`).

mod fivebar;
mod scan;

use crate::magnets::{SimulatedBed, draw_magnet_map, simulate_scan};
use crate::report;
use calibrate::scan::ScanParams;
use calibrate::scara::{self, ScaraGeometry};
use kinematics::ScaraFrame;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Find where the polar bed really turns: scan the magnets on the bed rim with the Hall sensor on the arm.
    Centre(CentreArgs),
    /// Identify SCARA arm lengths, shoulder position, joint zeros and elbow coupling from measured points.
    Scara(ScaraArgs),
    /// Write the G-code of a SCARA calibration pattern (crosses at well-chosen motor poses) to print and measure.
    ScaraPattern(PatternArgs),
    /// Identify a five-bar's base positions, link lengths and motor zeros from its measured pattern.
    Fivebar(fivebar::FitArgs),
    /// Write the G-code of a five-bar calibration pattern and the measurements file to fill in.
    FivebarPattern(fivebar::PatternArgs),
}

#[derive(Debug, clap::Args)]
pub struct CentreArgs {
    /// Run the scan on a simulated printer (KY-024 sensor, Ø3×5 mm magnets, realistic noise).
    #[arg(long, conflicts_with = "scan")]
    pub simulate: bool,
    /// Magnet detections logged by a real machine: CSV `magnet,side,arm_mm,bed_deg` (side `near` or `far`).
    /// `bed_deg` is the bed motor's reading in the machine's sign, the one Klipper's polar kinematics and
    /// `jointspace convert` use: an ideal machine has bed point (r·cos θ, r·sin θ) under the nozzle (the bed
    /// itself has turned by −θ). A log of the physical rotation must be negated first.
    #[arg(long, value_name = "CSV")]
    pub scan: Option<PathBuf>,
    /// The same ring scanned again with the nozzle raised by `--raise` mm (a detections file with its `peak_mt`
    /// column): a tilted sensor's bias grows with its height, so the two scans measure the tilt and remove it.
    #[arg(long, value_name = "CSV", requires_all = ["scan", "raise"])]
    pub scan_raised: Option<PathBuf>,
    /// How much higher the nozzle was for `--scan-raised` (mm).
    #[arg(long, value_name = "MM", requires = "scan_raised")]
    pub raise: Option<f64>,
    /// Also write the detections as such a CSV (its header comment states the sign); `-` for standard output.
    #[arg(long, value_name = "CSV")]
    pub save_scan: Option<PathBuf>,
    /// How well the sensor's axis is known to sit on the nozzle (mm, 1σ): a sensor beside the nozzle (or tilted,
    /// without `--scan-raised`) shifts dx and dy by that much and no scan can see it; it is added to the reported
    /// uncertainty.
    #[arg(long, default_value_t = 0.05, value_name = "MM")]
    pub sensor_alignment: f64,
    /// Magnets on the bed rim: the ring's size (default 16 for `--simulate`; for `--scan`, the file's `magnets`
    /// line, which scans written by jointspace carry). A magnet the scan did not find is flagged as missing.
    #[arg(long)]
    pub magnets: Option<usize>,
    /// True arm offsets `dx,dy` of the simulated machine (mm); random up to 2 mm when not given.
    #[arg(long, value_name = "DX,DY", allow_hyphen_values = true)]
    pub offset: Option<String>,
    /// Sensor noise (mT, 1σ) of the simulation.
    #[arg(long, default_value_t = 0.15)]
    pub noise: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Result file (JSON) for `convert --calibration` and `arm_zero_offset`/`arm_lateral_offset` in printer.cfg.
    #[arg(short = 'o', long = "out", default_value = "centre.json")]
    pub out: PathBuf,
    /// Picture of the magnet map with the fitted ring and residuals (PNG; an SVG is written beside it).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// Print the result as JSON (what the result file holds) instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct ScaraArgs {
    /// Measurements: the file `calibrate scara-pattern` (or `JOINTSPACE_SCARA_PATTERN`) wrote, filled in: an optional
    /// `frame,standard|xscara` line, then CSV `motor_a_deg,motor_b_deg,x_mm,y_mm` (x, y: the printer's X and Y).
    /// With `--image`, the file as written (x_mm and y_mm may stay empty): its poses are the pattern's.
    #[arg(long, value_name = "CSV", required_unless_present = "image")]
    pub measurements: Option<PathBuf>,
    /// A flatbed scan of the printed pattern (PNG or JPEG, colour or grey, 300–1200 dpi): the crosses are found on
    /// it and matched to the pattern's poses (the `--measurements` file's, else the pattern this config makes).
    #[arg(long, value_name = "PNG|JPEG")]
    pub image: Option<PathBuf>,
    /// The scan's resolution: sets its scale when no `--reference` is given (the scanner's own scale error, typically
    /// 0.1–0.5 %, then goes into both link lengths).
    #[arg(long, value_name = "DPI", requires = "image")]
    pub dpi: Option<f64>,
    /// The scan's scale from calipers: `A,B=MM`, the distance between crosses A and B (the pattern's numbers; the
    /// pattern names a good pair) measured across their strokes along Y.
    #[arg(long, value_name = "A,B=MM", requires = "image")]
    pub reference: Option<String>,
    /// Picture of the scan with each cross found, its pose number and its residual after the fit (PNG).
    #[arg(long, value_name = "PNG", requires = "image")]
    pub plot: Option<PathBuf>,
    /// Configuration whose geometry starts the fit and whose frame the file must state (default: FEKT-SCARA
    /// 100/100 mm, ECR 3).
    #[arg(short = 'c', long = "config")]
    pub config: Option<PathBuf>,
    /// How the cross centres were measured; gives the measurement noise the residuals are judged against
    /// (default: calipers, or scanner with `--image`).
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// Measurement noise (mm, 1σ per coordinate), instead of the method's (calipers 0.02, scanner 0.03,
    /// microscope 0.005).
    #[arg(long, value_name = "MM")]
    pub noise: Option<f64>,
    /// Result file (JSON).
    #[arg(short = 'o', long = "out", default_value = "scara.json")]
    pub out: PathBuf,
    /// Print the result as JSON (what the result file holds) instead of text.
    #[arg(long)]
    pub json: bool,
}

/// How the crosses were measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Calipers from two bed edges (0.02 mm).
    Calipers,
    /// A flatbed scan of the print with the bed's corner marks (0.03 mm).
    Scanner,
    /// A measuring microscope or a camera on the toolhead (0.005 mm).
    Microscope,
}

impl From<Method> for scara::MeasuringMethod {
    fn from(m: Method) -> Self {
        match m {
            Method::Calipers => scara::MeasuringMethod::Calipers,
            Method::Scanner => scara::MeasuringMethod::Scanner,
            Method::Microscope => scara::MeasuringMethod::Microscope,
        }
    }
}

#[derive(Debug, clap::Args)]
pub struct PatternArgs {
    /// Configuration of the arm (default: the FEKT-SCARA example, 100/100 mm, ECR 3, 60 mm base radius).
    #[arg(short = 'c', long = "config")]
    pub config: Option<PathBuf>,
    /// Number of crosses.
    #[arg(long, default_value_t = scara::DEFAULT_POSES)]
    pub poses: usize,
    /// Size of each cross, tip to tip (mm).
    #[arg(long, default_value_t = 6.0, value_name = "MM")]
    pub cross: f64,
    /// Output G-code.
    #[arg(short = 'o', long = "out", default_value = "scara-pattern.gcode")]
    pub out: PathBuf,
    /// The measurements file to fill in: each cross's motor angles, the frame, empty x_mm and y_mm.
    #[arg(long, default_value = "scara-measurements.csv", value_name = "CSV")]
    pub template: PathBuf,
}

pub fn run(command: Command) -> miette::Result<ExitCode> {
    match command {
        Command::Centre(args) => centre(args),
        Command::Scara(args) => scara_fit(args),
        Command::ScaraPattern(args) => pattern(args),
        Command::Fivebar(args) => fivebar::fit(args),
        Command::FivebarPattern(args) => fivebar::pattern(args),
    }
}

/// The ring's size a simulated scan has unless `--magnets` says otherwise.
const SIMULATED_MAGNETS: usize = 16;

/// Scan settings for the arguments and a ring of `magnets`.
fn scan_params(args: &CentreArgs, magnets: usize) -> ScanParams {
    ScanParams {
        magnet_count: magnets,
        sensor_alignment: args.sensor_alignment,
        ..ScanParams::default()
    }
}

/// The centre from a detections file: the ring's size from `--magnets` or the file's `magnets` line (both must
/// agree); without either, the highest magnet index found, with a warning that a missing last magnet goes unseen.
fn centre_from_file(args: &CentreArgs, path: &Path) -> miette::Result<calibrate::CentreResult> {
    crate::output::register_input(path);
    let name = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|e| miette::miette!("cannot read {name}: {e}"))?;
    let slots =
        calibrate::scan::parse_detections(&text, &name).map_err(|e| miette::miette!("{e}"))?;
    let found = slots.near.len().max(slots.far.len());
    let magnets = match (args.magnets, slots.ring) {
        (Some(given), Some(stated)) if given != stated => miette::bail!(
            "{name}: the file's ring has {stated} magnets (its `magnets` line), --magnets says {given}"
        ),
        (Some(n), _) | (None, Some(n)) => n,
        (None, None) => {
            crate::errln!(
                "{name}: warning: the ring's size is not known (no `magnets` line, no --magnets): taking {found} \
                 from the highest magnet index, so a missing last magnet cannot be flagged"
            );
            found
        }
    };
    calibrate::scan::centre_from_ring(&scan_params(args, magnets), slots)
        .map_err(|e| miette::miette!("{name}: {e}"))
}

fn centre(args: CentreArgs) -> miette::Result<ExitCode> {
    let (result, truth) = if let Some(path) = &args.scan {
        (tilt_removed(&args, centre_from_file(&args, path)?)?, None)
    } else if args.simulate {
        let params = scan_params(&args, args.magnets.unwrap_or(SIMULATED_MAGNETS));
        let (result, truth) = simulate_scan(&simulated_bed(&args)?, &params)?;
        (result, Some(truth))
    } else {
        return Err(miette::miette!("give --simulate or --scan FILE"));
    };
    // No output may replace an input; all are checked before any is written.
    let mut outputs = vec![args.out.clone()];
    outputs.extend(args.save_scan.clone());
    if let Some(png) = &args.plot {
        outputs.push(png.clone());
        outputs.push(png.with_extension("svg"));
    }
    for path in &outputs {
        crate::output::refuse_input(path).map_err(super::plain)?;
    }
    if let Some(path) = &args.save_scan {
        let text = calibrate::scan::write_detections(&result);
        crate::output::write_output(path, |w| Ok(w.write_all(text.as_bytes())?))
            .map_err(super::plain)?;
    }
    crate::output::write_output(&args.out, |w| {
        serde_json::to_writer_pretty(&mut *w, &result)?;
        Ok(w.write_all(b"\n")?)
    })
    .map_err(super::plain)?;
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&result).map_err(|e| miette::miette!("{e}"))?
        );
    } else {
        crate::out!("{}", report::centre(&result, truth));
        if !crate::output::is_stdio(&args.out) {
            crate::outln!("  result written to {}", args.out.display());
        }
    }
    if let Some(png) = &args.plot {
        draw_magnet_map(&result, png)?;
        if !args.json {
            crate::outln!("  magnet map drawn in {}", png.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `result` with the sensor's tilt removed when a raised scan is given.
fn tilt_removed(
    args: &CentreArgs,
    result: calibrate::CentreResult,
) -> miette::Result<calibrate::CentreResult> {
    let (Some(path), Some(raise)) = (&args.scan_raised, args.raise) else {
        return Ok(result);
    };
    let high = centre_from_file(args, path)?;
    calibrate::scan::with_tilt_removed(result, &high, raise)
        .map_err(|e| miette::miette!("{}: {e}", path.display()))
}

/// The simulated bed of the arguments.
fn simulated_bed(args: &CentreArgs) -> miette::Result<SimulatedBed> {
    let offset = match &args.offset {
        Some(text) => Some(parse_pair(text, "--offset")?),
        None => None,
    };
    Ok(SimulatedBed {
        magnets: args.magnets.unwrap_or(SIMULATED_MAGNETS),
        noise_mt: args.noise,
        seed: args.seed,
        offset,
    })
}

fn scara_fit(args: ScaraArgs) -> miette::Result<ExitCode> {
    if let Some(image) = &args.image {
        return scan::scara_scan(&args, image);
    }
    let (start, config_frame) = start_geometry(args.config.as_deref())?;
    let Some(path) = &args.measurements else {
        miette::bail!("give --measurements FILE or --image SCAN");
    };
    crate::output::register_input(path);
    let name = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|e| miette::miette!("cannot read {name}: {e}"))?;
    let file = scara::parse_measurement_file(&text, &name).map_err(|e| miette::miette!("{e}"))?;
    let frame = measurement_frame(file.frame, config_frame, &name)?;
    let noise = noise_of(&args, Method::Calipers)?;
    let data = &file.rows;
    let fit = scara::identify_in_frame(data, &start, frame).map_err(|e| miette::miette!("{e}"))?;
    let verdict = scara::judge(data, &fit, &start, frame, noise);
    let g = &fit.geometry;
    let json = serde_json::json!({
        "link1_length": g.link1_length, "link2_length": g.link2_length,
        "offset_x": g.offset_x, "offset_y": g.offset_y,
        "shoulder_zero_deg": g.shoulder_zero.to_degrees(), "elbow_zero_deg": g.elbow_zero.to_degrees(),
        "elbow_coupling": g.elbow_coupling, "sigma": fit.sigma.to_vec(), "rms_mm": fit.rms,
        "condition_number": fit.identifiability.condition_number,
        "frame": scara::frame_name(frame), "verdict": verdict,
    });
    crate::output::write_output(&args.out, |w| Ok(serde_json::to_writer_pretty(w, &json)?))
        .map_err(super::plain)?;
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&json).unwrap_or_default()
        );
    } else {
        let mut text = report::scara_fit(&fit, data.len());
        text += &report::fit_verdict(&verdict, data);
        if !crate::output::is_stdio(&args.out) {
            let _ = writeln!(text, "  result written to {}", args.out.display());
        }
        crate::out!("{text}");
    }
    Ok(judged(&name, &verdict))
}

/// A fit's exit status: success when it is trustworthy, else its problems on standard error and exit 1.
fn judged(name: &str, verdict: &calibrate::verdict::Verdict) -> ExitCode {
    if verdict.trustworthy {
        return ExitCode::SUCCESS;
    }
    crate::errln!(
        "error: {name}: the fit is not trustworthy: {}",
        verdict.problems.join("; ")
    );
    ExitCode::FAILURE
}

/// The measuring noise (mm): `--noise`, else the method's (`fallback` when none is given).
fn noise_of(args: &ScaraArgs, fallback: Method) -> miette::Result<f64> {
    noise_from(args.noise, args.method, fallback)
}

/// The measuring noise (mm) from `--noise` or `--method` (`fallback` when neither is given).
fn noise_from(noise: Option<f64>, method: Option<Method>, fallback: Method) -> miette::Result<f64> {
    let noise =
        noise.unwrap_or_else(|| scara::MeasuringMethod::from(method.unwrap_or(fallback)).noise());
    if !(noise.is_finite() && noise > 0.0) {
        miette::bail!("--noise must be a positive number of mm, not {noise}");
    }
    Ok(noise)
}

/// The frame the measurements count their motor angles in: the file's, which must be the machine's.
fn measurement_frame(
    stated: Option<(ScaraFrame, usize)>,
    config: Option<ScaraFrame>,
    name: &str,
) -> miette::Result<ScaraFrame> {
    match (stated, config) {
        (Some((stated, line)), Some(machine)) if stated != machine => Err(miette::miette!(
            "{name}:{line}:1: the measurements are in frame `{}`, the configured machine's frame is `{}`: \
             they were taken on another machine or the config's `frame` is wrong",
            scara::frame_name(stated),
            scara::frame_name(machine)
        )),
        (Some((stated, _)), _) => Ok(stated),
        (None, machine) => Ok(machine.unwrap_or_default()),
    }
}

fn pattern(args: PatternArgs) -> miette::Result<ExitCode> {
    let (kin, home) = pattern_machine(args.config.as_deref())?;
    for path in [&args.out, &args.template] {
        crate::output::refuse_input(path).map_err(super::plain)?;
    }
    let options = scara::PatternOptions {
        cross_size: args.cross,
        home,
        ..scara::PatternOptions::default()
    };
    let scara = kinematics::scara::Scara::of(kin.as_ref())
        .ok_or_else(|| miette::miette!("not a SCARA machine"))?;
    let pattern =
        scara::machine_pattern(scara, args.poses, &options).map_err(|e| miette::miette!("{e}"))?;
    crate::output::write_output(&args.out, |w| Ok(w.write_all(pattern.gcode.as_bytes())?))
        .map_err(super::plain)?;
    crate::output::write_output(&args.template, |w| {
        Ok(w.write_all(pattern.template.as_bytes())?)
    })
    .map_err(super::plain)?;
    crate::outln!(
        "{} crosses written to {} (condition number of the poses {:.1}), their motor angles to {}; print it, \
         measure each cross centre, fill in x_mm and y_mm and run `jointspace calibrate scara -c printer.cfg \
         --measurements {}`",
        pattern.poses.len(),
        args.out.display(),
        pattern.condition_number,
        args.template.display(),
        args.template.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// A machine's kinematics and where homing leaves it.
type HomedMachine = (Arc<dyn kinematics::Kinematics>, Option<[f64; 3]>);

/// The SCARA a pattern is made for, with where homing leaves it: the config's machine as every command builds it,
/// or the FEKT-SCARA example.
fn pattern_machine(config: Option<&Path>) -> miette::Result<HomedMachine> {
    let Some(path) = config else {
        let example = kinematics::scara::Scara::new(kinematics::ScaraParams::fekt_example())
            .map_err(|e| miette::miette!("{e}"))?;
        return Ok((Arc::new(example), None));
    };
    let machine = crate::machine::load_machine(path)?;
    if kinematics::scara::Scara::of(machine.setup.kinematics.as_ref()).is_none() {
        miette::bail!("{}: not a SCARA machine", path.display());
    }
    Ok((
        machine.setup.kinematics.clone(),
        machine.setup.home_position,
    ))
}

/// The SCARA geometry of a config (in the printer's X and Y) and its frame, or FEKT-SCARA's nominal one.
fn start_geometry(config: Option<&Path>) -> miette::Result<(ScaraGeometry, Option<ScaraFrame>)> {
    let Some(path) = config else {
        return Ok((ScaraGeometry::fekt(), None));
    };
    let machine = crate::machine::load_machine(path)?;
    match machine.config.params {
        kinematics::MachineParams::Scara(p) => Ok((ScaraGeometry::from(&p), Some(p.frame))),
        _ => Err(miette::miette!("{}: not a SCARA machine", path.display())),
    }
}

fn parse_pair(text: &str, flag: &str) -> miette::Result<[f64; 2]> {
    let values: Vec<f64> = text
        .split(',')
        .filter_map(|p| p.trim().parse::<f64>().ok())
        .filter(|v| v.is_finite())
        .collect();
    match values[..] {
        [a, b] if text.split(',').count() == 2 => Ok([a, b]),
        _ => Err(miette::miette!(
            "{flag} takes two numbers `a,b`, got `{text}`"
        )),
    }
}
