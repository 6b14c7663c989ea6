//! Shared helpers: locating `../shared`, building scenario machines.

use std::path::PathBuf;

/// The corpus circle print, or `None` (with a message) when `../shared` is absent.
pub fn corpus_circle() -> Option<Vec<u8>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/corpus/cura-4.10_circle-centred.gcode");
    match std::fs::read(&path) {
        Ok(bytes) => Some(bytes),
        Err(_) => {
            assert!(
                std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
                "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
                path.display()
            );
            println!(
                "SKIP corpus: {} not found; using a generated circle print",
                path.display()
            );
            None
        }
    }
}

/// Believed and actual config from the polar demo config with `[printer]` keys added to the actual one
/// and an optional `[sim]` section.
pub fn polar_pair(
    printer_keys: &str,
    sim_section: &str,
) -> (config::MachineConfig, config::MachineConfig) {
    let polar = sim::scenario::polar_config();
    let (believed, _) = sim::scenario::scenario_configs(&polar, "").expect("configs");
    let text = sim::scenario::with_keys(&polar, "sim", sim_section);
    let text = sim::scenario::with_keys(&text, "printer", printer_keys);
    let actual = config::MachineConfig::from_str(&text, "actual.cfg").expect("actual config");
    (believed, actual)
}

/// A generated polar print of concentric and off-centre circles plus a square.
pub fn polar_print() -> String {
    sim::scenario::test_print_gcode(
        &sim::scenario::POLAR_CIRCLES,
        &sim::scenario::POLAR_SQUARES,
        2,
        None,
    )
}
