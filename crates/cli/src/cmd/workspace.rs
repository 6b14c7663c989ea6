//! `jointspace workspace`: where the machine reaches, and how fine its motion is across the bed.

use kinematics::workspace::{self, ResolutionKind, WorkspaceMap};
use plot::workspace::{Outline, ResolutionLayer, WorkspaceData};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Printer configuration (Klipper's printer.cfg format).
    #[arg(short = 'c', long = "config")]
    pub config: PathBuf,
    /// Folder for the pictures (PNG and SVG).
    #[arg(short = 'o', long = "out", default_value = "workspace")]
    pub out: PathBuf,
    /// Grid cell size (mm).
    #[arg(long, default_value_t = 2.0)]
    pub cell: f64,
    /// Print the numbers as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The numbers a builder compares machines by.
#[derive(Debug, Clone, Serialize)]
pub struct WorkspaceFigures {
    pub machine: String,
    pub reachable_area_mm2: f64,
    /// Per motor and for the machine's worst direction: (name, best mm/step, where, worst mm/step, where).
    pub resolution: Vec<(String, f64, [f64; 2], f64, [f64; 2])>,
    pub pictures: Vec<String>,
}

pub fn run(args: Args) -> miette::Result<ExitCode> {
    let (machine, _) = super::run::load_machine(&args.config)?;
    if !(args.cell > 0.05 && args.cell.is_finite()) {
        return Err(miette::miette!("--cell must be at least 0.05 mm"));
    }
    let figures = map_and_draw(&machine.params, args.cell, &args.out, "workspace")?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&figures).map_err(|e| miette::miette!("{e}"))?);
    } else {
        print!("{}", render(&figures));
    }
    Ok(ExitCode::SUCCESS)
}

/// Map the workspace, write the pictures into `dir` as `<stem>-*.png/svg`, return the numbers.
pub fn map_and_draw(
    params: &kinematics::MachineParams,
    cell_mm: f64,
    dir: &Path,
    stem: &str,
) -> miette::Result<WorkspaceFigures> {
    let map = workspace::map_machine(params, cell_mm, 0.0).map_err(|e| miette::miette!("{e}"))?;
    std::fs::create_dir_all(dir).map_err(|e| miette::miette!("cannot create {}: {e}", dir.display()))?;
    let written = plot::workspace::write_workspace_maps(&workspace_data(&map), dir, stem)
        .map_err(|e| miette::miette!("{e}"))?;
    let mut resolution = Vec::new();
    for (name, range) in map.motor_names.iter().zip(map.summary.per_motor.iter()) {
        if let Some(r) = range {
            resolution.push((name.clone(), r.min.value, r.min.at, r.max.value, r.max.at));
        }
    }
    if let Some(r) = &map.summary.machine {
        resolution.push(("worst direction".into(), r.min.value, r.min.at, r.max.value, r.max.at));
    }
    Ok(WorkspaceFigures {
        machine: map.machine.to_string(),
        reachable_area_mm2: map.summary.reachable_area_mm2,
        resolution,
        pictures: written.iter().map(|p| p.display().to_string()).collect(),
    })
}

pub fn render(f: &WorkspaceFigures) -> String {
    let mut out = format!("{} workspace: {:.0} mm² reachable\n", f.machine, f.reachable_area_mm2);
    out += "  mm of nozzle travel per step   finest   at            coarsest   at\n";
    for (name, best, best_at, worst, worst_at) in &f.resolution {
        out += &format!(
            "  {:<28} {:>8.4}   ({:>5.0},{:>5.0})   {:>8.4}   ({:>5.0},{:>5.0})\n",
            name, best, best_at[0], best_at[1], worst, worst_at[0], worst_at[1]
        );
    }
    out += &format!("  {} pictures written (reach, per-motor and worst-direction maps)\n", f.pictures.len());
    out
}

/// The plain data the plot crate draws.
fn workspace_data(map: &WorkspaceMap) -> WorkspaceData {
    let (labels, reach) = map.reach_categories();
    let mut resolutions: Vec<ResolutionLayer> = map
        .motor_names
        .iter()
        .enumerate()
        .map(|(i, name)| ResolutionLayer {
            name: name.clone(),
            title: format!("{}: {name} resolution (mm of nozzle travel per step)", map.machine),
            values: map.resolution_values(ResolutionKind::Motor(i)),
        })
        .collect();
    resolutions.push(ResolutionLayer {
        name: "machine".into(),
        title: format!("{}: worst-direction resolution (mm per step)", map.machine),
        values: map.resolution_values(ResolutionKind::Machine),
    });
    let outline = match map.outline {
        workspace::Outline::Circle { centre, radius } => Outline::Circle { centre, radius },
        workspace::Outline::Rectangle { min, max } => Outline::Rectangle { min, max },
    };
    let s = &map.summary;
    let mut notes = vec![format!(
        "reachable area {:.0} mm² ({} of {} cells of {} mm)",
        s.reachable_area_mm2,
        s.reachable_cells,
        map.cells.len(),
        map.cell_mm
    )];
    if let Some(m) = s.machine {
        notes.push(format!(
            "worst-direction resolution {:.4} mm/step at ({:.0}, {:.0}) … {:.4} at ({:.0}, {:.0})",
            m.min.value, m.min.at[0], m.min.at[1], m.max.value, m.max.at[0], m.max.at[1]
        ));
    }
    WorkspaceData {
        machine: map.machine.to_string(),
        x_min: map.bounds.x_min,
        y_min: map.bounds.y_min,
        cell_mm: map.cell_mm,
        nx: map.nx,
        ny: map.ny,
        outline,
        reach_labels: labels.into_iter().map(String::from).collect(),
        reach,
        resolutions,
        notes,
    }
}
