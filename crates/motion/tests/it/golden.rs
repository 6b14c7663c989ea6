//! Plan every golden case's `input.gcode` with the case's `printer.cfg` and compare every trapq row with the
//! one Klipper recorded (`moves.csv.gz`, written by Python's `repr`, which reads back to the same double): same rows
//! in the same order, every value the same double, bit for bit.

use flate2::read::GzDecoder;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use trapq::csv::{CsvSink, parse_row};
use trapq::{Queue, TrapezoidMove};

fn golden_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/golden");
    if dir.is_dir() {
        Some(dir)
    } else {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            dir.display()
        );
        eprintln!(
            "SKIPPED: {} is absent (the golden reference data lives in ../shared)",
            dir.display()
        );
        None
    }
}

fn read_golden_moves(case: &Path) -> Vec<(Queue, TrapezoidMove)> {
    let file = std::fs::File::open(case.join("moves.csv.gz")).expect("moves.csv.gz opens");
    BufReader::new(GzDecoder::new(file))
        .lines()
        .skip(1)
        .map(|line| {
            let line = line.expect("reads");
            parse_row(&line).unwrap_or_else(|e| panic!("bad golden row {line}: {e:?}"))
        })
        .collect()
}

/// Plan a case through the same path the CLI uses and return the rows.
fn plan_case(case: &Path) -> Vec<(Queue, TrapezoidMove)> {
    let machine = config::MachineConfig::load(case.join("printer.cfg")).expect("printer.cfg loads");
    let mut setup = machine::MachineSetup::from_config(&machine).expect("machine builds");
    setup.planner.klipper_batch_flush = true;
    if machine.kinematics == config::KinematicsKind::Scara {
        // The golden SCARA cases come from the FEKT-SCARA Kalico fork: no Z speed limits, and its first move
        // starts one kin_flush_delay after the start buffer (golden/README.md).
        setup.planner.behave_as(motion::Host::KalicoFekt);
    }
    let mut rows = Vec::new();
    let sink = |queue: Queue, mv: &TrapezoidMove| rows.push((queue, *mv));
    let input = std::fs::File::open(case.join("input.gcode")).expect("input opens");
    let (_sink, _summary) =
        printjob::plan_gcode(&setup, BufReader::new(input), "input.gcode", sink).expect("plans");
    rows
}

/// The same double (a zero's sign aside: Klipper's CSV has no `-0.0` of its own to compare).
fn same(a: f64, b: f64) -> bool {
    a == b
}

fn compare_case(case: &Path) -> Result<usize, String> {
    let expected = read_golden_moves(case);
    let got = plan_case(case);
    let is_scara = case
        .file_name()
        .is_some_and(|n| n.to_string_lossy().starts_with("scara"));
    for (i, ((eq, e), (gq, g))) in expected.iter().zip(&got).enumerate() {
        let fields = |m: &TrapezoidMove| {
            [
                m.print_time,
                m.accel_t,
                m.cruise_t,
                m.decel_t,
                m.start_pos[0],
                m.start_pos[1],
                m.start_pos[2],
                m.axes_r[0],
                m.axes_r[1],
                m.axes_r[2],
                m.start_v,
                m.cruise_v,
                m.accel,
            ]
        };
        let (ef, gf) = (fields(e), fields(g));
        let mismatch = eq != gq
            || ef.iter().zip(&gf).enumerate().any(|(k, (a, b))| {
                // The fork writes its pressure-advance value and flag in the extruder's y/z direction columns.
                let skip = is_scara && *eq == Queue::Extruder && (k == 8 || k == 9);
                !skip && !same(*a, *b)
            });
        if mismatch {
            let mut text = Vec::new();
            let mut sink = CsvSink::new(&mut text);
            trapq::MoveSink::append(&mut sink, *eq, e).expect("the sink takes the move");
            trapq::MoveSink::append(&mut sink, *gq, g).expect("the sink takes the move");
            drop(sink);
            return Err(format!(
                "{}: row {} differs (expected, then ours):\n{}",
                case.display(),
                i + 1,
                String::from_utf8_lossy(&text)
            ));
        }
    }
    if expected.len() != got.len() {
        return Err(format!(
            "{}: {} golden rows, {} planned",
            case.display(),
            expected.len(),
            got.len()
        ));
    }
    Ok(expected.len())
}

#[test]
fn every_golden_case_plans_exactly_like_klipper() {
    let Some(dir) = golden_dir() else { return };
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("golden dir lists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("moves.csv.gz").is_file())
        .collect();
    cases.sort();
    assert!(
        cases.len() >= 8,
        "expected the 8 golden cases, found {}",
        cases.len()
    );
    let mut failures = Vec::new();
    for case in &cases {
        match compare_case(case) {
            Ok(rows) => eprintln!("{}: {rows} rows match", case.display()),
            Err(e) => failures.push(e),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
