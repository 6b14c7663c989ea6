//! The C boundary's own rules: no panic crosses it (`guarded`), numbers no machine can have are refused with the
//! value named, caps reach Klipper only positive and finite, and the caller's buffers are written safely.

use std::any::Any;
use std::ffi::c_char;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::ptr;

/// Coordinates beyond this magnitude (mm, a thousand kilometres) are refused at the boundary: no machine reaches
/// them, and squared they leave nothing of a millimetre in an f64.
pub const MAX_COORDINATE: f64 = 1e9;

/// A caller's error buffer (pointer and length), or [`NO_BUFFER`].
type ErrorBuffer = (*mut c_char, usize);
pub(crate) const NO_BUFFER: ErrorBuffer = (ptr::null_mut(), 0);

/// Runs an entry point's work so that a panic never crosses the C boundary (it would abort Klipper): on a panic,
/// the reason goes into `error` (if there is one) and the function answers `failure`, its documented failure value.
/// The success path costs nothing beyond the call (no allocation), so the per-step solver uses it too.
pub(crate) fn guarded<T>(failure: T, error: ErrorBuffer, f: impl FnOnce() -> T) -> T {
    // Unwind safety: the work only reads the immutable machine (or the solver's plain data) and writes the
    // caller's buffers, which the failure value tells the caller not to read; nothing half-updated is used again.
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(value) => value,
        Err(payload) => {
            if !error.0.is_null() {
                let reason = format!(
                    "internal error in jointspace (please report it with the move or config): {}",
                    panic_text(payload.as_ref())
                );
                write_message(&reason, error.0, error.1);
            }
            failure
        }
    }
}

/// The message a panic carried.
fn panic_text(payload: &(dyn Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("panic")
}

/// The reason a move's numbers cannot be a move on any machine: a coordinate that is not finite or is beyond
/// [`MAX_COORDINATE`], a speed or acceleration that is not finite (≤ 0 is allowed: `check_move` then checks the
/// segment only).
pub fn usable_move(start: [f64; 3], end: [f64; 3], speed: f64, accel: f64) -> Result<(), String> {
    usable_point(start)?;
    usable_point(end)?;
    for (name, v) in [("speed", speed), ("accel", accel)] {
        if !v.is_finite() {
            return Err(format!("{name}={v} is not a finite number"));
        }
    }
    Ok(())
}

/// The reason a point cannot be on any machine: a coordinate that is not finite or is beyond [`MAX_COORDINATE`].
pub fn usable_point(p: [f64; 3]) -> Result<(), String> {
    for (axis, v) in ["X", "Y", "Z"].into_iter().zip(p) {
        if !v.is_finite() {
            return Err(format!("{axis}={v} is not a finite coordinate"));
        }
        if v.abs() > MAX_COORDINATE {
            return Err(format!("{axis}={v:e} mm is beyond any machine"));
        }
    }
    Ok(())
}

/// Writes `message` into the caller's buffer (truncated, always NUL-terminated).
pub(crate) fn write_message(message: &str, buffer: *mut c_char, length: usize) {
    if buffer.is_null() || length == 0 {
        return;
    }
    let bytes = message.as_bytes();
    let n = bytes.len().min(length - 1);
    // SAFETY: the caller promises `buffer` holds `length` bytes; n + 1 ≤ length.
    unsafe {
        ptr::copy_nonoverlapping(bytes.as_ptr(), buffer.cast::<u8>(), n);
        *buffer.add(n) = 0;
    }
}

/// Reads three doubles from a caller's array.
///
/// # Safety
/// `p` points to at least three doubles.
pub(crate) unsafe fn read3(p: *const f64) -> [f64; 3] {
    // SAFETY: per the contract.
    unsafe { [*p, *p.add(1), *p.add(2)] }
}

#[cfg(test)]
mod tests {
    use std::ffi::{CStr, c_int};

    use super::*;

    #[test]
    fn a_panic_becomes_the_failure_value_with_its_reason() {
        let mut error = [0 as c_char; 160];
        let rc = guarded(-1, (error.as_mut_ptr(), error.len()), || -> c_int {
            panic!("a bug at the straight arm")
        });
        assert_eq!(rc, -1);
        // SAFETY: write_message NUL-terminates within the buffer.
        let reason = unsafe { CStr::from_ptr(error.as_ptr()) }.to_string_lossy();
        assert!(
            reason.starts_with("internal error in jointspace"),
            "{reason}"
        );
        assert!(reason.contains("a bug at the straight arm"), "{reason}");
        let formatted = guarded(f64::INFINITY, NO_BUFFER, || -> f64 { panic!("{}", 1 + 1) });
        assert_eq!(formatted, f64::INFINITY);
        assert_eq!(guarded(-1, NO_BUFFER, || 7), 7);
    }

    #[test]
    fn unusable_numbers_are_named() {
        let ok = [1.0, 2.0, 3.0];
        let named = |start, end, speed, accel| usable_move(start, end, speed, accel).err();
        assert_eq!(named(ok, ok, 100.0, 3000.0), None);
        assert_eq!(
            named(ok, ok, 0.0, -1.0),
            None,
            "≤ 0 checks the segment only"
        );
        assert_eq!(
            named([f64::INFINITY, 0.0, 0.0], ok, 100.0, 3000.0).as_deref(),
            Some("X=inf is not a finite coordinate")
        );
        assert_eq!(
            named(ok, [0.0, 0.0, 1e200], 100.0, 3000.0).as_deref(),
            Some("Z=1e200 mm is beyond any machine")
        );
        assert_eq!(
            named(ok, [0.0, -2e9, 0.0], 100.0, 3000.0).as_deref(),
            Some("Y=-2e9 mm is beyond any machine")
        );
        assert_eq!(named(ok, [1e9, -1e9, 0.0], 100.0, 3000.0), None);
        assert_eq!(
            named(ok, ok, f64::NAN, 3000.0).as_deref(),
            Some("speed=NaN is not a finite number")
        );
    }
}
