//! The moves CSV: one planned move per row, as Klipper's `trapq_append` receives it (the format of
//! `golden/*/moves.csv`), with floats written the way Python's `repr` writes them, so files compare with
//! Klipper's directly. [`CsvSink`] writes it (a [`MoveSink`]); [`read_moves`] and [`parse_row`] read it.
//!
//! Extruder rows carry E as the X coordinate; their `axes_r_y/z` are pressure-advance flags, not directions.

use std::fmt;
use std::io::{self, BufRead, Write};

use crate::{Motion, MoveSink, Queue, SinkError, TrapezoidMove};

/// The header row: the queue's name, then the numbers of [`row_values`] in their order.
pub const HEADER: &str = "trapq,print_time,accel_t,cruise_t,decel_t,start_x,start_y,start_z,axes_r_x,axes_r_y,axes_r_z,start_v,cruise_v,accel";

/// Numbers in a row (every column but the first).
const NUMBERS: usize = 13;

/// A row's numbers in column order (the one place that orders them, for writing and reading).
fn row_values(mv: &TrapezoidMove) -> [f64; NUMBERS] {
    [
        mv.print_time,
        mv.accel_t,
        mv.cruise_t,
        mv.decel_t,
        mv.start_pos[0],
        mv.start_pos[1],
        mv.start_pos[2],
        mv.axes_r[0],
        mv.axes_r[1],
        mv.axes_r[2],
        mv.start_v,
        mv.cruise_v,
        mv.accel,
    ]
}

/// The move of a row's numbers (the inverse of [`row_values`]).
fn move_from_values(values: [f64; NUMBERS]) -> TrapezoidMove {
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
    TrapezoidMove {
        print_time,
        accel_t,
        cruise_t,
        decel_t,
        start_pos: [sx, sy, sz],
        axes_r: [rx, ry, rz],
        start_v,
        cruise_v,
        accel,
        motion: Motion::Travel,
    }
}

fn queue_name(queue: Queue) -> &'static str {
    match queue {
        Queue::Toolhead => "toolhead",
        Queue::Extruder => "extruder",
    }
}

fn queue_named(name: &str) -> Option<Queue> {
    match name {
        "toolhead" => Some(Queue::Toolhead),
        "extruder" => Some(Queue::Extruder),
        _ => None,
    }
}

/// Format like Python's `repr(float)`: shortest round-trip digits; scientific notation below 1e-4 and from
/// 1e16 up, with a signed exponent of at least two digits; integral values end in `.0`.
pub fn python_float(v: f64) -> String {
    if v.is_nan() {
        return "nan".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf".into() } else { "-inf".into() };
    }
    let magnitude = v.abs();
    if magnitude != 0.0 && !(1e-4..1e16).contains(&magnitude) {
        // Rust's `{:e}` gives the shortest round-trip mantissa too.
        let s = format!("{v:e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let (sign, digits) = match exponent.strip_prefix('-') {
            Some(d) => ('-', d),
            None => ('+', exponent),
        };
        return format!("{mantissa}e{sign}{digits:0>2}");
    }
    let s = format!("{v}");
    if s.contains('.') { s } else { format!("{s}.0") }
}

/// A [`MoveSink`] writing the header, then one row per move.
#[derive(Debug)]
pub struct CsvSink<W: Write> {
    out: W,
    error: Option<io::Error>,
}

impl<W: Write> CsvSink<W> {
    pub fn new(mut out: W) -> Self {
        let error = writeln!(out, "{HEADER}").err();
        CsvSink { out, error }
    }

    /// The writer, or the header's write error (a row's is the error of its `append`).
    pub fn finish(mut self) -> io::Result<W> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write> MoveSink for CsvSink<W> {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        if let Some(e) = self.error.take() {
            return Err(SinkError::new(e));
        }
        let mut line = String::with_capacity(256);
        line.push_str(queue_name(queue));
        for v in row_values(mv) {
            line.push(',');
            line.push_str(&python_float(v));
        }
        writeln!(self.out, "{line}").map_err(SinkError::new)
    }
}

/// Why a row could not be read: the 1-based column where the offending field starts, and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RowError {
    pub column: usize,
    pub message: String,
}

/// Parse one data row as written (by [`CsvSink`] or Klipper's recorder); every number must be finite.
pub fn parse_row(line: &str) -> Result<(Queue, TrapezoidMove), RowError> {
    let error = |column, message| RowError { column, message };
    let mut fields = line.split(',');
    let queue_text = fields.next().unwrap_or_default();
    let queue = queue_named(queue_text.trim())
        .ok_or_else(|| error(1, format!("unknown trapq {:?}", queue_text.trim())))?;
    let mut column = 1 + queue_text.len() + 1;
    let mut values = [0.0f64; NUMBERS];
    for (i, value) in values.iter_mut().enumerate() {
        let text = fields
            .next()
            .ok_or_else(|| error(column, format!("missing field {} of 14", i + 2)))?;
        let v = text
            .trim()
            .parse::<f64>()
            .map_err(|e| error(column, format!("bad number {text:?}: {e}")))?;
        if !v.is_finite() {
            return Err(error(column, format!("value {text:?} is not finite")));
        }
        *value = v;
        column += text.len() + 1;
    }
    if fields.next().is_some() {
        return Err(error(column, "more than 14 fields".to_string()));
    }
    Ok((queue, move_from_values(values)))
}

/// Why a moves CSV could not be read, at a 1-based line (and column).
#[derive(Debug)]
pub enum ReadError {
    Io {
        line: usize,
        source: io::Error,
    },
    Parse {
        line: usize,
        column: usize,
        message: String,
    },
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReadError::Io { line, source } => write!(f, "line {line}: {source}"),
            ReadError::Parse {
                line,
                column,
                message,
            } => write!(f, "{line}:{column}: {message}"),
        }
    }
}

impl std::error::Error for ReadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ReadError::Io { source, .. } => Some(source),
            ReadError::Parse { .. } => None,
        }
    }
}

/// Read a whole moves CSV (header first; blank lines skipped), in file order, as moves to step: an extruder
/// row's direction becomes `[1, 0, 0]` (its `axes_r_y/z` are flags; no case uses pressure advance).
pub fn read_moves(input: impl BufRead) -> Result<Vec<(Queue, TrapezoidMove)>, ReadError> {
    let mut moves = Vec::new();
    for (index, line) in input.lines().enumerate() {
        let line_number = index + 1;
        let line = line.map_err(|source| ReadError::Io {
            line: line_number,
            source,
        })?;
        let parse_error = |RowError { column, message }| ReadError::Parse {
            line: line_number,
            column,
            message,
        };
        if index == 0 {
            if line.trim() != HEADER {
                return Err(parse_error(RowError {
                    column: 1,
                    message: format!("expected header {HEADER:?}"),
                }));
            }
            continue;
        }
        if line.trim().is_empty() {
            continue;
        }
        let (queue, mut mv) = parse_row(&line).map_err(parse_error)?;
        if queue == Queue::Extruder {
            mv.axes_r = [1.0, 0.0, 0.0];
        }
        moves.push((queue, mv));
    }
    Ok(moves)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_names_the_queue_and_every_number() {
        assert_eq!(HEADER.split(',').count(), 1 + NUMBERS);
    }

    #[test]
    fn floats_look_like_python_repr() {
        // Expected strings are what CPython 3.11 prints for these values.
        assert_eq!(python_float(0.25), "0.25");
        assert_eq!(python_float(300.0), "300.0");
        assert_eq!(python_float(-0.0), "-0.0");
        assert_eq!(python_float(0.0), "0.0");
        assert_eq!(
            python_float(1.7905631855129122e-17),
            "1.7905631855129122e-17"
        );
        assert_eq!(
            python_float(-1.3839660443868546e-17),
            "-1.3839660443868546e-17"
        );
        assert_eq!(python_float(99999999.9), "99999999.9");
        assert_eq!(python_float(1e16), "1e+16");
        assert_eq!(python_float(0.0001), "0.0001");
        assert_eq!(python_float(0.00001), "1e-05");
        assert_eq!(python_float(0.1 + 0.2), "0.30000000000000004");
    }

    #[test]
    fn rows_round_trip() {
        let row = "toolhead,0.25,0.12963624321753373,0.0,0.11296957655086703,300.0,0.0,0.5,0.0,0.0,1.0,0.0,3.8890872965260113,30.0";
        let (queue, mv) = parse_row(row).expect("parses");
        let mut sink = CsvSink::new(Vec::new());
        sink.append(queue, &mv).expect("writes");
        let text = String::from_utf8(sink.finish().expect("writes")).expect("utf8");
        assert_eq!(text.lines().nth(1), Some(row));
    }

    /// A writer with room for `room` bytes (a full disk after that).
    struct Full {
        room: usize,
    }

    impl Write for Full {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if buf.len() > self.room {
                return Err(io::Error::other("no space left on device"));
            }
            self.room -= buf.len();
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_full_disk_stops_the_sink_at_the_row_that_did_not_fit() {
        let row = "toolhead,0.25,0.1,0.0,0.1,300.0,0.0,0.5,0.0,0.0,1.0,0.0,3.9,30.0";
        let (queue, mv) = parse_row(row).expect("parses");
        let mut sink = CsvSink::new(Full {
            room: HEADER.len() + 1 + 70,
        });
        assert!(sink.append(queue, &mv).is_ok());
        let err = sink.append(queue, &mv).expect_err("full");
        assert_eq!(err.to_string(), "no space left on device");
        // No room even for the header: the first row says so.
        let mut sink = CsvSink::new(Full { room: 3 });
        assert!(sink.append(queue, &mv).is_err());
    }

    #[test]
    fn bad_rows_name_their_column() {
        let column = |row| parse_row(row).map(|_| ()).map_err(|e| e.column);
        assert_eq!(column("toolhead,1.5,x"), Err(14));
        assert_eq!(column("nozzle,1"), Err(1));
        assert_eq!(column("toolhead,1,1,1,1,1,1,1,1,1,1,1,1,nan"), Err(34));
        assert_eq!(column("toolhead,1,1"), Err(14));
        assert_eq!(column("toolhead,1,1,1,1,1,1,1,1,1,1,1,1,1,1"), Err(36));
    }

    #[test]
    fn reading_keeps_order_fixes_extruder_directions_and_names_lines() {
        let text = format!(
            "{HEADER}\nextruder,1.5,0.1,0.2,0.1,3.0,1.0,0.0,1.0,1.0,0.0,-0.0,-2.0,-20.0\n\n\
             toolhead,2,0,1,0,0,0,0,0,1,0,0,5,0\n"
        );
        let moves = read_moves(text.as_bytes()).expect("reads");
        assert_eq!(moves.len(), 2);
        assert_eq!(moves[0].0, Queue::Extruder);
        assert_eq!(moves[0].1.axes_r, [1.0, 0.0, 0.0]);
        assert_eq!(moves[0].1.cruise_v, -2.0);
        assert_eq!(moves[1].1.axes_r, [0.0, 1.0, 0.0]);
        let bad = format!("{HEADER}\ntoolhead,1.5,x\n");
        match read_moves(bad.as_bytes()) {
            Err(ReadError::Parse { line, column, .. }) => assert_eq!((line, column), (2, 14)),
            other => panic!("expected a parse error, got {other:?}"),
        }
        match read_moves("trapq,time\n".as_bytes()) {
            Err(ReadError::Parse { line, column, .. }) => assert_eq!((line, column), (1, 1)),
            other => panic!("expected a header error, got {other:?}"),
        }
    }
}
