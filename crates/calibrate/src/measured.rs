//! What a geometry fit reads (SCARA, five-bar): measured poses, each the two arm motors' commanded readings and the
//! printed point measured on the bed, and the rows of a measurements file that lists them.

use serde::{Deserialize, Serialize};

use crate::csv::CsvError;

/// One measured pose: the two arm motors' commanded readings (rad, in the machine's motor order: a SCARA's
/// `stepper_a`, `stepper_b`; a five-bar's `stepper_left`, `stepper_right`) and the nozzle position measured on
/// the bed (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    pub motor_a: f64,
    pub motor_b: f64,
    pub x: f64,
    pub y: f64,
    /// Source line (1-based), 0 when not from a file.
    pub line: usize,
}

/// Largest motor reading a row may give (degrees): a thousand turns.
const MOST_DEGREES: f64 = 360_000.0;
/// Largest coordinate a row may give (mm): 100 m, beyond any printer's bed, so squares and sums stay finite.
const MOST_MM: f64 = 100_000.0;

/// The rows of a measurements table under `header` (two motor angles in degrees, then x and y in mm).
pub(crate) fn measurement_rows(
    table: &str,
    header: &[&str; 4],
) -> Result<Vec<Measurement>, CsvError> {
    let mut rows = Vec::new();
    for row in crate::csv::data_rows(table, header)? {
        rows.push(Measurement {
            motor_a: row
                .bounded(0, MOST_DEGREES, "a thousand turns")?
                .to_radians(),
            motor_b: row
                .bounded(1, MOST_DEGREES, "a thousand turns")?
                .to_radians(),
            x: row.bounded(2, MOST_MM, "any printer's bed, in mm")?,
            y: row.bounded(3, MOST_MM, "any printer's bed, in mm")?,
            line: row.line,
        });
    }
    Ok(rows)
}

/// The motor angles (rad) of a table under `header` whose x and y may still be empty (a template as written).
pub(crate) fn pose_rows(table: &str, header: &[&str; 4]) -> Result<Vec<(f64, f64)>, CsvError> {
    let mut poses = Vec::new();
    for row in crate::csv::data_rows(table, header)? {
        poses.push((
            row.bounded(0, MOST_DEGREES, "a thousand turns")?
                .to_radians(),
            row.bounded(1, MOST_DEGREES, "a thousand turns")?
                .to_radians(),
        ));
    }
    Ok(poses)
}

/// Degrees with enough decimals that the angle read back is the listed one within 1e-11 rad.
pub(crate) fn degrees(v: f64) -> String {
    let s = format!("{:.10}", v.to_degrees());
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0.0000000000".to_string()
    } else {
        s
    }
}
