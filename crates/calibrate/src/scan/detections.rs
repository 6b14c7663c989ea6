//! The detections file: one magnet centre per line (`magnet,side,arm_mm,bed_deg`), what a printer's scan
//! logs and `jointspace calibrate centre --scan` reads.

use super::error::ScanError;
use super::result::{CentreResult, Detection};
use serde::{Deserialize, Serialize};

/// The header of a detections file.
pub const DETECTIONS_HEADER: [&str; 5] = ["magnet", "side", "arm_mm", "bed_deg", "peak_mt"];
/// The header of a detections file without peak heights (files written before they were kept).
const HEADER_WITHOUT_PEAKS: [&str; 4] = ["magnet", "side", "arm_mm", "bed_deg"];

/// Parse a detections file: `#` comments, blank lines skipped, an optional `magnets,N` line (the ring's size), a
/// header `magnet,side,arm_mm,bed_deg,peak_mt` (`peak_mt` may be left out), then
/// one detection per line (`magnet` a 0-based index, `side` `near` or `far`, the arm reading in mm and the
/// unwrapped bed motor reading in degrees at the magnet's centre, in the kinematics' sign: see the module
/// documentation). Returns (near, far) slots per magnet index.
/// Errors carry `file:line:column`.
pub fn parse_detections(text: &str, file: &str) -> Result<DetectionSlots, ScanError> {
    let located = |e: crate::csv::CsvError| ScanError::Parse {
        file: file.to_string(),
        line: e.line,
        column: e.column,
        message: e.message,
    };
    let (ring_line, table) = crate::csv::leading_setting(text, "magnets").map_err(located)?;
    let ring = match ring_line {
        Some(setting) => Some(ring_size(&setting).map_err(located)?),
        None => None,
    };
    let header: &[&str] = if header_width(&table) == HEADER_WITHOUT_PEAKS.len() {
        &HEADER_WITHOUT_PEAKS
    } else {
        &DETECTIONS_HEADER
    };
    let mut rows: Vec<(usize, bool, Detection)> = Vec::new();
    for row in crate::csv::data_rows(&table, header).map_err(located)? {
        let magnet_text = row.fields[0].1;
        let magnet: usize = magnet_text
            .parse()
            .ok()
            .filter(|&m: &usize| m < 10_000)
            .ok_or_else(|| {
                located(row.error_at(0, format!("`{magnet_text}` is not a magnet index")))
            })?;
        let side = row.fields[1].1;
        let far = match side.to_ascii_lowercase().as_str() {
            "near" => false,
            "far" => true,
            _ => {
                return Err(located(
                    row.error_at(1, format!("side `{side}` should be `near` or `far`")),
                ));
            }
        };
        if let Some(n) = ring.filter(|&n| magnet >= n) {
            return Err(located(row.error_at(
                0,
                format!("magnet {magnet} on a ring of {n} magnets (the file's `magnets` line): indices run 0 to {}", n - 1),
            )));
        }
        let r = row.number(2).map_err(located)?;
        let theta = row.number(3).map_err(located)?;
        // The peak field in mT (0: not known, as in files without the column).
        let peak = match row.fields.get(4) {
            Some(_) => row.number(4).map_err(located)? * 1e-3,
            None => 0.0,
        };
        if rows.iter().any(|r| r.0 == magnet && r.1 == far) {
            return Err(located(
                row.error_at(0, format!("magnet {magnet} {side} given twice")),
            ));
        }
        rows.push((
            magnet,
            far,
            Detection {
                r,
                theta: theta.to_radians(),
                peak,
            },
        ));
    }
    let n = rows.iter().map(|r| r.0 + 1).max().unwrap_or(0);
    let mut slots = DetectionSlots {
        near: vec![None; n],
        far: vec![None; n],
        ring,
    };
    for (k, far, d) in rows {
        if far {
            slots.far[k] = Some(d);
        } else {
            slots.near[k] = Some(d);
        }
    }
    Ok(slots)
}

/// How many fields the first line with content has (the header's width).
fn header_width(table: &str) -> usize {
    table
        .lines()
        .map(|raw| raw.split('#').next().unwrap_or(""))
        .find(|c| !c.trim().is_empty())
        .map_or(0, |c| c.split(',').count())
}

/// The ring's size of a `magnets,N` line.
fn ring_size(setting: &crate::csv::Setting) -> Result<usize, crate::csv::CsvError> {
    setting
        .value
        .parse::<usize>()
        .ok()
        .filter(|n| (3..10_000).contains(n))
        .ok_or_else(|| crate::csv::CsvError {
            line: setting.line,
            column: setting.column,
            message: format!(
                "`{}` is not a ring's number of magnets (3 or more)",
                setting.value
            ),
        })
}

/// The header comment of a detections file written by [`write_detections`]: what each column means and which
/// sign the bed angle has.
pub const DETECTIONS_PREAMBLE: &str = "\
# jointspace centre scan: each magnet's centre as the Hall sensor peaked it, on the near and the far side
# of the bed's rotation centre.
# arm_mm: the arm's reading (mm from its zero). bed_deg: the bed motor's reading (degrees, unwrapped) in the
# machine's sign, as Klipper's polar kinematics and `jointspace convert` use it: an ideal machine has bed
# point (r*cos(bed), r*sin(bed)) under the nozzle. The bed itself has turned by -bed_deg.
# magnets: the ring's size; a magnet without a line was not found. peak_mt: the peak field (mT), so weak, sunk or
# different magnets are flagged from the file as on the printer (0: not measured).
";

/// A detections file (see [`parse_detections`]) of a scan's result: the preamble, the header, and one line per
/// detection with every digit of the readings.
pub fn write_detections(result: &CentreResult) -> String {
    let mut text = String::from(DETECTIONS_PREAMBLE);
    text += &format!("magnets,{}\n", result.magnet_count);
    text += &DETECTIONS_HEADER.join(",");
    text.push('\n');
    for m in &result.magnets {
        for (side, d) in [("near", m.near), ("far", m.far)] {
            if let Some(d) = d {
                let peak = d.peak * 1e3;
                text += &format!(
                    "{},{side},{},{},{peak}\n",
                    m.index,
                    d.r,
                    d.theta.to_degrees()
                );
            }
        }
    }
    text
}

/// Detections per magnet index, near and far side.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct DetectionSlots {
    pub near: Vec<Option<Detection>>,
    pub far: Vec<Option<Detection>>,
    /// The ring's size the file states (its `magnets,N` line), if it does.
    #[serde(default)]
    pub ring: Option<usize>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detections_file_parses_and_reports_positions() {
        let text =
            "# scan\nmagnet,side,arm_mm,bed_deg\n0,near,98.5,1.0\n0, far ,-101.5,181.0 # ok\n";
        let slots = parse_detections(text, "d.csv").expect("parse");
        assert_eq!(slots.near.len(), 1);
        assert!(slots.far[0].is_some_and(|d| d.r == -101.5));
        let bad = "magnet,side,arm_mm,bed_deg\n0,middle,1,2\n";
        assert_eq!(
            parse_detections(bad, "d.csv"),
            Err(ScanError::Parse {
                file: "d.csv".into(),
                line: 2,
                column: 3,
                message: "side `middle` should be `near` or `far`".into()
            })
        );
        let dup = "magnet,side,arm_mm,bed_deg\n0,near,1,2\n0,near,1,2\n";
        assert!(matches!(
            parse_detections(dup, "d.csv"),
            Err(ScanError::Parse { line: 3, .. })
        ));
        let nan = "magnet,side,arm_mm,bed_deg\n0,near,NaN,2\n";
        assert!(matches!(
            parse_detections(nan, "d.csv"),
            Err(ScanError::Parse { column: 8, .. })
        ));
    }
}
