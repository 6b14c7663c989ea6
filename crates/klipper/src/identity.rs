//! What the library is: its version, the commit it was built from, and the hash of the header it was built from
//! (`klipper/jointspace_klipper/jointspace.h`), each answered through the C interface so the plug-in refuses a
//! library that is not its own and reports what it runs.

use std::ffi::{CStr, c_char};

use crate::boundary::{NO_BUFFER, guarded};

/// The library's version, `"jointspace-klipper X.Y.Z"`.
const VERSION: &CStr = concat_c_version();

const fn concat_c_version() -> &'static CStr {
    match CStr::from_bytes_with_nul(
        concat!("jointspace-klipper ", env!("CARGO_PKG_VERSION"), "\0").as_bytes(),
    ) {
        Ok(v) => v,
        Err(_) => c"jointspace-klipper",
    }
}

/// The commit the library was built from (build.rs: 12 hex digits, or `"unknown"`).
const COMMIT: &CStr =
    match CStr::from_bytes_with_nul(concat!(env!("JOINTSPACE_COMMIT"), "\0").as_bytes()) {
        Ok(c) => c,
        Err(_) => c"unknown",
    };

const HEADER: &[u8] = include_bytes!("../../../klipper/jointspace_klipper/jointspace.h");

/// FNV-1a (64-bit) of `klipper/jointspace_klipper/jointspace.h` as this library was built from it.
const HEADER_HASH: u64 = fnv1a(HEADER);

// The header names the version it belongs to (the plug-in refuses a library of another version): a version bump
// without the header's fails the build rather than every printer's start.
const _: () = assert!(
    contains(
        HEADER,
        concat!(
            "#define JOINTSPACE_VERSION \"",
            env!("CARGO_PKG_VERSION"),
            "\"\n"
        )
        .as_bytes()
    ),
    "klipper/jointspace_klipper/jointspace.h's JOINTSPACE_VERSION is not this crate's version"
);

const fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    let mut start = 0;
    while start + needle.len() <= haystack.len() {
        let mut i = 0;
        while i < needle.len() && haystack[start + i] == needle[i] {
            i += 1;
        }
        if i == needle.len() {
            return true;
        }
        start += 1;
    }
    false
}

const fn fnv1a(bytes: &[u8]) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325_u64;
    let mut i = 0;
    while i < bytes.len() {
        hash = (hash ^ bytes[i] as u64).wrapping_mul(0x0100_0000_01b3);
        i += 1;
    }
    hash
}

/// The hash of the C interface's header this library was built from: the Python side hashes the header it hands
/// cffi and refuses a library built from another (a plug-in updated without rebuilding its library).
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_header_hash() -> u64 {
    HEADER_HASH
}

/// The library version string (static).
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_version() -> *const c_char {
    guarded(c"".as_ptr(), NO_BUFFER, || VERSION.as_ptr())
}

/// The commit the library was built from (static): 12 hex digits, or "unknown" when built without git.
#[unsafe(no_mangle)]
pub extern "C" fn jointspace_commit() -> *const c_char {
    guarded(c"".as_ptr(), NO_BUFFER, || COMMIT.as_ptr())
}
