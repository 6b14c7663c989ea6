//! `jointspace demo`: the whole pipeline on the bundled example machines and jointspace's own test prints,
//! with a report and pictures in the output folder.

use crate::cmd::{run, workspace};
use crate::output::write_atomically;
use crate::testprint::TestPrint;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder for the report, pictures, machines and prints.
    #[arg(short = 'o', long = "out", default_value = "demo-out")]
    pub out: PathBuf,
}

/// A bundled machine: its printer.cfg and where its test print goes.
struct Example {
    name: &'static str,
    config: &'static str,
    print_centre: [f64; 2],
    print_size: f64,
}

const EXAMPLES: [Example; 3] = [
    Example {
        name: "polar",
        config: include_str!("../../../../examples/machines/polar.cfg"),
        print_centre: [0.0, 0.0],
        print_size: 40.0,
    },
    Example {
        name: "scara",
        config: include_str!("../../../../examples/machines/scara.cfg"),
        print_centre: [0.0, 130.0],
        print_size: 25.0,
    },
    Example {
        name: "cartesian",
        config: include_str!("../../../../examples/machines/cartesian.cfg"),
        print_centre: [110.0, 110.0],
        print_size: 40.0,
    },
];

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let out = &args.out;
    std::fs::create_dir_all(out).map_err(|e| miette::miette!("cannot create {}: {e}", out.display()))?;
    let mut report = String::from("jointspace demo: bundled machines and test prints\n\n");
    for example in &EXAMPLES {
        let section = demo_machine(example, out)?;
        print!("{section}");
        report += &section;
    }
    write_atomically(&out.join("report.txt"), |w| Ok(w.write_all(report.as_bytes())?))
        .map_err(super::plain)?;
    println!("report and pictures in {}", out.display());
    Ok(ExitCode::SUCCESS)
}

/// Plan and step the machine's test print, map its workspace; the report section.
fn demo_machine(example: &Example, out: &Path) -> miette::Result<String> {
    let dir = out.join(example.name);
    let config_path = dir.join("printer.cfg");
    let print_path = dir.join("test-print.gcode");
    let gcode = TestPrint::new(example.print_centre, example.print_size).gcode();
    write_atomically(&config_path, |w| Ok(w.write_all(example.config.as_bytes())?)).map_err(super::plain)?;
    write_atomically(&print_path, |w| Ok(w.write_all(gcode.as_bytes())?)).map_err(super::plain)?;

    let (machine, setup) = run::load_machine(&config_path)?;
    let mut section = format!("== {} printer ({})\n", example.name, config_path.display());
    let options = run::RunOptions { clock_hz: 16e6, ..Default::default() };
    let summary = run::execute(
        &machine,
        setup,
        gcode.as_bytes(),
        &print_path.display().to_string(),
        &config_path.display().to_string(),
        &options,
    )
    .map_err(|e| match e {
        run::ExecuteError::Pipeline(e) => run::pipeline_error(&print_path, e),
        run::ExecuteError::Other(r) => r,
    })?;
    section += &run::render(&summary);
    let figures = workspace::map_and_draw(&machine.params, 2.0, &dir, "workspace")?;
    section += &workspace::render(&figures);
    let _ = writeln!(section);
    Ok(section)
}
