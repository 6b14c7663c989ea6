//! `jointspace demo`: the whole pipeline on the bundled example machines and jointspace's own test prints,
//! with a report and pictures in the output folder.

use crate::machine::load_machine;
use crate::magnets::{SimulatedBed, draw_magnet_map, simulate_scan};
use crate::output::write_atomically;
use crate::{diag, maps, report};
use sim::testprint::TestPrint;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder for the report, pictures, machines and prints.
    #[arg(short = 'o', long = "out", default_value = "demo-out")]
    pub out: PathBuf,
}

/// A bundled machine: its printer.cfg, where its test print goes, and what to convert it for.
struct Example {
    name: &'static str,
    config: &'static str,
    print_centre: [f64; 2],
    print_size: f64,
    convert_to: Option<convert::Target>,
}

const EXAMPLES: [Example; 4] = [
    Example {
        name: "polar",
        config: include_str!("../../../../examples/machines/polar.cfg"),
        print_centre: [0.0, 0.0],
        print_size: 40.0,
        convert_to: Some(convert::Target::Cylindrical),
    },
    Example {
        name: "scara",
        config: include_str!("../../../../examples/machines/scara.cfg"),
        print_centre: [0.0, 130.0],
        print_size: 25.0,
        convert_to: Some(convert::Target::Joints),
    },
    Example {
        name: "fivebar",
        config: include_str!("../../../../examples/machines/fivebar.cfg"),
        print_centre: [0.0, 20.0],
        print_size: 40.0,
        convert_to: Some(convert::Target::Joints),
    },
    Example {
        name: "cartesian",
        config: include_str!("../../../../examples/machines/cartesian.cfg"),
        print_centre: [110.0, 110.0],
        print_size: 40.0,
        convert_to: None,
    },
];

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let out = &args.out;
    std::fs::create_dir_all(out)
        .map_err(|e| miette::miette!("cannot create {}: {e}", out.display()))?;
    let mut report = String::from("jointspace demo: bundled machines and test prints\n\n");
    for example in &EXAMPLES {
        let section = demo_machine(example, out)?;
        crate::out!("{section}");
        report += &section;
    }
    for section in [
        demo_calibration(out)?,
        demo_scan_calibration(out)?,
        demo_simulation(out)?,
    ] {
        crate::out!("{section}");
        report += &section;
    }
    write_atomically(&out.join("report.txt"), |w| {
        Ok(w.write_all(report.as_bytes())?)
    })
    .map_err(super::plain)?;
    crate::outln!("report and pictures in {}", out.display());
    Ok(ExitCode::SUCCESS)
}

/// Plan and step the machine's test print, map its workspace; the report section.
fn demo_machine(example: &Example, out: &Path) -> miette::Result<String> {
    let dir = out.join(example.name);
    let config_path = dir.join("printer.cfg");
    let print_path = dir.join("test-print.gcode");
    let gcode = TestPrint::new(example.print_centre, example.print_size).gcode();
    write_atomically(
        &config_path,
        |w| Ok(w.write_all(example.config.as_bytes())?),
    )
    .map_err(super::plain)?;
    write_atomically(&print_path, |w| Ok(w.write_all(gcode.as_bytes())?)).map_err(super::plain)?;

    let machine = load_machine(&config_path)?;
    let mut section = format!("== {} printer ({})\n", example.name, config_path.display());
    let summary = printjob::run(
        &machine,
        gcode.as_bytes(),
        &print_path.display().to_string(),
        &printjob::RunOptions::default(),
        crate::interrupt::requested,
    )
    .map_err(|e| match e {
        printjob::RunError::Plan(e) => diag::pipeline_error(&print_path, e),
        other => miette::miette!("{}: {other}", print_path.display()),
    })?;
    section += &report::run_summary(&summary);
    let figures = maps::map_and_draw(&machine.config.params, 2.0, &dir, "workspace")?;
    section += &report::workspace(&figures);
    section += &demo_view(&machine, &gcode, &print_path, &dir)?;
    if let Some(target) = example.convert_to {
        section += &demo_conversion(&machine, &gcode, &print_path, &dir, target)?;
    }
    let _ = writeln!(section);
    Ok(section)
}

/// The test print as `jointspace view` shows it: one HTML page beside it.
fn demo_view(
    machine: &printjob::Machine,
    gcode: &str,
    print_path: &Path,
    dir: &Path,
) -> miette::Result<String> {
    let name = print_path.display().to_string();
    let open =
        || -> std::io::Result<Box<dyn std::io::BufRead + '_>> { Ok(Box::new(gcode.as_bytes())) };
    let options = printjob::PlanOptions::default();
    let (estimate, page) = view::plan(machine, options, &open, &name, view::Budget::DEFAULT)
        .map_err(|e| miette::miette!("{name}: {e}"))?;
    let out = dir.join("test-print.html");
    let meta = view::PageMeta {
        file: name,
        config: machine.source.clone(),
    };
    write_atomically(&out, |w| {
        view::write_page(w, &estimate, &page, &meta)
            .map_err(|e| outfile::write_error(&out, e).into())
    })
    .map_err(|e: anyhow::Error| super::plain(e))?;
    let kept: usize = page.collected.layers.iter().map(|l| l.segments.len()).sum();
    Ok(format!(
        "view of the test print (open in a browser): {} ({kept} segments, {} layers)\n",
        out.display(),
        page.collected.layers.len()
    ))
}

/// Convert the test print for firmware without the machine's kinematics (the job `convert` assembles), and verify
/// the result.
fn demo_conversion(
    machine: &printjob::Machine,
    gcode: &str,
    print_path: &Path,
    dir: &Path,
    target: convert::Target,
) -> miette::Result<String> {
    let options = convert::ConvertOptions {
        target,
        ..Default::default()
    };
    let (map, options) =
        crate::machine::convert_job(machine, options).map_err(|e| miette::miette!("{e}"))?;
    let name = print_path.display().to_string();
    let mut converter = convert::Converter::new(map.clone(), options.clone(), Vec::new())
        .map_err(|e| miette::miette!("{e}"))?;
    convert::convert_gcode(gcode.as_bytes(), &name, &mut converter)
        .map_err(|e| miette::miette!("{e}"))?;
    let (written, stats) = converter.finish().map_err(|e| miette::miette!("{e}"))?;
    let written = String::from_utf8(written).map_err(|e| miette::miette!("{e}"))?;
    let out_path = dir.join("test-print-converted.gcode");
    write_atomically(&out_path, |w| Ok(w.write_all(written.as_bytes())?)).map_err(super::plain)?;
    let commands =
        convert::read_commands(gcode.as_bytes(), &name).map_err(|e| miette::miette!("{e}"))?;
    // Verified from the file as written, as the firmware reads it.
    let file = std::fs::File::open(&out_path)
        .map_err(|e| miette::miette!("cannot read {}: {e}", out_path.display()))?;
    let report = convert::verify(&map, &options, &commands, std::io::BufReader::new(file))
        .map_err(|e| miette::miette!("{e}"))?;
    Ok(format!(
        "conversion for firmware without {} kinematics ({}): {} moves → {} segments\n  {}\n",
        machine.config.kinematics.name(),
        out_path.display(),
        stats.moves,
        stats.segments,
        report::verify(&report)
    ))
}

/// A simulated Hall-sensor scan of a polar bed with a mis-centred arm: the fitted centre against the truth.
fn demo_calibration(out: &Path) -> miette::Result<String> {
    let bed = SimulatedBed {
        magnets: 16,
        noise_mt: 0.15,
        seed: 7,
        offset: Some([0.8, -0.45]),
    };
    let params = calibrate::scan::ScanParams {
        magnet_count: bed.magnets,
        sensor_alignment: 0.05,
        ..Default::default()
    };
    let dir = out.join("calibration");
    std::fs::create_dir_all(&dir).map_err(|e| miette::miette!("{e}"))?;
    let (result, truth) = simulate_scan(&bed, &params)?;
    result
        .write_json(&dir.join("centre.json"))
        .map_err(|e| miette::miette!("{e}"))?;
    draw_magnet_map(&result, &dir.join("magnet-map.png"))?;
    Ok(format!(
        "== centre calibration (simulated KY-024 scan of 16 magnets; {})\n{}\n",
        out.join("calibration").display(),
        report::centre(&result, Some(truth))
    ))
}

/// SCARA calibration from a scan: the FEKT example's pattern printed by an arm built 0.4 mm and −0.3 mm off in its
/// links, with ECR 3.05 and the elbow 0.3° off, scanned at 300 dpi turned 2.5°; the crosses found, matched and
/// fitted; the recovered geometry against the arm as built.
fn demo_scan_calibration(out: &Path) -> miette::Result<String> {
    use calibrate::scara::scan_image::{ScanImage, ScanScale, calibrate_scan};
    let believed_params = kinematics::ScaraParams::fekt_example();
    let believed = kinematics::scara::Scara::new(believed_params.clone())
        .map_err(|e| miette::miette!("{e}"))?;
    let actual_params = kinematics::ScaraParams {
        link1_length: believed_params.link1_length + 0.4,
        link2_length: believed_params.link2_length - 0.3,
        elbow_coupling: 1.0 / 3.05,
        ecr: Some(3.05),
        elbow_zero: believed_params.elbow_zero + 0.3f64.to_radians(),
        ..believed_params.clone()
    };
    let actual =
        kinematics::scara::Scara::new(actual_params.clone()).map_err(|e| miette::miette!("{e}"))?;
    let pattern = calibrate::scara::machine_pattern(
        &believed,
        calibrate::scara::DEFAULT_POSES,
        &calibrate::scara::PatternOptions::default(),
    )
    .map_err(|e| miette::miette!("{e}"))?;
    let settings = sim::scan::ScanSettings {
        dpi: 300.0,
        rotation_deg: 2.5,
        noise: 3.0,
        seed: 11,
    };
    let scan = sim::scan::render_scan(&believed, &actual, &pattern, &settings);
    let image = ScanImage::from_luma8(scan.width, scan.height, scan.luma)
        .map_err(|e| miette::miette!("{e}"))?;
    let start = calibrate::scara::ScaraGeometry::from(&believed_params);
    let frame = believed_params.frame;
    let cal = calibrate_scan(
        &image,
        "synthetic scan",
        &pattern.poses,
        &start,
        frame,
        &ScanScale::Dpi(300.0),
    )
    .map_err(|e| miette::miette!("{e}"))?;
    let dir = out.join("calibration");
    std::fs::create_dir_all(&dir).map_err(|e| miette::miette!("{e}"))?;
    let picture = dir.join("scan-found.png");
    crate::scan_picture::draw_scan(&image, &cal, &pattern.poses, frame, &picture)?;
    let g = &cal.fit.fit.geometry;
    let truth = calibrate::scara::ScaraGeometry::from(&actual_params);
    Ok(format!(
        "== SCARA calibration from a scan (synthetic 300 dpi scan, turned 2.5°, of the FEKT example's pattern \
         printed by an arm built with links +0.4/−0.3 mm, ECR 3.05, elbow zero +0.3°; {})\n  {} crosses found, {} \
         matched; recovered minus built: link1 {:+.4} mm, link2 {:+.4} mm, ECR {:+.5}, elbow zero {:+.4}°; residual \
         RMS {:.4} mm\n\n",
        picture.display(),
        cal.detection.crosses.len(),
        cal.fit.measurements.len(),
        g.link1_length - truth.link1_length,
        g.link2_length - truth.link2_length,
        1.0 / g.elbow_coupling - 1.0 / truth.elbow_coupling,
        (g.elbow_zero - truth.elbow_zero).to_degrees(),
        cal.fit.fit.rms
    ))
}

/// The virtual printer: what an assembly error does to a print, and the print after calibration and correction.
fn demo_simulation(out: &Path) -> miette::Result<String> {
    let mut section =
        String::from("== simulation: assembly errors, before and after calibration\n");
    let polar_dir = out.join("simulation-polar");
    let polar =
        sim::scenario::polar_lateral_offset_demo(&polar_dir).map_err(|e| miette::miette!("{e}"))?;
    section += &format!(
        "-- polar printer whose arm passes 1 mm beside the bed centre ({})\n",
        polar_dir.display()
    );
    section += &polar.text();
    let scara_dir = out.join("simulation-scara");
    let scara =
        sim::scenario::scara_coupling_demo(&scara_dir).map_err(|e| miette::miette!("{e}"))?;
    section += &format!(
        "-- SCARA built with ECR 3.2 and a 0.5 mm longer arm, configured as ECR 3 ({})\n",
        scara_dir.display()
    );
    section += &scara.text();
    let fivebar_dir = out.join("simulation-fivebar");
    let fivebar = sim::scenario::fivebar_demo(&fivebar_dir).map_err(|e| miette::miette!("{e}"))?;
    section += &format!(
        "-- five-bar built with its left base 0.3 mm further left, the right proximal link 0.4 mm long and the left \
         zero 0.5° off, configured as the example; calibrated from its printed pattern ({})\n",
        fivebar_dir.display()
    );
    section += &fivebar.text();
    section += &format!(
        "before/after pictures: {} and {}\n\n",
        polar_dir.join("overlay.png").display(),
        polar_dir.join("overlay-after.png").display()
    );
    Ok(section)
}
