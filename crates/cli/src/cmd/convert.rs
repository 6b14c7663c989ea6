//! `jointspace convert`: G-code for firmware without these kinematics (radius/angle or joint angles), with a
//! bounded path error; optionally corrected for a mis-centred polar bed, and verified.

use crate::{diag, input, output};
use convert::{
    AngleUnit, AxisMap, CentreCorrection, ConvertOptions, Converter, Extrusion, FeedMode,
    Segmentation, Target,
};
use kinematics::MachineParams;
use printjob::Machine;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum To {
    /// Polar firmware: X = arm radius (mm), Y = bed angle (degrees), Z, E.
    Cylindrical,
    /// Raw motor positions (SCARA: motor a, motor b in degrees; polar: bed angle, arm), Z, E.
    Joints,
    /// Cartesian XY corrected for the configured/measured centre offsets, for polar firmware that assumes an
    /// ideal machine.
    Cartesian,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Fixed {
    /// Marlin: 200 segments/s, 0.5 mm minimum.
    Marlin,
    /// Marlin POLAR: 180 segments/s, 0.5 mm minimum.
    MarlinPolar,
    /// RepRapFirmware: 100 segments/s, 0.2 mm minimum.
    Rrf,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FirmwareArg {
    /// Marlin: G90/G91 also switch E; M82/M83 switch E alone.
    Marlin,
    /// RepRapFirmware: G90/G91 switch X Y Z only.
    Rrf,
    /// Klipper: G91 makes E relative too; G90 gives E back its M82/M83 mode.
    Klipper,
}

impl From<FirmwareArg> for convert::Firmware {
    fn from(f: FirmwareArg) -> Self {
        match f {
            FirmwareArg::Marlin => convert::Firmware::Marlin,
            FirmwareArg::Rrf => convert::Firmware::Rrf,
            FirmwareArg::Klipper => convert::Firmware::Klipper,
        }
    }
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Printer configuration (Klipper's printer.cfg format).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// G-code file (`-` for standard input).
    pub file: PathBuf,
    /// Output G-code file (`-` for standard output). It never replaces the input.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// What the output's axes are.
    #[arg(long, value_enum, default_value = "cylindrical")]
    pub to: To,
    /// Largest distance (mm) between the nozzle and the intended path when the firmware interpolates linearly
    /// in motor space between the written points.
    #[arg(long, default_value_t = 0.005)]
    pub tolerance: f64,
    /// Segment like a firmware does instead (for comparison).
    #[arg(long, value_enum)]
    pub fixed: Option<Fixed>,
    /// Polar centre correction of the arm (mm): its zero lies `dx` along the arm from the bed's rotation axis,
    /// and its line passes `dy` beside the axis (`arm_zero_offset`, `arm_lateral_offset`). The part stays
    /// where the slicer put it relative to the axis; the motors are computed for the offset arm.
    #[arg(long, value_name = "DX,DY", allow_hyphen_values = true)]
    pub centre_offset: Option<String>,
    /// The centring thesis' correction (mm): the part is shifted, every point `p` written as the polar
    /// coordinates of `p − (dx, dy)`. It corrects a bed whose origin (what the slicer's coordinates refer to)
    /// lies at `(dx, dy)` from the rotation axis in the bed's frame; the arm is taken as ideal. A different
    /// model from --centre-offset: the two agree only for d = (0, 0).
    #[arg(long, value_name = "DX,DY", allow_hyphen_values = true)]
    pub centre_shift: Option<String>,
    /// Take the centre correction from a `jointspace calibrate centre` result file.
    #[arg(long, value_name = "FILE", conflicts_with = "centre_offset")]
    pub calibration: Option<PathBuf>,
    /// Output axis letters, e.g. `RT` as in the centring thesis (default `XY`).
    #[arg(long, value_name = "AB")]
    pub letters: Option<String>,
    /// Angles in radians instead of degrees.
    #[arg(long)]
    pub radians: bool,
    /// Inverse-time feed (`G93`, F = 1/minutes per segment) instead of motor-space F.
    #[arg(long)]
    pub inverse_time: bool,
    /// Absolute extrusion (`M82`) instead of relative.
    #[arg(long)]
    pub absolute_e: bool,
    /// Re-read the written file as --firmware reads it (its mode lines included), replay it through the
    /// forward kinematics and report the deviation, extrusion and time against the input.
    #[arg(long)]
    pub verify: bool,
    /// The firmware that will run the output: how --verify reads its mode lines.
    #[arg(long, value_enum, default_value = "marlin")]
    pub firmware: FirmwareArg,
    /// Print the counts (and the verification) as JSON; a failure as `{"error": …}`.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let json = args.json;
    let file = args.file.display().to_string();
    let result = convert_file(args);
    if json && let Err(e) = &result {
        super::print_json_error(&file, e.place, &e.message);
    }
    result.map_err(|e| e.report)
}

/// A failure of `convert`: the diagnostic, and for `--json` its place and message.
struct Failure {
    report: miette::Report,
    place: Option<(u64, u32)>,
    message: String,
}

impl From<miette::Report> for Failure {
    fn from(report: miette::Report) -> Self {
        Failure {
            message: report.to_string(),
            place: None,
            report,
        }
    }
}

fn convert_file(args: Args) -> Result<ExitCode, Failure> {
    let machine = crate::machine::load_machine(&args.config)?;
    let (map, options) = axis_map(&args, &machine)?;
    if args.verify && output::is_stdio(&args.file) {
        return Err(
            miette::miette!("--verify re-reads the input: give it as a file, not `-`").into(),
        );
    }
    // Written to standard output and verified: every byte also goes to a scratch copy, which is re-read.
    let copy = if args.verify && output::is_stdio(&args.out) {
        Some(
            tempfile::NamedTempFile::new()
                .map_err(|e| miette::miette!("cannot create a scratch copy to verify: {e}"))?,
        )
    } else {
        None
    };
    let (reader, name, bar) = input::open_gcode(&args.file).map_err(super::plain)?;
    let mut stats = None;
    let mut warnings = (Vec::new(), 0);
    output::write_output(&args.out, |out| {
        let mut tee;
        let out: &mut dyn std::io::Write = match &copy {
            Some(file) => {
                tee = Tee(out, std::io::BufWriter::new(file.reopen()?));
                &mut tee
            }
            None => out,
        };
        let mut converter = Converter::new(map.clone(), options.clone(), out)?;
        warnings = convert::convert_gcode(reader, &name, &mut converter)?;
        let (_, s) = converter.finish()?;
        stats = Some(s);
        Ok(())
    })
    .map_err(|e| convert_error(&args, e))?;
    bar.finish_and_clear();
    print_warnings(&name, &warnings);
    let verification = match args.verify {
        true => Some(verify_written(&args, &map, &options, &name, copy.as_ref())?),
        false => None,
    };
    let problem = verification
        .as_ref()
        .and_then(|r| verify_problem(r, &options));
    if args.json {
        let summary = JsonSummary {
            name: &name,
            stats: stats.unwrap_or_default(),
            warnings: warnings.1,
            verification: verification.as_ref(),
            problem: problem.as_deref(),
        };
        print_json(&args, &options, &summary);
    } else {
        print_text(&args, &name, stats, verification.as_ref(), &options);
    }
    if let Some(problem) = problem {
        crate::errln!("{}: verification failed: {problem}", args.out.display());
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

/// The reader's warnings on standard error, the first 20 of them.
fn print_warnings(name: &str, (warnings, total): &(Vec<gcode::Warning>, u64)) {
    for w in warnings.iter().take(20) {
        crate::errln!(
            "{name}:{}:{}: warning: {}",
            w.span.line,
            w.span.column,
            w.message
        );
    }
    if *total > 20 {
        crate::errln!("{name}: … and {} more warnings", total - 20);
    }
}

/// The written file (or the scratch copy of standard output) re-read as the firmware reads it and replayed
/// against the input.
fn verify_written(
    args: &Args,
    map: &AxisMap,
    options: &ConvertOptions,
    name: &str,
    copy: Option<&tempfile::NamedTempFile>,
) -> miette::Result<convert::VerifyReport> {
    let input = std::fs::File::open(&args.file)
        .map_err(|e| miette::miette!("cannot reopen {} to verify: {e}", args.file.display()))?;
    let commands = convert::read_commands(std::io::BufReader::new(input), name)
        .map_err(|e| miette::Report::new(diag::gcode_error(&e)))?;
    let written = match copy {
        Some(file) => file.reopen(),
        None => std::fs::File::open(&args.out),
    }
    .map_err(|e| miette::miette!("cannot read {}: {e}", args.out.display()))?;
    convert::verify(map, options, &commands, std::io::BufReader::new(written))
        .map_err(|e| miette::miette!("{}: {e}", args.out.display()))
}

/// What `--json` reports.
struct JsonSummary<'a> {
    name: &'a str,
    stats: convert::ConvertStats,
    warnings: u64,
    verification: Option<&'a convert::VerifyReport>,
    problem: Option<&'a str>,
}

fn print_json(args: &Args, options: &ConvertOptions, summary: &JsonSummary) {
    let s = &summary.stats;
    let value = serde_json::json!({
        "input": summary.name,
        "output": args.out.display().to_string(),
        "moves": s.moves,
        "segments": s.segments,
        "centre_turns": s.flips,
        "positioning_moves": s.positioning_moves,
        "limited_segments": s.limited,
        "warnings": summary.warnings,
        "firmware": options.firmware.name(),
        "verification": summary.verification.map(verify_json),
        "verification_failure": summary.problem,
    });
    let text = serde_json::to_string_pretty(&value).unwrap_or_default();
    // With `-o -` standard output is the G-code: the report goes to standard error.
    if output::is_stdio(&args.out) {
        eprintln!("{text}");
    } else {
        crate::outln!("{text}");
    }
}

/// Writes everything to both.
struct Tee<'a, B: std::io::Write>(&'a mut dyn std::io::Write, B);

impl<B: std::io::Write> std::io::Write for Tee<'_, B> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.write_all(buf)?;
        self.1.write_all(buf)?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()?;
        self.1.flush()
    }
}

/// The verification figures as JSON.
fn verify_json(r: &convert::VerifyReport) -> serde_json::Value {
    serde_json::json!({
        "max_deviation_mm": r.max_deviation,
        "worst_point": r.worst_point,
        "rms_deviation_mm": r.rms_deviation,
        "segments": r.segments,
        "unmatched_segments": r.unmatched,
        "filament_in_mm": r.extrusion_in,
        "filament_out_mm": r.extrusion_out,
        "time_in_s": r.time_in,
        "time_out_s": r.time_out,
        "centre_turn_time_s": r.flip_time,
        "motor_limited_time_s": r.limited_time,
        "over_limit_segments": r.over_limit,
        "max_limit_use": r.max_limit_use,
    })
}

fn print_text(
    args: &Args,
    name: &str,
    stats: Option<convert::ConvertStats>,
    verification: Option<&convert::VerifyReport>,
    options: &ConvertOptions,
) {
    if let Some(s) = stats.filter(|_| !output::is_stdio(&args.out)) {
        crate::outln!(
            "{} → {}: {} moves as {} segments ({} centre turns, {} positioning moves)",
            name,
            args.out.display(),
            s.moves,
            s.segments,
            s.flips,
            s.positioning_moves
        );
    }
    if let Some(r) = verification {
        let text = format!(
            "verification ({} reading {}): {}",
            options.firmware.name(),
            if output::is_stdio(&args.out) {
                "what went to standard output".to_string()
            } else {
                args.out.display().to_string()
            },
            crate::report::verify(r)
        );
        // With `-o -` standard output is the G-code: the report goes to standard error.
        if output::is_stdio(&args.out) {
            crate::errln!("{text}");
        } else {
            crate::outln!("{text}");
        }
    }
}

/// What makes a verification fail: the path off by more than the tolerance, segments on no input path,
/// extrusion different from the input's, or time off by more than 1 %.
pub fn verify_problem(r: &convert::VerifyReport, options: &ConvertOptions) -> Option<String> {
    let tolerance = match options.segmentation {
        Segmentation::Adaptive { tolerance } => Some(tolerance),
        Segmentation::Fixed { .. } => None,
    };
    if let Some(t) = tolerance.filter(|&t| r.max_deviation > t * 1.01) {
        return Some(format!(
            "the path deviates by {:.4} mm, more than the tolerance {t} mm",
            r.max_deviation
        ));
    }
    if r.unmatched > 0 {
        return Some(format!(
            "{} written segments follow no input move",
            r.unmatched
        ));
    }
    let e_error = (r.extrusion_out - r.extrusion_in).abs() / r.extrusion_in.abs().max(1.0);
    if e_error.is_nan() || e_error > 1e-6 {
        return Some(format!(
            "extrusion {:.5} mm differs from the input's {:.5} mm",
            r.extrusion_out, r.extrusion_in
        ));
    }
    if r.over_limit > 0 {
        return Some(format!(
            "{} written lines drive a motor faster than its limit (up to {:.3}× the limit)",
            r.over_limit, r.max_limit_use
        ));
    }
    time_problem(r)
}

/// The written moves (turns in place at the polar centre, which have no Cartesian counterpart, aside) must take
/// the input's Cartesian time within 1 %, or longer only in lines that run a motor at its speed limit: no faster
/// than the input asks, and every second beyond it explained by a limit.
fn time_problem(r: &convert::VerifyReport) -> Option<String> {
    let moves = r.time_out - r.flip_time;
    let slack = 0.01 * r.time_in.max(1.0);
    let too_fast = moves < r.time_in - slack;
    let unexplained = moves - r.limited_time > r.time_in + slack;
    if too_fast || unexplained || moves.is_nan() {
        return Some(format!(
            "the written moves take {moves:.1} s ({:.1} s of them at a motor limit; besides {:.1} s turning at \
             the centre) against the input's {:.1} s",
            r.limited_time, r.flip_time, r.time_in
        ));
    }
    None
}

fn options(args: &Args) -> miette::Result<ConvertOptions> {
    if !(args.tolerance > 0.0 && args.tolerance.is_finite()) {
        return Err(miette::miette!(
            "--tolerance must be a positive number of mm"
        ));
    }
    let mut options = ConvertOptions {
        target: if args.to == To::Joints {
            Target::Joints
        } else {
            Target::Cylindrical
        },
        segmentation: match args.fixed {
            None => Segmentation::Adaptive {
                tolerance: args.tolerance,
            },
            Some(Fixed::Marlin) => Segmentation::MARLIN,
            Some(Fixed::MarlinPolar) => Segmentation::MARLIN_POLAR,
            Some(Fixed::Rrf) => Segmentation::RRF,
        },
        angle_unit: if args.radians {
            AngleUnit::Radians
        } else {
            AngleUnit::Degrees
        },
        feed: if args.inverse_time {
            FeedMode::InverseTime
        } else {
            FeedMode::MotorSpace
        },
        extrusion: if args.absolute_e {
            Extrusion::Absolute
        } else {
            Extrusion::Relative
        },
        firmware: args.firmware.into(),
        ..ConvertOptions::default()
    };
    if let Some(text) = &args.centre_shift {
        let [dx, dy] = pair_of_numbers("--centre-shift", text)?;
        options.translate = [-dx, -dy];
    }
    if let Some(letters) = &args.letters {
        let chars: Vec<char> = letters.chars().collect();
        match chars[..] {
            [a, b] if a.is_ascii_alphabetic() && b.is_ascii_alphabetic() && a != b => {
                options.axis_letters = Some([a.to_ascii_uppercase(), b.to_ascii_uppercase()]);
            }
            _ => {
                return Err(miette::miette!(
                    "--letters takes two different letters, e.g. RT"
                ));
            }
        }
    }
    Ok(options)
}

/// The output axes and the options: the configured machine's motors (the job every conversion shares), or a
/// corrected polar machine's.
fn axis_map(args: &Args, machine: &Machine) -> miette::Result<(AxisMap, ConvertOptions)> {
    let fail = |e: convert::ConvertError| miette::miette!("{e}");
    let correction = centre_correction(args)?;
    let polar = matches!(machine.config.params, MachineParams::Polar(_));
    if !polar && (correction.is_some() || args.to == To::Cartesian) {
        return Err(miette::miette!(
            "centre correction and --to cartesian need a polar machine"
        ));
    }
    let (map, options) = crate::machine::convert_job(machine, options(args)?).map_err(fail)?;
    let corrected = match (&machine.config.params, correction, args.to) {
        (MachineParams::Polar(p), Some(c), To::Cartesian) => c.cartesian_map(p).map_err(fail)?,
        (MachineParams::Polar(p), Some(c), _) => c.motor_map(p, options.target).map_err(fail)?,
        (MachineParams::Polar(p), None, To::Cartesian) => {
            let c = CentreCorrection {
                arm_zero_offset: p.arm_zero_offset,
                arm_lateral_offset: p.arm_lateral_offset,
            };
            c.cartesian_map(p).map_err(fail)?
        }
        _ => map,
    };
    Ok((corrected, options))
}

/// `dx,dy`: two finite numbers (mm).
fn pair_of_numbers(flag: &str, text: &str) -> miette::Result<[f64; 2]> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let numbers: Vec<f64> = parts
        .iter()
        .filter_map(|p| p.parse::<f64>().ok())
        .filter(|v| v.is_finite())
        .collect();
    match numbers[..] {
        [dx, dy] if parts.len() == 2 => Ok([dx, dy]),
        _ => Err(miette::miette!(
            "{flag} takes two numbers `dx,dy` in mm, got `{text}`"
        )),
    }
}

fn centre_correction(args: &Args) -> miette::Result<Option<CentreCorrection>> {
    if let Some(text) = &args.centre_offset {
        let [dx, dy] = pair_of_numbers("--centre-offset", text)?;
        return Ok(Some(CentreCorrection {
            arm_zero_offset: dx,
            arm_lateral_offset: dy,
        }));
    }
    if let Some(path) = &args.calibration {
        crate::output::register_input(path);
        let result = calibrate::scan::CentreResult::read_json(path)
            .map_err(|e| miette::miette!("{}: {e}", path.display()))?;
        return Ok(Some(CentreCorrection {
            arm_zero_offset: result.arm_zero_offset,
            arm_lateral_offset: result.arm_lateral_offset,
        }));
    }
    Ok(None)
}

/// A conversion error: on a G-code line when it has one.
fn convert_error(args: &Args, e: anyhow::Error) -> Failure {
    let (place, message) = match e.downcast_ref::<convert::ConvertError>() {
        Some(c) => (c.place().map(|s| (s.line, s.column)), c.message()),
        None => (None, format!("{e:#}")),
    };
    Failure {
        report: convert_report(args, e),
        place,
        message,
    }
}
fn convert_report(args: &Args, e: anyhow::Error) -> miette::Report {
    use convert::ConvertError as E;
    match e.downcast::<E>() {
        Ok(E::Gcode(e)) => miette::Report::new(diag::gcode_error(&e)),
        Ok(other) => match other.place() {
            Some(span) => miette::Report::new(diag::at_gcode_line(
                &args.file,
                span,
                other.message(),
                "here".into(),
            )),
            None => miette::miette!("{}: {other}", args.file.display()),
        },
        Err(e) => super::plain(e),
    }
}
