//! The five-bar's measurements file: the motor readings of each printed cross (as the pattern lists them) and the
//! cross centre measured on the bed.
//!
//! ```text
//! # comments
//! motor_left_deg,motor_right_deg,x_mm,y_mm
//! 150.123456789,30.5,,
//! ```
//! `x_mm`, `y_mm` are the printer's X and Y (the G-code's coordinates). The header names the five-bar's motors, so
//! a SCARA's file (`motor_a_deg,…`) is refused at its header.

use std::fmt::Write as _;

use super::FivebarError;
use crate::measured::{Measurement, degrees, measurement_rows, pose_rows};

/// The CSV header this reader expects (motor readings in degrees, positions in mm).
pub const CSV_HEADER: [&str; 4] = ["motor_left_deg", "motor_right_deg", "x_mm", "y_mm"];

/// A CSV error of `file` as the located parse error.
fn located_in(file: &str) -> impl Fn(crate::csv::CsvError) -> FivebarError + Copy + '_ {
    move |e| FivebarError::Parse {
        file: file.to_string(),
        line: e.line,
        column: e.column,
        message: e.message,
    }
}

/// Parse measurements: `#` starts a comment (whole line or trailing), blank lines are skipped, the header
/// `motor_left_deg,motor_right_deg,x_mm,y_mm` comes first, then one pose per line. Errors carry
/// `file:line:column` of the offending field.
pub fn parse_measurements(text: &str, file: &str) -> Result<Vec<Measurement>, FivebarError> {
    measurement_rows(text, &CSV_HEADER).map_err(located_in(file))
}

/// The poses (motor readings, rad) of a measurements file or template, `x_mm` and `y_mm` empty or not.
pub fn parse_poses(text: &str, file: &str) -> Result<Vec<(f64, f64)>, FivebarError> {
    pose_rows(text, &CSV_HEADER).map_err(located_in(file))
}

/// The measurements file to fill in: one row per pose with its motor readings, `x_mm` and `y_mm` left to the
/// person measuring the printed crosses.
pub fn measurement_template(poses: &[(f64, f64)]) -> String {
    let mut s = String::from(
        "# jointspace five-bar calibration: measure each printed cross's centre on the bed (mm, the printer's X/Y,\n\
         # the coordinates the G-code uses) and fill in x_mm and y_mm; the motor readings are the ones the machine\n\
         # commands at each cross centre (stepper_left, stepper_right).\n\
         # Then run: jointspace calibrate fivebar -c printer.cfg --measurements THIS_FILE\n",
    );
    s += &CSV_HEADER.join(",");
    s.push('\n');
    for &(a, b) in poses {
        let _ = writeln!(s, "{},{},,", degrees(a), degrees(b));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_template_reads_back_and_errors_are_located() {
        let poses = [(2.5, 0.25), (1.75, -0.5)];
        let template = measurement_template(&poses);
        let read = parse_poses(&template, "t.csv").expect("reads");
        for (r, p) in read.iter().zip(poses) {
            assert!((r.0 - p.0).abs() < 1e-11 && (r.1 - p.1).abs() < 1e-11);
        }
        // The template's header is on line 5, the first pose on line 6: its x_mm at column 30.
        let filled = template.replacen(",,", ",1.0,oops", 1);
        match parse_measurements(&filled, "t.csv") {
            Err(FivebarError::Parse {
                line,
                column,
                message,
                ..
            }) => {
                assert_eq!(line, 6);
                let row = filled.lines().nth(5).expect("row");
                assert_eq!(&row[column - 1..], "oops", "{message}");
            }
            other => panic!("{other:?}"),
        }
        let scara = "motor_a_deg,motor_b_deg,x_mm,y_mm\n1,2,3,4\n";
        assert!(matches!(
            parse_measurements(scara, "s.csv"),
            Err(FivebarError::Parse {
                line: 1,
                column: 1,
                ..
            })
        ));
    }
}
