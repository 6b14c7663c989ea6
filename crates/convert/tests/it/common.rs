//! Shared helpers: locating the shared corpus, placing a part on a machine, converting and verifying.

use std::path::PathBuf;

use convert::{
    AxisMap, ConvertOptions, ConvertStats, Converter, VerifyReport, convert_gcode, read_commands,
    verify,
};
use gcode::Command;

/// `../shared` next to the workspace, if present.
pub fn shared() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared");
    if dir.is_dir() {
        Some(dir)
    } else {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "{} is absent, and JOINTSPACE_REQUIRE_SHARED says it must be there (CI)",
            dir.display()
        );
        println!("SKIPPED: {} is absent", dir.display());
        None
    }
}

/// Every corpus file, sorted by name: `(name, text)`.
pub fn corpus_files() -> Vec<(String, Vec<u8>)> {
    let Some(dir) = shared() else {
        return Vec::new();
    };
    let mut files: Vec<_> = std::fs::read_dir(dir.join("corpus"))
        .map(|entries| entries.filter_map(Result::ok).map(|e| e.path()).collect())
        .unwrap_or_default();
    files.sort();
    let read: Vec<(String, Vec<u8>)> = files
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "gcode"))
        .filter_map(|p| {
            Some((
                p.file_name()?.to_string_lossy().into_owned(),
                std::fs::read(&p).ok()?,
            ))
        })
        .collect();
    // A corpus loop over fewer files than the corpus holds would pass by not looking.
    assert!(
        read.len() >= CORPUS_FILES,
        "{} corpus files read, the corpus holds {CORPUS_FILES}",
        read.len()
    );
    read
}

/// How many G-code files `../shared/corpus` holds.
const CORPUS_FILES: usize = 10;

/// XY bounding box `(min, max)` of all move targets.
pub fn bounding_box(commands: &[Command]) -> ([f64; 2], [f64; 2]) {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in commands {
        let xy = match c {
            Command::Move(m) => [m.target[0], m.target[1]],
            Command::Arc(a) => [a.target[0], a.target[1]],
            _ => continue,
        };
        for i in 0..2 {
            lo[i] = lo[i].min(xy[i]);
            hi[i] = hi[i].max(xy[i]);
        }
    }
    (lo, hi)
}

/// Scale and offset that put the box centre at `at` with every corner within `radius` of it.
pub fn placement(commands: &[Command], at: [f64; 2], radius: f64) -> (f64, [f64; 2]) {
    let (lo, hi) = bounding_box(commands);
    let half_diagonal = (hi[0] - lo[0]).hypot(hi[1] - lo[1]) / 2.0;
    let scale = if half_diagonal > radius {
        radius / half_diagonal
    } else {
        1.0
    };
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    (
        scale,
        [at[0] - centre[0] * scale, at[1] - centre[1] * scale],
    )
}

pub fn convert_text(
    map: &AxisMap,
    options: &ConvertOptions,
    text: &[u8],
) -> Result<(String, ConvertStats), convert::ConvertError> {
    let mut converter = Converter::new(map.clone(), options.clone(), Vec::new())?;
    convert_gcode(text, "test.gcode", &mut converter)?;
    let (out, stats) = converter.finish()?;
    Ok((String::from_utf8(out).expect("output is UTF-8"), stats))
}

/// Converts `text` and verifies the output against it.
pub fn round_trip(
    map: &AxisMap,
    options: &ConvertOptions,
    text: &[u8],
) -> (String, ConvertStats, VerifyReport) {
    let (out, stats) = convert_text(map, options, text).expect("conversion succeeds");
    let commands = read_commands(text, "test.gcode").expect("input parses");
    let report = verify(map, options, &commands, out.as_bytes()).expect("output readable");
    (out, stats, report)
}

/// A written line: its command word and its `letter value` words (comments dropped).
pub fn parse_line(line: &str) -> Option<(String, Vec<(char, f64)>)> {
    let code = line.split(';').next()?.trim();
    let mut parts = code.split_ascii_whitespace();
    let head = parts.next()?.to_string();
    // Words without a number (`G28 X`) are left out.
    let words = parts
        .filter_map(|w| {
            let mut chars = w.chars();
            let letter = chars.next()?;
            Some((letter, chars.as_str().parse::<f64>().ok()?))
        })
        .collect();
    Some((head, words))
}

pub fn word(words: &[(char, f64)], letter: char) -> Option<f64> {
    words.iter().find(|(l, _)| *l == letter).map(|(_, v)| *v)
}

/// The `G1` lines of an output, parsed.
pub fn g1_lines(out: &str) -> Vec<Vec<(char, f64)>> {
    out.lines()
        .filter_map(parse_line)
        .filter(|(head, _)| head == "G1")
        .map(|(_, w)| w)
        .collect()
}

/// Default options on a machine homed at Z 0 (`home`: the tests' prints start with an XY move and set Z later,
/// as a homed printer runs them; without a homing pose the converter refuses to guess Z).
pub fn homed() -> ConvertOptions {
    ConvertOptions {
        home: Some([0.0, 0.0, 0.0]),
        ..ConvertOptions::default()
    }
}
