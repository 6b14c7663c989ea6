//! Minimal fixed-decimal number writer for output G-code: no exponent, no `-0`, trailing zeros trimmed.
//!
//! Values are handled as integers in units of `10^-decimals`, which is also how the converter tracks what
//! it has written (so totals are exact sums of written values).

/// `10^d` for the supported decimal counts.
pub fn scale(decimals: u8) -> f64 {
    10f64.powi(i32::from(decimals))
}

/// `value` rounded to `decimals` places, as an integer count of `10^-decimals`.
pub fn to_units(value: f64, decimals: u8) -> i64 {
    // Round half away from zero; the cast truncates (and saturates: values here are far below 2^53).
    let scaled = value * scale(decimals);
    (scaled + 0.5f64.copysign(scaled)) as i64
}

/// Appends ` <letter><units·10^-decimals>` to `out`.
pub fn push_word(out: &mut Vec<u8>, letter: char, units: i64, decimals: u8) {
    out.push(b' ');
    let mut buf = [0u8; 4];
    out.extend_from_slice(letter.encode_utf8(&mut buf).as_bytes());
    push_units(out, units, decimals);
}

/// Appends the decimal text of `units · 10^-decimals`.
pub fn push_units(out: &mut Vec<u8>, units: i64, decimals: u8) {
    // Built right to left in one stack buffer: sign, integer digits, point, trimmed fraction.
    let mut tmp = [0u8; 48];
    let mut i = tmp.len();
    let magnitude = units.unsigned_abs();
    let divisor = 10u64.pow(u32::from(decimals));
    let mut frac = magnitude % divisor;
    let mut digits = decimals;
    if frac != 0 {
        while frac.is_multiple_of(10) {
            frac /= 10;
            digits -= 1;
        }
        for _ in 0..digits {
            i -= 1;
            tmp[i] = b'0' + (frac % 10) as u8;
            frac /= 10;
        }
        i -= 1;
        tmp[i] = b'.';
    }
    let mut whole = magnitude / divisor;
    loop {
        i -= 1;
        tmp[i] = b'0' + (whole % 10) as u8;
        whole /= 10;
        if whole == 0 {
            break;
        }
    }
    if units < 0 {
        i -= 1;
        tmp[i] = b'-';
    }
    out.extend_from_slice(&tmp[i..]);
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

    fn text(value: f64, decimals: u8) -> String {
        let mut out = Vec::new();
        push_units(&mut out, to_units(value, decimals), decimals);
        String::from_utf8(out).unwrap_or_default()
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
    fn feed_decimals_keep_relative_precision() {
        assert_eq!(feed_decimals(3000.0), 4);
        assert_eq!(feed_decimals(0.05), 9);
        assert_eq!(feed_decimals(5e7), 3);
    }
}
