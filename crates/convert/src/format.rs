//! Minimal fixed-decimal number writer for output G-code: no exponent, no `-0`, trailing zeros trimmed.
//!
//! Values are handled as integers in units of `10^-decimals`, which is also how the converter tracks what
//! it has written (so totals are exact sums of written values).

/// `10^d` for d = 0..=18 (decimals go up to 12 for feeds; integer parts use the rest).
const POW10: [u64; 19] = {
    let mut table = [1u64; 19];
    let mut i = 1;
    while i < 19 {
        table[i] = table[i - 1] * 10;
        i += 1;
    }
    table
};

/// Two-digit strings "00".."99", so digits are written in pairs.
const PAIRS: [[u8; 2]; 100] = {
    let mut table = [[0u8; 2]; 100];
    let mut i = 0;
    while i < 100 {
        table[i] = [b'0' + (i / 10) as u8, b'0' + (i % 10) as u8];
        i += 1;
    }
    table
};

/// `10^d` for the supported decimal counts.
pub fn scale(decimals: u8) -> f64 {
    POW10[usize::from(decimals.min(18))] as f64
}

/// `value` rounded to `decimals` places, as an integer count of `10^-decimals`.
pub fn to_units(value: f64, decimals: u8) -> i64 {
    // Round half away from zero; the cast truncates (and saturates: values here are far below 2^53).
    let scaled = value * scale(decimals);
    (scaled + 0.5f64.copysign(scaled)) as i64
}

/// One output line assembled in place (numbers written straight into it), then written with one call.
#[derive(Debug, Clone)]
pub struct LineBuf {
    bytes: [u8; 256],
    len: usize,
}

impl Default for LineBuf {
    fn default() -> Self {
        LineBuf {
            bytes: [0; 256],
            len: 0,
        }
    }
}

/// Room one number may need: sign, 19 integer digits, point, 18 decimals.
const NUMBER_MAX: usize = 40;

impl LineBuf {
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Appends `bytes`; a line never holds more than a command and five words, far below the capacity
    /// (anything beyond it would be cut, never a panic).
    pub fn push(&mut self, bytes: &[u8]) {
        let end = (self.len + bytes.len()).min(self.bytes.len());
        self.bytes[self.len..end].copy_from_slice(&bytes[..end - self.len]);
        self.len = end;
    }

    /// Appends ` <letter><units·10^-decimals>`.
    pub fn word(&mut self, letter: char, units: i64, decimals: u8) {
        match u8::try_from(letter) {
            // The usual ASCII letter: two stores instead of a copy.
            Ok(ascii) if ascii.is_ascii() && self.len + 2 <= self.bytes.len() => {
                self.bytes[self.len] = b' ';
                self.bytes[self.len + 1] = ascii;
                self.len += 2;
            }
            _ => {
                let mut head = [b' ', 0, 0, 0, 0];
                let len = letter.encode_utf8(&mut head[1..]).len();
                self.push(&head[..=len]);
            }
        }
        self.number(units, decimals);
    }

    /// Appends the decimal text of `units · 10^-decimals` (trailing zeros trimmed, no `-0`), with integer
    /// arithmetic by constants only (no division by a variable power of ten), two digits at a time.
    pub fn number(&mut self, units: i64, decimals: u8) {
        if self.len + NUMBER_MAX > self.bytes.len() {
            return;
        }
        let mut frac_digits = usize::from(decimals.min(18));
        let mut digits = units.unsigned_abs();
        // Trailing zeros of the fraction are not written.
        while frac_digits > 0 && digits.is_multiple_of(10) {
            digits /= 10;
            frac_digits -= 1;
        }
        let all_digits = digits.checked_ilog10().map_or(1, |l| l as usize + 1);
        let whole_digits = all_digits.saturating_sub(frac_digits).max(1);
        let sign = usize::from(units < 0);
        let point = usize::from(frac_digits > 0);
        let end = self.len + sign + whole_digits + point + frac_digits;
        let out = &mut self.bytes[self.len..end];
        // Right to left: fraction, point, integer part, sign.
        let mut i = out.len();
        digits = write_digits(&mut out[i - frac_digits..i], digits);
        i -= frac_digits;
        if point == 1 {
            i -= 1;
            out[i] = b'.';
        }
        write_digits(&mut out[i - whole_digits..i], digits);
        if sign == 1 {
            out[0] = b'-';
        }
        self.len = end;
    }

    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..self.len]
    }
}

/// Fills `out` with the last `out.len()` decimal digits of `value` (zero-padded); returns the digits left.
fn write_digits(out: &mut [u8], mut value: u64) -> u64 {
    let mut i = out.len();
    while i >= 2 {
        let [a, b] = PAIRS[(value % 100) as usize];
        out[i - 2] = a;
        out[i - 1] = b;
        value /= 100;
        i -= 2;
    }
    if i == 1 {
        out[0] = b'0' + (value % 10) as u8;
        value /= 10;
    }
    value
}

/// Decimals for a feed value so that its relative rounding error stays below 1e-7.
pub fn feed_decimals(feed: f64) -> u8 {
    let mut decimals = 7u8;
    let mut bound = 1.0;
    let feed = feed.abs();
    while feed >= bound * 10.0 && decimals > 3 {
        bound *= 10.0;
        decimals -= 1;
    }
    while feed < bound && decimals < 12 {
        bound /= 10.0;
        decimals += 1;
    }
    decimals
}

#[cfg(test)]
mod tests {
    use super::*;

    fn number(units: i64, decimals: u8) -> String {
        let mut line = LineBuf::default();
        line.number(units, decimals);
        String::from_utf8(line.as_bytes().to_vec()).unwrap_or_default()
    }

    fn text(value: f64, decimals: u8) -> String {
        number(to_units(value, decimals), decimals)
    }

    #[test]
    fn trims_zeros_and_never_writes_negative_zero() {
        assert_eq!(text(1.5, 4), "1.5");
        assert_eq!(text(-0.00001, 3), "0");
        assert_eq!(text(-2.25, 3), "-2.25");
        assert_eq!(text(0.000123, 6), "0.000123");
        assert_eq!(text(123456.0, 3), "123456");
        assert_eq!(text(0.1 + 0.2, 5), "0.3");
    }

    #[test]
    fn round_trips_through_parse() {
        for v in [0.0, 1e-5, -359.999999, 12345.678901, 7.0] {
            let parsed: f64 = text(v, 6).parse().unwrap_or(f64::NAN);
            assert!((parsed - v).abs() <= 0.5e-6, "{v} -> {parsed}");
        }
    }

    #[test]
    fn integer_writer_matches_float_formatting() {
        for units in [
            0i64,
            1,
            -1,
            9,
            10,
            99,
            100,
            12345,
            -98765,
            1_000_000,
            i64::MAX,
            i64::MIN + 1,
        ] {
            for decimals in [0u8, 1, 3, 6, 9, 12] {
                let text = number(units, decimals);
                let expected = if decimals == 0 {
                    units.to_string()
                } else {
                    let d = usize::from(decimals);
                    let m = units.unsigned_abs().to_string();
                    let m = format!("{m:0>w$}", w = d + 1);
                    let (whole, frac) = m.split_at(m.len() - d);
                    let frac = frac.trim_end_matches('0');
                    let sign = if units < 0 { "-" } else { "" };
                    if frac.is_empty() {
                        format!("{sign}{whole}")
                    } else {
                        format!("{sign}{whole}.{frac}")
                    }
                };
                assert_eq!(text, expected, "{units} at {decimals}");
            }
        }
    }

    #[test]
    fn words_have_a_space_and_any_letter() {
        let mut line = LineBuf::default();
        line.push(b"G1");
        line.word('X', 12345, 3);
        line.word('θ', -5, 1);
        assert_eq!(line.as_bytes(), "G1 X12.345 θ-0.5".as_bytes());
    }

    #[test]
    fn feed_decimals_keep_relative_precision() {
        assert_eq!(feed_decimals(3000.0), 4);
        assert_eq!(feed_decimals(0.05), 9);
        assert_eq!(feed_decimals(5e7), 3);
    }
}
