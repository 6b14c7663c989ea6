//! The page's bulk data: little-endian typed arrays written as base64 into `<script type="application/octet-stream">`
//! elements, which the page decodes into `Float32Array`, `Uint16Array`, `Uint32Array` or `Uint8Array`.

use std::io::{self, Write};

const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 (with padding) of `bytes`.
pub fn base64(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        let digits = [18, 12, 6, 0].map(|shift| ALPHABET[(n >> shift & 63) as usize] as char);
        let kept = chunk.len() + 1;
        out.extend(&digits[..kept]);
        out.extend(std::iter::repeat_n('=', 4 - kept));
    }
    out
}

/// One typed array of the page.
#[derive(Debug, Clone, PartialEq)]
pub enum Array {
    F32(Vec<f32>),
    U16(Vec<u16>),
    U32(Vec<u32>),
    U8(Vec<u8>),
}

impl Array {
    fn bytes(&self) -> Vec<u8> {
        match self {
            Array::F32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Array::U16(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Array::U32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Array::U8(v) => v.clone(),
        }
    }

    fn kind(&self) -> &'static str {
        match self {
            Array::F32(_) => "f32",
            Array::U16(_) => "u16",
            Array::U32(_) => "u32",
            Array::U8(_) => "u8",
        }
    }

    pub fn len(&self) -> usize {
        match self {
            Array::F32(v) => v.len(),
            Array::U16(v) => v.len(),
            Array::U32(v) => v.len(),
            Array::U8(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// `value / full` as a 16-bit fraction (0 when there is no scale).
pub fn fraction(value: f64, full: f64) -> u16 {
    if full > 0.0 && value.is_finite() {
        (value / full * 65535.0).round().clamp(0.0, 65535.0) as u16
    } else {
        0
    }
}

/// `<script type="application/octet-stream" id="d-NAME" data-type="…">base64</script>`, written in pieces.
pub fn write_array(w: &mut dyn Write, name: &str, array: &Array) -> io::Result<()> {
    write!(
        w,
        "<script type=\"application/octet-stream\" id=\"d-{name}\" data-type=\"{}\">",
        array.kind()
    )?;
    // Whole groups of three bytes per piece, so the pieces join into one base64 text.
    for piece in array.bytes().chunks(3 << 16) {
        w.write_all(base64(piece).as_bytes())?;
    }
    w.write_all(b"</script>\n")
}

/// JSON that can sit inside a `<script>` element (no `</script>` or `<!--` in it).
pub fn script_json(value: &serde_json::Value) -> String {
    value
        .to_string()
        .replace('<', "\\u003c")
        .replace('>', "\\u003e")
        .replace('&', "\\u0026")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_as_rfc_4648_writes_it() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(base64(&[0xff, 0xfe, 0xfd, 0x00]), "//79AA==");
    }

    #[test]
    fn json_in_a_script_cannot_close_it() {
        let value = serde_json::json!({"name": "</script><!-- & >"});
        let text = script_json(&value);
        assert!(!text.contains('<') && !text.contains('>'));
        let back: serde_json::Value = serde_json::from_str(&text).expect("still JSON");
        assert_eq!(back, value);
    }

    #[test]
    fn fractions_fill_sixteen_bits() {
        assert_eq!(fraction(5.0, 10.0), 32768);
        assert_eq!(fraction(20.0, 10.0), 65535);
        assert_eq!(fraction(1.0, 0.0), 0);
    }
}
