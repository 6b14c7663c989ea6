//! Reader for Klipper `trapq_append` logs in the golden `moves.csv(.gz)` format:
//! `trapq,print_time,accel_t,cruise_t,decel_t,start_x,start_y,start_z,axes_r_x,axes_r_y,axes_r_z,start_v,cruise_v,accel`.
//!
//! Extruder rows carry E as the X coordinate; their `axes_r_y/z` are pressure-advance flags, not directions,
//! so the direction is normalised to `[1, 0, 0]` here (no case uses pressure advance).

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use flate2::read::MultiGzDecoder;
use trapq::{Queue, TrapezoidMove};

use crate::error::MovesCsvError;

const HEADER: &str = "trapq,print_time,accel_t,cruise_t,decel_t,start_x,start_y,start_z,axes_r_x,axes_r_y,axes_r_z,start_v,cruise_v,accel";

/// Read every row of a moves file, in file order.
pub fn read_moves_csv(
    path: impl AsRef<Path>,
) -> Result<Vec<(Queue, TrapezoidMove)>, MovesCsvError> {
    let path = path.as_ref();
    let io = |source| MovesCsvError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io)?;
    let reader: Box<dyn Read> = if path.extension().is_some_and(|e| e == "gz") {
        Box::new(MultiGzDecoder::new(file))
    } else {
        Box::new(file)
    };
    let mut moves = Vec::new();
    for (index, line) in BufReader::new(reader).lines().enumerate() {
        let line = line.map_err(io)?;
        let parse_error = |column: usize, message: String| MovesCsvError::Parse {
            path: path.to_path_buf(),
            line: index + 1,
            column,
            message,
        };
        if index == 0 {
            if line.trim() != HEADER {
                return Err(parse_error(1, format!("expected header {HEADER:?}")));
            }
            continue;
        }
        if line.trim().is_empty() {
            continue;
        }
        moves.push(parse_row(&line).map_err(|(column, message)| parse_error(column, message))?);
    }
    Ok(moves)
}

/// Parse one data row; errors carry the 1-based column of the offending field.
pub fn parse_row(line: &str) -> Result<(Queue, TrapezoidMove), (usize, String)> {
    let mut values = [0.0f64; 13];
    let mut fields = line.split(',');
    let mut column = 1;
    let queue_text = fields.next().unwrap_or_default();
    let queue = match queue_text.trim() {
        "toolhead" => Queue::Toolhead,
        "extruder" => Queue::Extruder,
        other => return Err((column, format!("unknown trapq {other:?}"))),
    };
    column += queue_text.len() + 1;
    for (i, value) in values.iter_mut().enumerate() {
        let text = fields
            .next()
            .ok_or((column, format!("missing field {} of 14", i + 2)))?;
        let v = text
            .trim()
            .parse::<f64>()
            .map_err(|e| (column, format!("bad number {text:?}: {e}")))?;
        if !v.is_finite() {
            return Err((column, format!("value {text:?} is not finite")));
        }
        *value = v;
        column += text.len() + 1;
    }
    if fields.next().is_some() {
        return Err((column, "more than 14 fields".to_string()));
    }
    let [
        print_time,
        accel_t,
        cruise_t,
        decel_t,
        sx,
        sy,
        sz,
        rx,
        ry,
        rz,
        start_v,
        cruise_v,
        accel,
    ] = values;
    let axes_r = match queue {
        Queue::Toolhead => [rx, ry, rz],
        Queue::Extruder => [1.0, 0.0, 0.0],
    };
    let mv = TrapezoidMove {
        print_time,
        accel_t,
        cruise_t,
        decel_t,
        start_pos: [sx, sy, sz],
        axes_r,
        start_v,
        cruise_v,
        accel,
        motion: trapq::Motion::Travel,
    };
    Ok((queue, mv))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_rows_and_reports_columns() {
        let (q, mv) = parse_row("extruder,1.5,0.1,0.2,0.1,3.0,1.0,0.0,1.0,1.0,0.0,-0.0,-2.0,-20.0")
            .expect("row");
        assert_eq!(q, Queue::Extruder);
        assert_eq!(mv.axes_r, [1.0, 0.0, 0.0]);
        assert_eq!(mv.cruise_v, -2.0);
        assert_eq!(parse_row("toolhead,1.5,x").map_err(|e| e.0), Err(14));
        assert!(parse_row("nozzle,1").is_err());
        assert!(parse_row("toolhead,1,1,1,1,1,1,1,1,1,1,1,1,nan").is_err());
    }
}
