//! G-code writer: numbers with fixed decimals per axis (trailing zeros trimmed, never `-0`, never an
//! exponent) or in shortest exact form, lexed lines written back (optionally with their comments), and
//! moves written from values with configurable axis letters (a converter may write `X`=radius, `Y`=angle).

use std::io::{self, Write};

use crate::lexer::{CommandWord, Line};

/// Decimals per kind of value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decimals {
    /// X, Y, Z (and the letters written in their place).
    pub xyz: u8,
    pub e: u8,
    pub f: u8,
    /// Every other letter (S, P, I, J, R…).
    pub other: u8,
}

impl Default for Decimals {
    fn default() -> Self {
        Decimals {
            xyz: 3,
            e: 5,
            f: 1,
            other: 4,
        }
    }
}

/// How numbers are printed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NumberFormat {
    /// Rounded to fixed decimals, trailing zeros trimmed.
    Fixed(Decimals),
    /// The shortest text that parses back to the same f64 (exact round trips).
    Shortest,
}

/// Writer settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WriterOptions {
    pub numbers: NumberFormat,
    /// Write comments of lexed lines (and comment-only / blank lines).
    pub keep_comments: bool,
    /// Letters [`Writer::write_move`] uses for axes 0..4 (default `X Y Z E`).
    pub letters: [u8; 4],
}

impl Default for WriterOptions {
    fn default() -> Self {
        WriterOptions {
            numbers: NumberFormat::Fixed(Decimals::default()),
            keep_comments: true,
            letters: *b"XYZE",
        }
    }
}

/// Appends `value` to `out`: fixed `decimals` (trimmed) or shortest exact (`None`).
/// Non-finite values are an error: a NaN in G-code is always a bug upstream.
pub fn format_number(value: f64, decimals: Option<u8>, out: &mut Vec<u8>) -> io::Result<()> {
    if !value.is_finite() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("cannot write {value} as G-code"),
        ));
    }
    let start = out.len();
    match decimals {
        Some(decimals) => {
            write!(out, "{:.*}", usize::from(decimals), value)?;
            if decimals > 0 {
                while out.last() == Some(&b'0') {
                    out.pop();
                }
                if out.last() == Some(&b'.') {
                    out.pop();
                }
            }
        }
        // Display for f64 is the shortest round-trip form and never uses an exponent.
        None => write!(out, "{value}")?,
    }
    if &out[start..] == b"-0" {
        out.truncate(start);
        out.push(b'0');
    }
    Ok(())
}

/// Writes G-code lines to `out`.
#[derive(Debug)]
pub struct Writer<W: Write> {
    out: W,
    options: WriterOptions,
    buf: Vec<u8>,
}

impl<W: Write> Writer<W> {
    pub fn new(out: W, options: WriterOptions) -> Self {
        Writer {
            out,
            options,
            buf: Vec::with_capacity(256),
        }
    }

    pub fn options(&self) -> &WriterOptions {
        &self.options
    }

    /// Decimals used for `letter` (`None` in shortest mode).
    pub fn decimals_for(&self, letter: u8) -> Option<u8> {
        let NumberFormat::Fixed(d) = self.options.numbers else {
            return None;
        };
        let [x, y, z, e] = self.options.letters;
        Some(match letter.to_ascii_uppercase() {
            l if l == e || l == b'E' => d.e,
            l if l == x || l == y || l == z || matches!(l, b'X' | b'Y' | b'Z') => d.xyz,
            b'F' => d.f,
            _ => d.other,
        })
    }

    /// Writes a lexed line back: `N`, command, words, raw text, extended parameters, a recomputed
    /// checksum if the line had one, and (if kept) its comments. Blank and comment-only lines are
    /// written only when comments are kept.
    pub fn write_line(&mut self, line: &Line<'_>) -> io::Result<()> {
        self.buf.clear();
        let Some(command) = line.command_text() else {
            if self.options.keep_comments {
                self.push_comments(line);
                return self.finish_line();
            }
            return Ok(());
        };
        if let Some((number, _)) = line.line_number() {
            write!(self.buf, "N{number} ")?;
        }
        self.buf
            .extend(command.bytes().map(|b| b.to_ascii_uppercase()));
        if let Some(CommandWord::Code { .. }) = line.command() {
            for word in line.words() {
                self.buf.push(b' ');
                self.buf.push(word.letter);
                if let Some(value) = word.value {
                    let decimals = self.decimals_for(word.letter);
                    format_number(value, decimals, &mut self.buf)?;
                }
            }
        }
        if let Some(text) = line.raw_text().filter(|t| !t.is_empty()) {
            self.buf.push(b' ');
            self.buf.extend_from_slice(text.as_bytes());
        }
        for param in line.ext_params() {
            self.buf.push(b' ');
            self.buf.extend_from_slice(param.key.as_bytes());
            self.buf.push(b'=');
            if param.quoted {
                self.buf.push(b'"');
            }
            self.buf.extend_from_slice(param.value.as_bytes());
            if param.quoted {
                self.buf.push(b'"');
            }
        }
        if line.checksum().is_some() {
            let checksum = self.buf.iter().fold(0u8, |acc, b| acc ^ b);
            write!(self.buf, "*{checksum}")?;
        }
        if self.options.keep_comments && line.has_comments() {
            self.buf.push(b' ');
            self.push_comments(line);
        }
        self.finish_line()
    }

    fn push_comments(&mut self, line: &Line<'_>) {
        let mut first = true;
        for comment in line.comments() {
            if !first {
                self.buf.push(b' ');
            }
            first = false;
            if comment.parenthesised {
                self.buf.push(b'(');
                self.buf.extend_from_slice(comment.text.as_bytes());
                self.buf.push(b')');
            } else {
                self.buf.push(b';');
                self.buf.extend_from_slice(comment.text.as_bytes());
            }
        }
    }

    /// `G0`/`G1` with the configured letters for the axes given and `F` (mm/min as written).
    pub fn write_move(
        &mut self,
        rapid: bool,
        axes: &[Option<f64>; 4],
        feed: Option<f64>,
    ) -> io::Result<()> {
        self.buf.clear();
        self.buf
            .extend_from_slice(if rapid { b"G0" } else { b"G1" });
        for (letter, value) in self.options.letters.into_iter().zip(axes) {
            if let Some(value) = value {
                self.push_word(letter, *value)?;
            }
        }
        if let Some(feed) = feed {
            self.push_word(b'F', feed)?;
        }
        self.finish_line()
    }

    /// Any command with numeric words (`M204 S3000`, `G2 X.. I..`), letters written as given.
    pub fn write_words(&mut self, command: &str, words: &[(u8, f64)]) -> io::Result<()> {
        self.buf.clear();
        self.buf.extend_from_slice(command.as_bytes());
        for &(letter, value) in words {
            self.push_word(letter, value)?;
        }
        self.finish_line()
    }

    /// A line written verbatim (the text must not contain a line break).
    pub fn write_raw(&mut self, text: &str) -> io::Result<()> {
        self.buf.clear();
        self.buf.extend_from_slice(text.as_bytes());
        self.finish_line()
    }

    /// `;text` on its own line.
    pub fn write_comment(&mut self, text: &str) -> io::Result<()> {
        self.buf.clear();
        self.buf.push(b';');
        self.buf.extend_from_slice(text.as_bytes());
        self.finish_line()
    }

    fn push_word(&mut self, letter: u8, value: f64) -> io::Result<()> {
        let decimals = self.decimals_for(letter);
        self.buf.push(b' ');
        self.buf.push(letter);
        format_number(value, decimals, &mut self.buf)
    }

    fn finish_line(&mut self) -> io::Result<()> {
        self.buf.push(b'\n');
        self.out.write_all(&self.buf)
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reader::Reader;

    fn fixed(value: f64, decimals: u8) -> String {
        let mut out = Vec::new();
        format_number(value, Some(decimals), &mut out).expect("finite");
        String::from_utf8(out).expect("ascii")
    }

    fn shortest(value: f64) -> String {
        let mut out = Vec::new();
        format_number(value, None, &mut out).expect("finite");
        String::from_utf8(out).expect("ascii")
    }

    #[test]
    fn fixed_numbers_are_trimmed() {
        assert_eq!(fixed(0.1 + 0.2, 3), "0.3");
        assert_eq!(fixed(10.0, 3), "10");
        assert_eq!(fixed(-0.0001, 3), "0");
        assert_eq!(fixed(-0.0, 5), "0");
        assert_eq!(fixed(1e21, 3), "1000000000000000000000");
        assert_eq!(fixed(1.23456789, 5), "1.23457");
        assert_eq!(fixed(-2.6, 0), "-3");
        assert_eq!(fixed(120.0, 0), "120");
    }

    #[test]
    fn shortest_numbers_are_exact_and_plain() {
        assert_eq!(shortest(0.1 + 0.2), "0.30000000000000004");
        assert_eq!(shortest(1e-7), "0.0000001");
        assert_eq!(shortest(-0.0), "0");
        assert_eq!(shortest(1e300).parse::<f64>().ok(), Some(1e300));
    }

    #[test]
    fn non_finite_values_are_refused() {
        assert!(format_number(f64::NAN, Some(3), &mut Vec::new()).is_err());
        assert!(format_number(f64::INFINITY, None, &mut Vec::new()).is_err());
    }

    fn rewrite(text: &str, options: WriterOptions) -> String {
        let mut reader = Reader::new(text.as_bytes(), "t");
        let mut writer = Writer::new(Vec::new(), options);
        while let Some(line) = reader.next_line() {
            writer.write_line(&line.expect("line")).expect("write");
        }
        String::from_utf8(writer.into_inner()).expect("utf8")
    }

    #[test]
    fn lines_are_written_back() {
        let text = "g1 x1.50000 Y-0.0001 E.5 ; go\n; note\nM117 Hello world\nSET_FAN_SPEED FAN=a MSG=\"x y\"\n\nG28 X Y\n";
        assert_eq!(
            rewrite(text, WriterOptions::default()),
            "G1 X1.5 Y0 E0.5 ; go\n; note\nM117 Hello world\nSET_FAN_SPEED FAN=a MSG=\"x y\"\n\nG28 X Y\n"
        );
        let bare = WriterOptions {
            keep_comments: false,
            ..WriterOptions::default()
        };
        assert_eq!(rewrite("; a\nG1 X1 (b)\n", bare), "G1 X1\n");
    }

    #[test]
    fn checksums_are_recomputed() {
        let body = "N7 G1 X1.000";
        let input = format!("{body}*{}\n", body.bytes().fold(0u8, |a, b| a ^ b));
        let out = rewrite(&input, WriterOptions::default());
        let (body, sum) = out.trim_end().split_once('*').expect("checksum");
        assert_eq!(body, "N7 G1 X1");
        assert_eq!(
            sum.parse::<u8>().ok(),
            Some(body.bytes().fold(0, |a, b| a ^ b))
        );
    }

    #[test]
    fn moves_use_configured_letters() {
        let options = WriterOptions {
            letters: *b"XYZE",
            ..WriterOptions::default()
        };
        let mut writer = Writer::new(Vec::new(), options);
        writer
            .write_move(
                false,
                &[Some(12.34567), Some(-0.00001), None, Some(0.123456)],
                Some(1800.0),
            )
            .expect("w");
        let polar = WriterOptions {
            letters: *b"RTZE",
            ..WriterOptions::default()
        };
        let mut polar_writer = Writer::new(Vec::new(), polar);
        polar_writer
            .write_move(true, &[Some(1.0), Some(90.0), None, None], None)
            .expect("w");
        assert_eq!(
            String::from_utf8(writer.into_inner()).ok().as_deref(),
            Some("G1 X12.346 Y0 E0.12346 F1800\n")
        );
        assert_eq!(
            String::from_utf8(polar_writer.into_inner()).ok().as_deref(),
            Some("G0 R1 T90\n")
        );
    }
}
