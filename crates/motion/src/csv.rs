//! Planned moves as CSV in the format of `golden/*/moves.csv` (Klipper's `trapq_append` arguments), with
//! floats written the way Python's `repr` writes them, so files can be compared with Klipper's directly.

use std::io::{self, Write};
use trapq::{MoveSink, Queue, TrapezoidMove};

pub const HEADER: &str = "trapq,print_time,accel_t,cruise_t,decel_t,start_x,start_y,start_z,axes_r_x,axes_r_y,axes_r_z,start_v,cruise_v,accel";

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

/// A [`MoveSink`] writing CSV rows.
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

    /// The writer, or the first write error.
    pub fn finish(mut self) -> io::Result<W> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write> MoveSink for CsvSink<W> {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) {
        if self.error.is_some() {
            return;
        }
        let name = match queue {
            Queue::Toolhead => "toolhead",
            Queue::Extruder => "extruder",
        };
        let values = [
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
        ];
        let mut line = String::with_capacity(256);
        line.push_str(name);
        for v in values {
            line.push(',');
            line.push_str(&python_float(v));
        }
        if let Err(e) = writeln!(self.out, "{line}") {
            self.error = Some(e);
        }
    }
}

/// Parse one CSV row (as written by [`CsvSink`] or Klipper's recorder).
pub fn parse_row(line: &str) -> Option<(Queue, TrapezoidMove)> {
    let mut fields = line.split(',');
    let queue = match fields.next()? {
        "toolhead" => Queue::Toolhead,
        "extruder" => Queue::Extruder,
        _ => return None,
    };
    let mut v = [0.0; 13];
    for slot in &mut v {
        *slot = fields.next()?.trim().parse().ok()?;
    }
    if fields.next().is_some() {
        return None;
    }
    Some((
        queue,
        TrapezoidMove {
            print_time: v[0],
            accel_t: v[1],
            cruise_t: v[2],
            decel_t: v[3],
            start_pos: [v[4], v[5], v[6]],
            axes_r: [v[7], v[8], v[9]],
            start_v: v[10],
            cruise_v: v[11],
            accel: v[12],
            motion: trapq::Motion::Travel,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

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
        sink.append(queue, &mv);
        let text = String::from_utf8(sink.finish().expect("writes")).expect("utf8");
        assert_eq!(text.lines().nth(1), Some(row));
    }
}
