//! Plan a G-code file on a printer.cfg and write the planned moves as golden-format CSV to stdout.
//! Usage: `cargo run -p motion --example plan_csv -- printer.cfg input.gcode [--kalico]`

use std::io::BufReader;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(cfg), Some(input)) = (args.get(1), args.get(2)) else {
        return Err("usage: plan_csv printer.cfg input.gcode [--kalico]".into());
    };
    let machine = config::MachineConfig::load(cfg)?;
    let mut setup = machine::MachineSetup::from_config(&machine)?;
    setup.planner.klipper_batch_flush = !args.iter().any(|a| a == "--lookahead-only");
    if args.iter().any(|a| a == "--kalico") {
        setup.planner.apply_z_limits = false;
        setup.planner.initial_step_gen_time = setup.planner.buffer_time_start;
    }
    let sink = trapq::csv::CsvSink::new(std::io::stdout().lock());
    let file = std::fs::File::open(input)?;
    let (sink, _) = printjob::plan_gcode(&setup, BufReader::new(file), input, sink)?;
    let _stdout = sink.finish()?;
    Ok(())
}
