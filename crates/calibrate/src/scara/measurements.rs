//! The measurements file: the motor angles of each printed cross (as the pattern lists them) and the cross centre
//! measured on the bed, with the frame the motor angles count in (the machine's `frame`), so the fit reads the
//! positions as the machine places them.
//!
//! ```text
//! # comments
//! frame,xscara
//! motor_a_deg,motor_b_deg,x_mm,y_mm
//! 31.123456789,112.5,,
//! ```
//! `x_mm`, `y_mm` are the printer's X and Y (the G-code's coordinates) whatever the frame. The `frame` line is
//! optional (files written before it existed); without it the configuration's frame is used.

use std::fmt::Write as _;

use kinematics::ScaraFrame;

use super::{Measurement, ScaraError};

/// The CSV header this reader expects (angles in degrees, positions in mm).
pub const CSV_HEADER: [&str; 4] = ["motor_a_deg", "motor_b_deg", "x_mm", "y_mm"];

/// The frame names a file (and printer.cfg's `frame`) uses.
pub fn frame_name(frame: ScaraFrame) -> &'static str {
    match frame {
        ScaraFrame::Standard => "standard",
        ScaraFrame::XScara => "xscara",
    }
}

/// A measurements file: its rows and the frame it states, with the line that states it.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementFile {
    pub frame: Option<(ScaraFrame, usize)>,
    pub rows: Vec<Measurement>,
}

/// Parse measurements: `#` starts a comment (whole line or trailing), blank lines are skipped, an optional
/// `frame,<standard|xscara>` line comes first, then the header `motor_a_deg,motor_b_deg,x_mm,y_mm`, then one pose
/// per line. Errors carry `file:line:column` of the offending field.
pub fn parse_measurement_file(text: &str, file: &str) -> Result<MeasurementFile, ScaraError> {
    let located = located_in(file);
    let (frame, table) = frame_line(text).map_err(located)?;
    let rows = crate::measured::measurement_rows(&table, &CSV_HEADER).map_err(located)?;
    Ok(MeasurementFile { frame, rows })
}

/// A CSV error of `file` as the located parse error both readers give.
fn located_in(file: &str) -> impl Fn(crate::csv::CsvError) -> ScaraError + Copy + '_ {
    move |e| ScaraError::Parse {
        file: file.to_string(),
        line: e.line,
        column: e.column,
        message: e.message,
    }
}

/// A measurements file read for its poses alone (the template as written, `x_mm` and `y_mm` empty or not).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseFile {
    pub frame: Option<(ScaraFrame, usize)>,
    /// Motor angles (rad) per row, in order (the pattern's cross numbers).
    pub poses: Vec<(f64, f64)>,
}

/// The poses of a measurements file or template, errors located as [`parse_measurement_file`]'s.
pub fn parse_pose_file(text: &str, file: &str) -> Result<PoseFile, ScaraError> {
    let located = located_in(file);
    let (frame, table) = frame_line(text).map_err(located)?;
    let poses = crate::measured::pose_rows(&table, &CSV_HEADER).map_err(located)?;
    Ok(PoseFile { frame, poses })
}

/// The rows of a measurements file (its frame line, if any, checked and set aside).
pub fn parse_measurements(text: &str, file: &str) -> Result<Vec<Measurement>, ScaraError> {
    parse_measurement_file(text, file).map(|f| f.rows)
}

/// The `frame,…` line when it is the first line with content, and the text with that line blanked.
fn frame_line(text: &str) -> Result<(Option<(ScaraFrame, usize)>, String), crate::csv::CsvError> {
    let (setting, table) = crate::csv::leading_setting(text, "frame")?;
    let Some(setting) = setting else {
        return Ok((None, table));
    };
    let frame = match setting.value.to_ascii_lowercase().as_str() {
        "standard" => ScaraFrame::Standard,
        "xscara" | "x-scara" => ScaraFrame::XScara,
        other => {
            return Err(crate::csv::CsvError {
                line: setting.line,
                column: setting.column,
                message: format!(
                    "frame `{other}` is not `standard` or `xscara` (printer.cfg's `frame`)"
                ),
            });
        }
    };
    Ok((Some((frame, setting.line)), table))
}

pub(crate) use crate::measured::degrees;

/// The measurements file to fill in: the frame line, then one row per pose with its motor angles, `x_mm` and `y_mm`
/// left to the person measuring the printed crosses.
pub fn measurement_template(poses: &[(f64, f64)], frame: ScaraFrame) -> String {
    let mut s = String::from(
        "# jointspace SCARA calibration: measure each printed cross's centre on the bed (mm, the printer's X/Y,\n\
         # the coordinates the G-code uses) and fill in x_mm and y_mm; the motor angles are the ones the machine\n\
         # commands at each cross centre, counted in the machine's frame (the line below).\n\
         # Then run: jointspace calibrate scara -c printer.cfg --measurements THIS_FILE\n",
    );
    let _ = writeln!(s, "frame,{}", frame_name(frame));
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
    fn csv_parse_and_errors() {
        let text =
            "# poses\nmotor_a_deg, motor_b_deg, x_mm, y_mm\n10,20,1.5,2.5 # ok\n\n30,40,3,4\n";
        let m = parse_measurements(text, "p.csv").expect("parse");
        assert_eq!(m.len(), 2);
        assert!((m[0].motor_a - 10f64.to_radians()).abs() < 1e-15 && m[1].line == 5);
        let bad = "motor_a_deg,motor_b_deg,x_mm,y_mm\n1,2,abc,4\n";
        assert_eq!(
            parse_measurements(bad, "p.csv"),
            Err(ScaraError::Parse {
                file: "p.csv".into(),
                line: 2,
                column: 5,
                message: "`abc` is not a finite number".into()
            })
        );
        assert!(matches!(
            parse_measurements("a,b,c,d\n", "p.csv"),
            Err(ScaraError::Parse {
                line: 1,
                column: 1,
                ..
            })
        ));
        assert!(matches!(
            parse_measurements("motor_a_deg,motor_b_deg,x_mm\n", "p.csv"),
            Err(ScaraError::Parse { .. })
        ));
        assert!(matches!(
            parse_measurements("# nothing\n", "p.csv"),
            Err(ScaraError::Parse { .. })
        ));
    }

    #[test]
    fn the_frame_line_is_read_and_located() {
        let text = "# x\nframe, xscara\nmotor_a_deg,motor_b_deg,x_mm,y_mm\n1,2,3,4\n";
        let f = parse_measurement_file(text, "m.csv").expect("reads");
        assert_eq!(f.frame, Some((ScaraFrame::XScara, 2)));
        assert_eq!(f.rows[0].line, 4);
        let none = parse_measurement_file("motor_a_deg,motor_b_deg,x_mm,y_mm\n1,2,3,4\n", "m.csv")
            .expect("reads");
        assert_eq!(none.frame, None);
        assert_eq!(
            parse_measurement_file("frame,  polar\n", "m.csv"),
            Err(ScaraError::Parse {
                file: "m.csv".into(),
                line: 1,
                column: 9,
                message: "frame `polar` is not `standard` or `xscara` (printer.cfg's `frame`)"
                    .into()
            })
        );
        // A frame line after the header is a data row, and wrong as one.
        let late = "motor_a_deg,motor_b_deg,x_mm,y_mm\nframe,standard\n";
        assert!(matches!(
            parse_measurement_file(late, "m.csv"),
            Err(ScaraError::Parse { line: 2, .. })
        ));
    }

    #[test]
    fn the_template_reads_back_with_its_frame_and_angles() {
        let poses = [(0.5, -1.25), (-3.0, 2.0)];
        let text = measurement_template(&poses, ScaraFrame::XScara).replace(",,", ",10,20");
        let f = parse_measurement_file(&text, "t.csv").expect("reads");
        assert_eq!(f.frame.map(|f| f.0), Some(ScaraFrame::XScara));
        for (m, (a, b)) in f.rows.iter().zip(poses) {
            assert!((m.motor_a - a).abs() < 1e-11 && (m.motor_b - b).abs() < 1e-11);
        }
    }
}
