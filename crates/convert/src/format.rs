//! Minimal fixed-decimal number writer for output G-code: no exponent, no `-0`, trailing zeros trimmed.
//!
//! Values are handled as integers in units of `10^-decimals`, which is also how the converter tracks what
//! it has written (so totals are exact sums of written values).

use std::io::Write;

/// `10^d` for d = 0..=18 (decimals go up to 12 for feeds; integer parts use the rest), as the f64 each
/// is exactly, so scaling needs no integer conversion.
const POW10: [f64; 19] = {
    let mut table = [1.0; 19];
    let mut i = 1;
    while i < 19 {
        table[i] = table[i - 1] * 10.0;
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
#[inline]
pub fn scale(decimals: u8) -> f64 {
    POW10[usize::from(decimals.min(18))]
}

/// `value` rounded to `decimals` places, as an integer count of `10^-decimals`.
#[inline]
pub fn to_units(value: f64, decimals: u8) -> i64 {
    // Round half away from zero; the cast truncates (and saturates: values here are far below 2^53).
    let scaled = value * scale(decimals);
    (scaled + 0.5f64.copysign(scaled)) as i64
}

/// The output assembled in one reusable buffer: lines are built straight into it (numbers included, no
/// intermediate strings) and handed to the writer in large blocks, not line by line.
#[derive(Clone)]
pub struct OutBuf {
    bytes: Box<[u8]>,
    len: usize,
}

/// Buffer size: large enough that handing it over is rare, small enough to stay in cache.
const CAPACITY: usize = 1 << 16;
/// Room kept free before a line is built: a command and a handful of words, each at most
/// [`NUMBER_MAX`] + 5 bytes (anything beyond it would be cut, never a panic).
const LINE_ROOM: usize = 512;
/// Room one number may need: sign, 19 integer digits, point, 18 decimals.
const NUMBER_MAX: usize = 40;
/// Where numbers are assembled right-aligned, then copied with one fixed-size copy.
const SCRATCH: usize = 2 * NUMBER_MAX;

impl Default for OutBuf {
    fn default() -> Self {
        OutBuf {
            bytes: vec![0; CAPACITY].into_boxed_slice(),
            len: 0,
        }
    }
}

impl std::fmt::Debug for OutBuf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OutBuf").field("len", &self.len).finish()
    }
}

impl OutBuf {
    /// Makes room for one line of words, handing what is buffered to `out` if needed.
    pub fn line_room<W: Write>(&mut self, out: &mut W) -> std::io::Result<()> {
        if self.len + LINE_ROOM > self.bytes.len() {
            self.flush_to(out)?;
        }
        Ok(())
    }

    /// Hands everything buffered to `out`.
    pub fn flush_to<W: Write>(&mut self, out: &mut W) -> std::io::Result<()> {
        out.write_all(&self.bytes[..self.len])?;
        self.len = 0;
        Ok(())
    }

    /// Appends text of any length (pass-through lines), flushing as needed.
    pub fn text<W: Write>(&mut self, text: &[u8], out: &mut W) -> std::io::Result<()> {
        if self.len + text.len() > self.bytes.len() {
            self.flush_to(out)?;
            if text.len() > self.bytes.len() {
                return out.write_all(text);
            }
        }
        self.push(text);
        Ok(())
    }

    /// Appends `bytes` within the buffer (callers make room first with [`OutBuf::line_room`] or use
    /// [`OutBuf::text`]); anything beyond the capacity is cut, never a panic.
    #[inline]
    pub fn push(&mut self, bytes: &[u8]) {
        let end = (self.len + bytes.len()).min(self.bytes.len());
        self.bytes[self.len..end].copy_from_slice(&bytes[..end - self.len]);
        self.len = end;
    }

    /// Appends a short constant (a command, a letter, the newline): fixed-size stores, no copy call.
    #[inline]
    pub fn push_array<const N: usize>(&mut self, bytes: &[u8; N]) {
        if let Some(room) = self.bytes.get_mut(self.len..self.len + N) {
            room.copy_from_slice(bytes);
            self.len += N;
        }
    }

    /// Appends ` <letter><units·10^-decimals>`.
    #[inline(always)]
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

    /// Appends the decimal text of `units · 10^-decimals` (trailing zeros trimmed, no `-0`): assembled
    /// right to left in a scratch array, four digits per division by a constant, then copied in one
    /// fixed-size copy (the bytes past the number are overwritten by what follows).
    #[inline(always)]
    pub fn number(&mut self, units: i64, decimals: u8) {
        let value = units.unsigned_abs();
        if let Some((whole, fraction)) = split_eight(value, decimals) {
            self.eight_and_eight(units < 0, whole, fraction);
        } else {
            self.any_number(units, decimals);
        }
    }

    /// The usual number: at most eight integer digits and eight decimals (`fraction` holds eight digits,
    /// padded with zeros), each part turned into eight ASCII digits at once and stored in one 8-byte write.
    #[inline(always)]
    fn eight_and_eight(&mut self, negative: bool, whole: u32, fraction: u32) {
        let Some(out) = self.bytes.get_mut(self.len..self.len + 18) else {
            return;
        };
        let sign = usize::from(negative);
        out[0] = b'-';
        let whole = eight_digits(whole);
        // Leading zeros are not written; at least one digit is.
        let skip = (whole.trailing_zeros() / 8).min(7);
        let whole_len = 8 - skip as usize;
        let text = (whole | ASCII_ZEROS) >> (8 * skip);
        out[sign..sign + 8].copy_from_slice(&text.to_le_bytes());
        let mut len = sign + whole_len;
        let fraction = eight_digits(fraction);
        // Trailing zeros are not written, nor a point with nothing after it.
        let kept = 8 - (fraction.leading_zeros() / 8) as usize;
        if kept > 0 {
            out[len] = b'.';
            out[len + 1..len + 9].copy_from_slice(&(fraction | ASCII_ZEROS).to_le_bytes());
            len += 1 + kept;
        }
        self.len += len;
    }

    /// Any number [`OutBuf::number`] may be given, digit pair by digit pair.
    fn any_number(&mut self, units: i64, decimals: u8) {
        let Some(out) = self.bytes.get_mut(self.len..self.len + NUMBER_MAX) else {
            return;
        };
        let mut scratch = [b'0'; SCRATCH];
        let decimals = usize::from(decimals.min(18));
        let end = NUMBER_MAX;
        let mut value = units.unsigned_abs();
        // The fraction, zero-padded to `decimals` digits.
        let point = end - decimals;
        value = write_digits(&mut scratch[point..end], value);
        // Trailing zeros are not written, nor a point with nothing after it.
        let mut last = end;
        while last > point && scratch[last - 1] == b'0' {
            last -= 1;
        }
        let whole_end = if last > point {
            scratch[point - 1] = b'.';
            point - 1
        } else {
            last = point;
            point
        };
        // The integer part, at least one digit.
        let mut first = write_whole(&mut scratch[..whole_end], value);
        if units < 0 {
            first -= 1;
            scratch[first] = b'-';
        }
        out.copy_from_slice(&scratch[first..first + NUMBER_MAX]);
        self.len += last - first;
    }

    /// What is buffered and not yet handed to a writer.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..self.len]
    }
}

/// `'0'` in every byte: digit values 0..=9 per byte become ASCII by an OR.
const ASCII_ZEROS: u64 = 0x3030_3030_3030_3030;

/// `value · 10^-decimals` as an integer part below 10^8 and the first eight decimals (as an integer below
/// 10^8), when the number is that small and has at most eight decimals; divisions by constants only.
#[inline(always)]
fn split_eight(value: u64, decimals: u8) -> Option<(u32, u32)> {
    fn by<const P: u64>(value: u64) -> (u64, u64) {
        (value / P, value % P * (100_000_000 / P))
    }
    let (whole, fraction) = match decimals {
        0 => (value, 0),
        1 => by::<10>(value),
        2 => by::<100>(value),
        3 => by::<1_000>(value),
        4 => by::<10_000>(value),
        5 => by::<100_000>(value),
        6 => by::<1_000_000>(value),
        7 => by::<10_000_000>(value),
        8 => by::<100_000_000>(value),
        _ => return None,
    };
    // Both below 10^8 < 2^32.
    Some((
        u32::try_from(whole).ok().filter(|&w| w < 100_000_000)?,
        fraction as u32,
    ))
}

/// The eight decimal digits of `x < 10^8` (zero-padded), one digit value per byte, the most significant
/// in the lowest byte (so `to_le_bytes` reads them in order): halves, quarters and digits split in parallel
/// lanes of one register by multiplications (the SWAR method Daniel Lemire describes).
#[inline(always)]
fn eight_digits(x: u32) -> u64 {
    let x = u64::from(x);
    // Lanes of 32 bits: the first four digits, the last four.
    let halves = (x / 10_000) | ((x % 10_000) << 32);
    // Lanes of 16 bits: digit pairs (x·10486 >> 20 is x / 100 for x < 10^4).
    let high_pairs = ((halves * 10_486) >> 20) & ((0x7F << 32) | 0x7F);
    let pairs = ((halves - 100 * high_pairs) << 16) | high_pairs;
    // Lanes of 8 bits: digits (x·103 >> 10 is x / 10 for x < 100).
    let tens = ((pairs * 103) >> 10) & ((0xF << 48) | (0xF << 32) | (0xF << 16) | 0xF);
    ((pairs - 10 * tens) << 8) | tens
}

/// Fills `out` with the last `out.len()` decimal digits of `value` (zero-padded), four at a time; returns
/// the digits left.
#[inline]
fn write_digits(out: &mut [u8], mut value: u64) -> u64 {
    let mut i = out.len();
    while i >= 4 {
        let quad = (value % 10_000) as u32;
        value /= 10_000;
        out[i - 4..i - 2].copy_from_slice(&PAIRS[(quad / 100) as usize]);
        out[i - 2..i].copy_from_slice(&PAIRS[(quad % 100) as usize]);
        i -= 4;
    }
    while i >= 2 {
        out[i - 2..i].copy_from_slice(&PAIRS[(value % 100) as usize]);
        value /= 100;
        i -= 2;
    }
    if i == 1 {
        out[0] = b'0' + (value % 10) as u8;
        value /= 10;
    }
    value
}

/// Writes the digits of `value` (at least one) right-aligned at the end of `out`; returns where they
/// start. `out` holds at least 20 bytes (any u64).
#[inline]
fn write_whole(out: &mut [u8], mut value: u64) -> usize {
    let mut i = out.len();
    while value >= 100 {
        out[i - 2..i].copy_from_slice(&PAIRS[(value % 100) as usize]);
        value /= 100;
        i -= 2;
    }
    if value >= 10 {
        out[i - 2..i].copy_from_slice(&PAIRS[value as usize]);
        i - 2
    } else {
        out[i - 1] = b'0' + value as u8;
        i - 1
    }
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
        let mut line = OutBuf::default();
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
    fn eight_digits_in_order() {
        for x in [0u32, 7, 10, 99_999_999, 12_345_678, 10_000_000, 90_807, 100] {
            let text = (eight_digits(x) | ASCII_ZEROS).to_le_bytes();
            assert_eq!(text, *format!("{x:08}").as_bytes(), "{x}");
        }
    }

    #[test]
    fn fast_and_general_numbers_agree() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for i in 0..200_000u64 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            // Values of every size, many with trailing zeros.
            let magnitude = seed % 10u64.pow((i % 19) as u32).max(1) / 10u64.pow((i % 5) as u32)
                * 10u64.pow((i % 5) as u32);
            let units = if seed & 1 == 0 {
                magnitude as i64
            } else {
                -(magnitude as i64)
            };
            let decimals = (i % 11) as u8;
            let mut fast = OutBuf::default();
            fast.number(units, decimals);
            let mut general = OutBuf::default();
            general.any_number(units, decimals);
            assert_eq!(fast.as_bytes(), general.as_bytes(), "{units} at {decimals}");
        }
    }

    #[test]
    fn words_have_a_space_and_any_letter() {
        let mut line = OutBuf::default();
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
