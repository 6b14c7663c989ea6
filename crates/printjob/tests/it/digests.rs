//! Step files and planned moves of the bench and the golden cases are byte-stable across refactors: each run's
//! files hashed (FNV-1a, 64 bits) and compared with digests pinned when they were last checked against the hosts
//! (the golden cases' step files against Klipper's own, `stepgen`'s golden test). A change that moves a single step
//! by one tick fails here; a deliberate change re-pins them (`JOINTSPACE_PRINT_DIGESTS=1` prints the new table).

use std::path::{Path, PathBuf};

use printjob::{Machine, RunOptions};

/// `(case, file, digest)` for every file a run writes: one step file per motor and the moves CSV.
const PINNED: &[(&str, &str, u64)] = &[
    (
        "cartesian-bambu-square-ring",
        "extruder.txt",
        0xd19e17af09754128,
    ),
    (
        "cartesian-bambu-square-ring",
        "moves.csv",
        0x12f06e2bf62a9553,
    ),
    (
        "cartesian-bambu-square-ring",
        "stepper_x.txt",
        0x094537e9b54f898b,
    ),
    (
        "cartesian-bambu-square-ring",
        "stepper_y.txt",
        0x46901167d0057b53,
    ),
    (
        "cartesian-bambu-square-ring",
        "stepper_z.txt",
        0xe96ccd6dc02b79a0,
    ),
    (
        "cartesian-prusa-minicube-arcs",
        "extruder.txt",
        0x66e0e917556bd8c0,
    ),
    (
        "cartesian-prusa-minicube-arcs",
        "moves.csv",
        0x5ef5a2a5a7e1d2a5,
    ),
    (
        "cartesian-prusa-minicube-arcs",
        "stepper_x.txt",
        0x2278668d275a4cb8,
    ),
    (
        "cartesian-prusa-minicube-arcs",
        "stepper_y.txt",
        0x7c443902254b6f87,
    ),
    (
        "cartesian-prusa-minicube-arcs",
        "stepper_z.txt",
        0x76fb58c78404c4ea,
    ),
    ("polar-cura-circle", "extruder.txt", 0x6cca2e7ec2eda8b5),
    ("polar-cura-circle", "moves.csv", 0x6c5a8eebd2275b48),
    ("polar-cura-circle", "stepper_arm.txt", 0x64444c8fc764d68d),
    ("polar-cura-circle", "stepper_bed.txt", 0x1867271a2501a4bd),
    ("polar-cura-circle", "stepper_z.txt", 0xc1e5e5b601f40b35),
    ("polar-kisslicer-cube", "extruder.txt", 0x68704dfc0b7e089d),
    ("polar-kisslicer-cube", "moves.csv", 0x066b7fc8cdd2c478),
    (
        "polar-kisslicer-cube",
        "stepper_arm.txt",
        0x545866de5a4ec549,
    ),
    (
        "polar-kisslicer-cube",
        "stepper_bed.txt",
        0x7fdfd570f4aa15a1,
    ),
    ("polar-kisslicer-cube", "stepper_z.txt", 0xcec7f0a263437556),
    (
        "polar-prusa-minicube-arcs",
        "extruder.txt",
        0x7b5720b4327a8b77,
    ),
    ("polar-prusa-minicube-arcs", "moves.csv", 0x432b6c20a170d073),
    (
        "polar-prusa-minicube-arcs",
        "stepper_arm.txt",
        0xfa39f63784fed477,
    ),
    (
        "polar-prusa-minicube-arcs",
        "stepper_bed.txt",
        0xa8df0d0d9762d507,
    ),
    (
        "polar-prusa-minicube-arcs",
        "stepper_z.txt",
        0x0d796db8b61afa21,
    ),
    ("polar-synthetic", "extruder.txt", 0x5a3956d6b7656196),
    ("polar-synthetic", "moves.csv", 0x9d88d18b488e7a29),
    ("polar-synthetic", "stepper_arm.txt", 0x35c395ffdc38f64f),
    ("polar-synthetic", "stepper_bed.txt", 0xdbcb6b4d34e90e2a),
    ("polar-synthetic", "stepper_z.txt", 0x1be315b212db1ad0),
    ("scara-fekt-cura-hex", "extruder.txt", 0x21ee2463cc88cf83),
    ("scara-fekt-cura-hex", "moves.csv", 0x5fc4558b4d19da5f),
    ("scara-fekt-cura-hex", "stepper_a.txt", 0x44aad7b5ca04dbad),
    ("scara-fekt-cura-hex", "stepper_b.txt", 0xc34bfd0cca8e36c5),
    ("scara-fekt-cura-hex", "stepper_z.txt", 0x1fd7928e340cdc76),
    ("scara-fekt-synthetic", "extruder.txt", 0x7e0d0c9f0b4318bc),
    ("scara-fekt-synthetic", "moves.csv", 0xd44a64d9eefddea6),
    ("scara-fekt-synthetic", "stepper_a.txt", 0x843c60f274485030),
    ("scara-fekt-synthetic", "stepper_b.txt", 0xa99e695dc126e3a5),
    ("scara-fekt-synthetic", "stepper_z.txt", 0x5403e57305cc9026),
    ("polar-bench", "extruder.txt", 0x51c0204d4d0d9f5d),
    ("polar-bench", "moves.csv", 0x65832b5d08b04705),
    ("polar-bench", "stepper_arm.txt", 0xea31d93bc5f5386e),
    ("polar-bench", "stepper_bed.txt", 0xcc862d04b7f13142),
    ("polar-bench", "stepper_z.txt", 0x34c08520f9f6a075),
];

fn shared() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared");
    if dir.join("golden").is_dir() && dir.join("bench").is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
        "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
        dir.display()
    );
    eprintln!("SKIPPED: {} is absent", dir.display());
    None
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The cases: every golden case (its printer.cfg and input) and the polar bench.
fn cases(shared: &Path) -> Vec<(String, PathBuf, PathBuf)> {
    let mut cases: Vec<(String, PathBuf, PathBuf)> = entries(&shared.join("golden"))
        .into_iter()
        .filter(|p| p.join("printer.cfg").is_file())
        .map(|p| (name_of(&p), p.join("printer.cfg"), p.join("input.gcode")))
        .collect();
    let bench = shared.join("bench");
    cases.push((
        "polar-bench".into(),
        bench.join("polar-bench.cfg"),
        bench.join("polar-bench20.gcode"),
    ));
    cases
}

/// Every file one run of `case` writes, with its digest, in name order.
fn run_digests(case: &str, cfg: &Path, gcode: &Path) -> Vec<(String, String, u64)> {
    let dir = tempfile::tempdir().expect("temp dir");
    let (mut machine, _) = Machine::load(cfg).expect("machine loads");
    // The golden polar cases follow Klipper's rule, whose bed steps at up to 533,000 steps/s near the centre:
    // these runs pin bytes, so their audit assumes boards with 100 ns step pulses (TMC drivers), which can.
    for stepper in &mut machine.config.steppers {
        stepper.step_pulse_duration = Some(1e-7);
    }
    let options = RunOptions {
        steps: Some(dir.path().join("steps")),
        moves: Some(dir.path().join("steps/moves.csv")),
        ..RunOptions::default()
    };
    let input = std::io::BufReader::new(std::fs::File::open(gcode).expect("gcode opens"));
    printjob::run(&machine, input, "input.gcode", &options, || false).expect("runs");
    entries(&dir.path().join("steps"))
        .iter()
        .map(|f| {
            let digest = fnv1a(&std::fs::read(f).expect("reads"));
            (case.to_string(), name_of(f), digest)
        })
        .collect()
}

/// The entries of `dir`, in name order.
fn entries(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("the folder lists")
        .flatten()
        .map(|e| e.path())
        .collect();
    found.sort();
    found
}

fn name_of(path: &Path) -> String {
    path.file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned()
}

#[test]
fn the_bench_and_golden_runs_write_the_pinned_bytes() {
    let Some(shared) = shared() else { return };
    let cases = cases(&shared);
    assert!(cases.len() >= 9, "only {} cases", cases.len());
    let found: Vec<(String, String, u64)> = cases
        .iter()
        .flat_map(|(case, cfg, gcode)| run_digests(case, cfg, gcode))
        .collect();
    if std::env::var_os("JOINTSPACE_PRINT_DIGESTS").is_some() {
        for (case, file, digest) in &found {
            println!("    (\"{case}\", \"{file}\", {digest:#018x}),");
        }
    }
    let pinned: Vec<(String, String, u64)> = PINNED
        .iter()
        .map(|(c, f, d)| (c.to_string(), f.to_string(), *d))
        .collect();
    assert_eq!(found, pinned, "step files or moves changed");
}

#[test]
fn the_digest_sees_a_one_byte_change() {
    assert_ne!(fnv1a(b"1000,1\n"), fnv1a(b"1001,1\n"));
    assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
}
