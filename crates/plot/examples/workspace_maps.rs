//! Writes the workspace pictures of the golden polar and SCARA machines into a directory:
//! `cargo run -p plot --example workspace_maps -- <dir> [cell_mm]`.

#[path = "../tests/it/glue.rs"]
mod glue;
#[path = "../tests/it/maps.rs"]
#[allow(dead_code, unused_imports)]
mod maps;
#[path = "../tests/it/wellformed.rs"]
#[allow(dead_code)]
mod wellformed;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(args.next().ok_or("usage: workspace_maps <dir> [cell_mm]")?);
    let cell: f64 = args.next().map(|s| s.parse()).transpose()?.unwrap_or(2.0);
    std::fs::create_dir_all(&dir)?;
    for (stem, params) in [("polar", maps::polar()), ("scara", maps::scara())] {
        let map = kinematics::workspace::map_machine(&params, cell, 1.0)?;
        for path in plot::workspace::write_workspace_maps(&glue::workspace_data(&map), &dir, stem)?
        {
            println!("{}", path.display());
        }
    }
    Ok(())
}
