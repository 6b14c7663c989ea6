//! Exact, fast parsing of G-code numbers (`94.838`, `-.54`, `+5`, `10.`): the value is always the one
//! `str::parse::<f64>` gives for the same text.
//!
//! Fast path (Clinger): an integer mantissa of at most 2^53 and at most 22 fraction digits is turned into
//! the value by one correctly rounded division by an exact power of ten. Anything else goes to std's
//! parser. Exponents, `nan` and `inf` are not G-code and never reach either path.

/// Why a number could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NumberError {
    /// No digits (`-`, `.`), or a second `.` (`1.2.3`).
    Invalid,
    /// The value does not fit an f64 (a 400-digit integer).
    Overflow,
}

/// Powers of ten that are exact in f64.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Largest mantissa for which the fast path is exact.
const MAX_EXACT_MANTISSA: u64 = 1 << 53;

/// Parses the number starting at `bytes[start]`; returns the value and the index just past it.
/// Stops at the first byte that cannot continue the number; the caller checks what follows.
/// (Always inlined: it is the inner loop of the lexer's and of the fast path's word loops.)
#[inline(always)]
pub fn parse_number(bytes: &[u8], start: usize) -> Result<(f64, usize), NumberError> {
    let mut i = start;
    let negative = match bytes.get(i) {
        Some(b'-') => {
            i += 1;
            true
        }
        Some(b'+') => {
            i += 1;
            false
        }
        _ => false,
    };
    // Nearly every G-code number ends within eight bytes of its sign: read those at once.
    if let Some((magnitude, end)) = short_number(bytes, i) {
        return Ok((if negative { -magnitude } else { magnitude }, end));
    }
    let unsigned_start = i;
    let (mut mantissa, int_end) = digits(bytes, i, 0);
    let int_digits = int_end - i;
    i = int_end;
    let mut frac_digits = 0;
    if bytes.get(i) == Some(&b'.') {
        let (with_fraction, frac_end) = digits(bytes, i + 1, mantissa);
        mantissa = with_fraction;
        frac_digits = frac_end - (i + 1);
        i = frac_end;
    }
    if int_digits + frac_digits == 0 || bytes.get(i) == Some(&b'.') {
        return Err(NumberError::Invalid);
    }
    // At most 19 digits cannot overflow u64 (the wrapping arithmetic below is then exact).
    let fast = int_digits + frac_digits <= 19
        && mantissa <= MAX_EXACT_MANTISSA
        && frac_digits < POW10.len();
    let magnitude = if fast {
        mantissa as f64 / POW10[frac_digits]
    } else {
        slow_parse(&bytes[unsigned_start..i])?
    };
    let value = if negative { -magnitude } else { magnitude };
    Ok((value, i))
}

/// Eight ASCII `0` bytes.
const ZEROS: u64 = u64::from_le_bytes([b'0'; 8]);

/// `b'.' ^ b'0'`: a dot after [`ZEROS`] is taken away.
const DOT: u64 = (b'.' ^ b'0') as u64;

/// The unsigned number at `bytes[start..]` when it ends within eight bytes: its value and end,
/// by [`parse_number`]'s fast path (same mantissa, same division). `None` (for the byte loop)
/// for a longer number, a malformed one, and near the end of `bytes`. Branch-free but for that:
/// the byte loop's exits, at a different place in every number, were mispredicted.
#[inline(always)]
fn short_number(bytes: &[u8], start: usize) -> Option<(f64, usize)> {
    let window = u64::from_le_bytes(*bytes.get(start..)?.first_chunk::<8>()?);
    // Digits become 0..=9; any other byte has its high bit set in `stops` (exact up to the
    // first non-ASCII byte: the addition carries only out of one, into the bytes after it).
    let values = window ^ ZEROS;
    let stops = (values.wrapping_add(0x7676_7676_7676_7676) | values) & 0x8080_8080_8080_8080;
    let first = stops.trailing_zeros() / 8;
    if first == 8 {
        return None;
    }
    let has_dot = (values >> (8 * first)) & 0xFF == DOT;
    // With a dot, the number ends at the next stop, which must not be a second dot.
    let end = if has_dot {
        (stops & (stops - 1)).trailing_zeros() / 8
    } else {
        first
    };
    let digits = end - u32::from(has_dot);
    if end == 8 || digits == 0 || (has_dot && (values >> (8 * end)) & 0xFF == DOT) {
        return None;
    }
    // The digits closed up over the dot, then moved to the top bytes (leading zeros below).
    let below_dot = (1u64 << (8 * first)) - 1;
    let closed = if has_dot {
        (values & below_dot) | ((values >> 8) & !below_dot)
    } else {
        values
    };
    let mantissa = eight_digits(closed << (8 * (8 - digits)));
    let frac_digits = if has_dot { end - first - 1 } else { 0 };
    let value = mantissa as f64 / POW10[frac_digits as usize];
    Some((value, start + end as usize))
}

/// The value of eight digit values (0..=9), the most significant in the low byte.
#[inline(always)]
fn eight_digits(values: u64) -> u64 {
    // Pairs, then fours, then all eight (one multiply each: 10 * 256 + 1, 100 * 2^16 + 1…).
    let pairs = (values.wrapping_mul(10 * (1 << 8) + 1) >> 8) & 0x00FF_00FF_00FF_00FF;
    let fours = (pairs.wrapping_mul(100 * (1 << 16) + 1) >> 16) & 0x0000_FFFF_0000_FFFF;
    fours.wrapping_mul(10_000 * (1 << 32) + 1) >> 32
}

/// Reads decimal digits from `bytes[start..]`, continuing `mantissa` (wrapping: callers check the
/// digit count); returns the mantissa and the index after the last digit.
#[inline(always)]
fn digits(bytes: &[u8], start: usize, mut mantissa: u64) -> (u64, usize) {
    let mut i = start;
    // Two bytes a step (numbers run to several digits): half the loop's tests and steps.
    while let Some(&[first, second]) = bytes.get(i..i + 2) {
        let (first, second) = (digit_value(first), digit_value(second));
        if first > 9 {
            return (mantissa, i);
        }
        if second > 9 {
            return (append_digit(mantissa, first), i + 1);
        }
        mantissa = append_digit(append_digit(mantissa, first), second);
        i += 2;
    }
    if let Some(&last) = bytes.get(i) {
        let digit = digit_value(last);
        if digit <= 9 {
            return (append_digit(mantissa, digit), i + 1);
        }
    }
    (mantissa, i)
}

/// The value of a digit byte; above 9 for any other byte.
#[inline(always)]
fn digit_value(byte: u8) -> u8 {
    byte.wrapping_sub(b'0')
}

/// `mantissa` with the digit appended (wrapping: callers check the digit count).
#[inline(always)]
fn append_digit(mantissa: u64, digit: u8) -> u64 {
    mantissa.wrapping_mul(10).wrapping_add(u64::from(digit))
}

/// std's correctly rounded parser for the rare long numbers; the text holds only digits and `.`.
/// (Cold: kept out of the hot loops that call [`parse_number`].)
#[cold]
fn slow_parse(text: &[u8]) -> Result<f64, NumberError> {
    let text = std::str::from_utf8(text).map_err(|_| NumberError::Invalid)?;
    let value: f64 = text.parse().map_err(|_| NumberError::Invalid)?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(NumberError::Overflow)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_all(text: &str) -> Result<f64, NumberError> {
        let (value, end) = parse_number(text.as_bytes(), 0)?;
        assert_eq!(end, text.len(), "{text}");
        Ok(value)
    }

    #[test]
    fn equals_std_on_typical_values() {
        for text in [
            "94.838",
            "-.54",
            "+5",
            "10.",
            "0",
            "-0",
            "0.2",
            "0.1",
            "0.3",
            "123456789.123456789",
            "0.00000000000000000000001",
            "9007199254740993",
            "17976931348623157",
            "4.35",
            "-82.491",
            "000000000000000000000001.5",
            "1.0000000000000000000000000001",
        ] {
            let ours = parse_all(text).expect(text);
            let std: f64 = text.parse().expect(text);
            assert_eq!(ours.to_bits(), std.to_bits(), "{text}");
        }
    }

    #[test]
    fn rejects_malformed_numbers() {
        assert_eq!(parse_number(b"1.2.3", 0), Err(NumberError::Invalid));
        assert_eq!(parse_number(b"-", 0), Err(NumberError::Invalid));
        assert_eq!(parse_number(b".", 0), Err(NumberError::Invalid));
        assert_eq!(parse_number(b"-.", 0), Err(NumberError::Invalid));
        assert_eq!(parse_number(b"abc", 0), Err(NumberError::Invalid));
    }

    #[test]
    fn huge_integers_overflow() {
        let text = "9".repeat(400);
        assert_eq!(parse_number(text.as_bytes(), 0), Err(NumberError::Overflow));
    }

    #[test]
    fn stops_at_the_next_word() {
        assert_eq!(parse_number(b"94.838Y81.7", 0), Ok((94.838, 6)));
        assert_eq!(parse_number(b"X-1 ", 1), Ok((-1.0, 3)));
    }

    #[test]
    fn digit_runs_of_either_parity_end_where_they_end() {
        // Digits are read two a step: runs of odd and even length, followed by anything or
        // by the end of the bytes.
        for (text, value, end) in [
            ("12.34Y", 12.34, 5),
            ("123.4 ", 123.4, 5),
            ("1234", 1234.0, 4),
            ("12345", 12345.0, 5),
            ("1.", 1.0, 2),
            (".5", 0.5, 2),
            ("9.99\n", 9.99, 4),
        ] {
            assert_eq!(
                parse_number(text.as_bytes(), 0),
                Ok((value, end)),
                "{text:?}"
            );
        }
    }

    /// `parse_number` on `number` followed by `rest` must give std's value, to the bit, and end
    /// where `number` ends (both an error when std rejects `number`).
    fn check_in_context(number: &str, rest: &[u8]) -> Result<(), String> {
        let mut bytes = number.as_bytes().to_vec();
        bytes.extend_from_slice(rest);
        match (parse_number(&bytes, 0), number.parse::<f64>()) {
            (Ok((ours, end)), Ok(std))
                if end == number.len() && ours.to_bits() == std.to_bits() =>
            {
                Ok(())
            }
            (Err(_), Err(_)) => Ok(()),
            (ours, std) => Err(format!("{number:?} + {rest:?}: ours {ours:?}, std {std:?}")),
        }
    }

    #[test]
    fn short_numbers_end_where_the_byte_loop_ends_them() {
        // Read eight bytes at once: every length and dot place, before any terminator.
        let numbers = [
            "7", "12", ".5", "5.", "0.2", "-.54", "+10.", "94.838", "-82.491", "1234567",
        ];
        let longer = [
            "12345678",
            "1234.5678",
            "0.0347212",
            "00000000001.5",
            "-123.45678",
            "1234567.1234567",
            "1002.32686",
            "0.12345678",
        ];
        for number in numbers.into_iter().chain(longer) {
            for rest in [
                &b" "[..],
                b"\n",
                b"\r\n",
                b"Y81.7 E1\n",
                b";c\n",
                b"*12",
                b"\xC3\xA9",
                b"",
            ] {
                assert_eq!(check_in_context(number, rest), Ok(()));
            }
        }
        for bad in ["1.2.3", ".", "-.", "-", "1..", "12.3.4567"] {
            let text = format!("{bad}        ");
            assert_eq!(
                parse_number(text.as_bytes(), 0),
                Err(NumberError::Invalid),
                "{bad}"
            );
        }
    }

    /// The exact decimal text of `odd * 2^-scale`: with `odd` odd, between 2^53 and 2^54, it lies
    /// halfway between two neighbouring doubles (rounded to the even one).
    fn halfway(odd: u64, scale: u32) -> String {
        let digits = (u128::from(odd) * 5u128.pow(scale)).to_string();
        let digits = format!("{digits:0>width$}", width = scale as usize + 1);
        let (int, frac) = digits.split_at(digits.len() - scale as usize);
        format!("{int}.{frac}")
    }

    proptest::proptest! {
        #[test]
        fn matches_std_followed_by_anything(
            sign in "[-+]?",
            int in "0{0,3}[0-9]{0,9}",
            frac in proptest::option::of("[0-9]{0,12}"),
            rest in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..10),
            terminator in "[ \t\r\nXYZEFIJ;*\\-]",
        ) {
            let number = match &frac { Some(f) => format!("{sign}{int}.{f}"), None => format!("{sign}{int}") };
            // A `-` right at the start is no terminator: it begins the number in `rest`.
            proptest::prop_assume!(!(number.is_empty() && terminator == "-"));
            let mut tail = terminator.into_bytes();
            tail.extend(rest);
            proptest::prop_assert_eq!(check_in_context(&number, &tail), Ok(()));
        }

        #[test]
        fn matches_std_on_printed_doubles(
            fraction in 0u64..(1 << 52), exponent in -40i64..40, negative: bool, decimals in 0usize..20,
        ) {
            let bits = (u64::from(negative) << 63) | (((1023 + exponent) as u64) << 52) | fraction;
            let value = f64::from_bits(bits);
            for number in [format!("{value}"), format!("{value:.decimals$}")] {
                proptest::prop_assert_eq!(check_in_context(&number, b" E1\n"), Ok(()));
            }
        }

        #[test]
        fn matches_std_at_and_beside_halfway_points(half in (1u64 << 52)..(1 << 53), scale in 0u32..=20) {
            let exact = halfway(2 * half + 1, scale);
            let above = format!("{exact}1");
            // The exact text ends in 5 (with a fraction): a little below it.
            let below = match exact.strip_suffix('5') {
                Some(head) => format!("{head}49999"),
                None => exact.clone(),
            };
            for number in [exact, above, below] {
                proptest::prop_assert_eq!(check_in_context(&number, b"\n"), Ok(()));
            }
        }

        #[test]
        fn matches_std_for_any_decimal(int in "[0-9]{0,25}", frac in proptest::option::of("[0-9]{0,30}"), sign in "[-+]?") {
            let text = match &frac { Some(f) => format!("{sign}{int}.{f}"), None => format!("{sign}{int}") };
            let std: Result<f64, _> = text.parse::<f64>();
            match (parse_number(text.as_bytes(), 0), std) {
                (Ok((ours, end)), Ok(std)) => {
                    proptest::prop_assert_eq!(end, text.len());
                    proptest::prop_assert_eq!(ours.to_bits(), std.to_bits());
                }
                (Err(_), Err(_)) => {}
                (ours, std) => proptest::prop_assert!(false, "{text}: ours {ours:?}, std {std:?}"),
            }
        }
    }
}
