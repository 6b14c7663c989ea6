//! Results as text, for the commands that print them and for the demo's report.

use crate::maps::WorkspaceFigures;
use calibrate::scan::CentreResult;
use calibrate::scara::{self, Identification, Measurement, Verdict};
use printjob::RunSummary;
use std::fmt::Write as _;

/// A run's summary as text: print time, moves, steps and peak rates per motor, warnings.
pub fn run_summary(r: &RunSummary) -> String {
    let mut out = format!("{} on {} ({})\n", r.file, r.config, r.kinematics);
    let total = r.print_time_s.max(0.0);
    out += &format!(
        "  print time   {:.1} s ({}h{:02}m{:02}s)\n",
        total,
        (total / 3600.0) as u64,
        ((total % 3600.0) / 60.0) as u64,
        (total % 60.0) as u64
    );
    out += &format!(
        "  moves        {} toolhead, {} extruder\n",
        r.toolhead_moves, r.extruder_moves
    );
    out += &format!(
        "  steps        {} in all, computed in {:.3} s\n",
        r.total_steps, r.wall_time_s
    );
    out += "  motor             steps        net   peak rate (1 ms)   min interval\n";
    for m in &r.motors {
        let interval = m
            .min_interval_ticks
            .map_or("-".to_string(), |t| format!("{t} ticks"));
        out += &format!(
            "  {:<14} {:>9} {:>10} {:>12.0} steps/s   {:>12}\n",
            m.name, m.steps, m.net_steps, m.peak_rate_1ms, interval
        );
        if let Some(limit) = m.over_max_step_rate {
            out += &format!(
                "    warning: {} exceeds its max_step_rate of {limit:.0} steps/s\n",
                m.name
            );
        }
        if m.filtered_pairs > 0 {
            out += &format!(
                "    {} step pairs removed by the step+dir+step filter\n",
                m.filtered_pairs
            );
        }
    }
    if r.slowed_moves > 0 {
        out += &format!(
            "  {} moves slowed below 25% of their requested speed by machine limits\n",
            r.slowed_moves
        );
    }
    for w in r.warnings.iter().take(20) {
        out += &format!(
            "  {}:{}:{}: warning: {}\n",
            r.file, w.line, w.column, w.message
        );
    }
    if r.warnings.len() > 20 {
        out += &format!(
            "  … and {} more warnings (see --json)\n",
            r.warnings.len() - 20
        );
    }
    out
}

/// A workspace map's numbers: reachable area, and the smallest and largest nozzle travel per step of each motor
/// and of the worst direction, with what each means.
pub fn workspace(f: &WorkspaceFigures) -> String {
    let mut out = format!(
        "{} workspace: {:.0} mm² reachable\n",
        f.machine, f.reachable_area_mm2
    );
    out +=
        "  nozzle travel per motor step (mm)           smallest   at              largest   at\n";
    for r in &f.resolution {
        let name = if r.name == "worst direction" {
            "both motors, worst direction".to_string()
        } else {
            format!("{}, steepest direction", r.name)
        };
        out += &format!(
            "  {name:<42} {:>8.4}   ({:>5.0},{:>5.0})   {:>8.4}   ({:>5.0},{:>5.0})\n",
            r.smallest,
            r.smallest_at[0],
            r.smallest_at[1],
            r.largest,
            r.largest_at[0],
            r.largest_at[1]
        );
    }
    out += "  (a motor's smallest travel is where it steps for the least nozzle motion, where it turns fastest;\n   \
            the machine positions finest where the worst direction's travel is smallest)\n";
    for c in &f.singular_curves {
        out += &format!(
            "  singular curve drawn: {} ({:.0} mm of it in the area)\n",
            c.label, c.length_mm
        );
    }
    out += &format!(
        "  {} pictures written (reach, per-motor and worst-direction maps)\n",
        f.pictures.len()
    );
    out
}

/// A centre scan's result: the offsets with their uncertainty, what the scan saw, and against the truth when
/// simulated.
pub fn centre(r: &CentreResult, truth: Option<[f64; 2]>) -> String {
    let mut out = format!(
        "rotation centre: arm_zero_offset {:+.4} mm (±{:.4}), arm_lateral_offset {:+.4} mm (±{:.4})\n",
        r.arm_zero_offset,
        r.sigma_arm_zero_offset,
        r.arm_lateral_offset,
        r.sigma_arm_lateral_offset
    );
    out += &format!(
        "  {} of {} magnets seen, {} pairs used; scan takes {:.0} s on the machine ({} sensor readings)\n",
        r.detected, r.magnet_count, r.pairs_used, r.scan_time, r.sensor_reads
    );
    out += &format!(
        "  uncertainty: scan ±{:.4} / ±{:.4} mm, sensor alignment to the nozzle ±{:.4} mm (not observable by \
         a scan; --sensor-alignment)\n",
        r.sigma_scan[0], r.sigma_scan[1], r.sensor_alignment
    );
    if let Some(t) = &r.tilt {
        out += &format!(
            "  sensor tilt removed: the scan {:.2} mm higher moved the offsets by {:+.4} / {:+.4} mm per mm; \
             bias {:+.4} / {:+.4} mm at {:.2} mm from the magnets' centres (a tilt of about {:.1}°)\n",
            t.raise,
            t.bias[0] / t.distance,
            t.bias[1] / t.distance,
            t.bias[0],
            t.bias[1],
            t.distance,
            t.tilt_deg
        );
    }
    for flag in &r.flags {
        out += &format!("  warning: {flag}\n");
    }
    if let Some([dx, dy]) = truth {
        let error = (r.arm_zero_offset - dx).hypot(r.arm_lateral_offset - dy);
        out += &format!(
            "  simulated truth: {dx:+.4}, {dy:+.4} mm; error of the estimate {error:.4} mm\n"
        );
    }
    out
}

/// The verification figures in one line.
pub fn verify(r: &convert::VerifyReport) -> String {
    let mut text = format!(
        "max deviation {:.4} mm at ({:.2}, {:.2}), RMS {:.5} mm over {} segments; filament {:.5} → {:.5} mm; \
         time {:.1} s Cartesian → {:.1} s on the machine from the written feeds ({:.1} s turning at the centre)",
        r.max_deviation,
        r.worst_point[0],
        r.worst_point[1],
        r.rms_deviation,
        r.segments,
        r.extrusion_in,
        r.extrusion_out,
        r.time_in,
        r.time_out,
        r.flip_time
    );
    if r.limited_time > 0.0 || r.max_limit_use > 0.0 {
        let longer = r.time_out - r.flip_time - r.time_in;
        let _ = write!(
            text,
            "; motor limits: {longer:+.1} s ({:+.1} %) against the Cartesian time, {:.1} s in lines at a limit, \
             fastest line at {:.1} % of its limit",
            100.0 * longer / r.time_in.max(f64::MIN_POSITIVE),
            r.limited_time,
            100.0 * r.max_limit_use
        );
    }
    text
}

/// A geometry fit's verdict (SCARA, five-bar): the residuals against the stated noise, and when the fit cannot be
/// trusted, why, the poses that fit worst and the likely causes.
pub fn fit_verdict(v: &Verdict, data: &[Measurement]) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "  residuals against {} mm of measurement noise: chi-square {:.1} over {} degrees of freedom (at most {:.1}, \
         an RMS of {:.4} mm)",
        v.noise, v.chi_square, v.dof, v.chi_square_limit, v.rms_limit
    );
    if v.trustworthy {
        let _ = writeln!(
            text,
            "  verdict: the fit agrees with the measurements within their noise"
        );
        return text;
    }
    let _ = writeln!(
        text,
        "  verdict: NOT TRUSTWORTHY, do not apply these values"
    );
    for problem in &v.problems {
        let _ = writeln!(text, "    - {problem}");
    }
    let _ = writeln!(text, "  worst poses:");
    for w in &v.worst {
        let place = match data.get(w.index) {
            Some(m) if m.line > 0 => format!("line {}", m.line),
            _ => format!("measurement {}", w.index + 1),
        };
        let _ = writeln!(
            text,
            "    {place}: {:.4} mm from the fitted model",
            w.distance
        );
    }
    if !v.causes.is_empty() {
        let _ = writeln!(text, "  likely causes:");
        for cause in &v.causes {
            let _ = writeln!(text, "    - {cause}");
        }
    }
    text
}

/// An identified SCARA geometry: each parameter with its uncertainty, the poses' condition, and which parameter
/// combinations the poses cannot tell apart.
pub fn scara_fit(fit: &Identification, measurements: usize) -> String {
    let g = &fit.geometry;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "identified from {} measurements (residual RMS {:.4} mm):",
        measurements, fit.rms
    );
    let values = [
        g.link1_length,
        g.link2_length,
        g.offset_x,
        g.offset_y,
        g.shoulder_zero.to_degrees(),
        g.elbow_zero.to_degrees(),
        g.elbow_coupling,
    ];
    let sigmas = [
        fit.sigma[0],
        fit.sigma[1],
        fit.sigma[2],
        fit.sigma[3],
        fit.sigma[4].to_degrees(),
        fit.sigma[5].to_degrees(),
        fit.sigma[6],
    ];
    for ((name, v), s) in scara::PARAM_NAMES.iter().zip(values).zip(sigmas) {
        let _ = writeln!(text, "  {name:<16} {v:>12.5} ± {s:.5}");
    }
    let _ = writeln!(
        text,
        "  (ecr = 1/elbow_coupling = {:.5}; zeros in degrees)",
        1.0 / g.elbow_coupling
    );
    let id = &fit.identifiability;
    let _ = writeln!(
        text,
        "  condition number of the poses: {:.1}",
        id.condition_number
    );
    for combination in &id.unidentifiable {
        let _ = writeln!(
            text,
            "  not identifiable from these poses: {}",
            combination_text(combination)
        );
    }
    text
}

/// What a check found the print asks of the machine: each limited motor's travel and the closest the nozzle comes to
/// each special pose, with the lines (nothing for a print that plans no move).
pub fn envelope(e: &printjob::Envelope) -> String {
    let mut out = String::new();
    if !e.motors.is_empty() {
        out += &format!(
            "  motor travel (the planned moves sampled every {} mm):\n",
            printjob::SAMPLE_MM
        );
    }
    for m in &e.motors {
        let (min, max) = (
            in_config_units(m.unit, m.min),
            in_config_units(m.unit, m.max),
        );
        let unit = config_unit(m.unit);
        out += &format!(
            "    {:<16} {min:>9.3} {unit} (line {}) … {max:.3} {unit} (line {})\n",
            m.name, m.min_line, m.max_line
        );
    }
    for c in &e.closest {
        let verdict = if c.value < c.margin {
            "inside the margin: only where a move starts or ends at rest"
        } else {
            "clear of the margin"
        };
        out += &format!(
            "  closest to {}: |sin| {:.3} at ({:.1}, {:.1}), line {} (margin {}; {verdict})\n",
            c.label, c.value, c.at[0], c.at[1], c.line, c.margin
        );
    }
    out
}

/// Degrees for a turning motor, as printer.cfg states its limits; mm otherwise.
fn in_config_units(unit: kinematics::MotorUnit, value: f64) -> f64 {
    match unit {
        kinematics::MotorUnit::Rad => value.to_degrees(),
        kinematics::MotorUnit::Mm => value,
    }
}

fn config_unit(unit: kinematics::MotorUnit) -> &'static str {
    match unit {
        kinematics::MotorUnit::Rad => "°",
        kinematics::MotorUnit::Mm => "mm",
    }
}

/// [`envelope`]'s motor travel for `--json` (degrees for turning motors, as printer.cfg states their limits).
pub fn motor_travel_json(e: &printjob::Envelope) -> serde_json::Value {
    e.motors
        .iter()
        .map(|m| {
            serde_json::json!({
                "motor": m.name,
                "unit": if m.unit == kinematics::MotorUnit::Rad { "deg" } else { "mm" },
                "min": in_config_units(m.unit, m.min),
                "min_line": m.min_line,
                "max": in_config_units(m.unit, m.max),
                "max_line": m.max_line,
            })
        })
        .collect()
}

/// [`envelope`]'s closest approaches for `--json`.
pub fn closest_json(e: &printjob::Envelope) -> serde_json::Value {
    e.closest
        .iter()
        .map(|c| {
            serde_json::json!({
                "pose": c.label,
                "sin": c.value,
                "margin": c.margin,
                "line": c.line,
                "at": c.at,
            })
        })
        .collect()
}

/// An identified five-bar: each key with its uncertainty, the poses' condition in the bed frame, and what
/// measurements fixing no frame would leave undetermined.
pub fn fivebar_fit(fit: &calibrate::fivebar::Identification, measurements: usize) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "identified from {} measurements (residual RMS {:.4} mm):",
        measurements, fit.rms
    );
    let values = fit.geometry.to_array();
    for (k, name) in calibrate::fivebar::PARAM_NAMES.iter().enumerate() {
        let unit = if k % 5 == 4 {
            180.0 / std::f64::consts::PI
        } else {
            1.0
        };
        let _ = writeln!(
            text,
            "  {name:<22} {:>12.5} ± {:.5}",
            values[k] * unit,
            fit.sigma[k] * unit
        );
    }
    let _ = writeln!(text, "  (mm; zeros in degrees)");
    let id = &fit.identifiability;
    let _ = writeln!(
        text,
        "  condition number of the poses (measured in the bed frame): {:.1}",
        id.condition_number
    );
    for combination in &fit.free_frame.unidentifiable {
        let _ = writeln!(
            text,
            "  measured relative to each other only (no bed frame), not identified: {}",
            combination_text(combination)
        );
    }
    text
}

/// A parameter combination the data cannot determine, as `+0.71·a −0.71·b`.
fn combination_text<N: std::fmt::Display>(combination: &[(N, f64)]) -> String {
    let terms: Vec<String> = combination
        .iter()
        .map(|(n, w)| format!("{w:+.2}·{n}"))
        .collect();
    terms.join(" ")
}
