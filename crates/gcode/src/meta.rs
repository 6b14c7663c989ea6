//! Slicer metadata in comments: layer changes, feature types and object markers, as each slicer writes
//! them (PrusaSlicer/SuperSlicer/Orca `;LAYER_CHANGE` + `;Z:`, Cura `;LAYER:n` and `;TYPE:`, Bambu
//! `; CHANGE_LAYER` + `; Z_HEIGHT:` and `; FEATURE:`, Simplify3D `; layer n, Z = z` and `; feature …`,
//! KISSlicer `; BEGIN_LAYER_OBJECT z=…` and `; 'Perimeter', …`, PrusaSlicer `; printing object …`), and the
//! slicer's own time estimate (PrusaSlicer/SuperSlicer/Orca/Bambu `; estimated printing time (normal mode) = …`,
//! Cura `;TIME:` and `;TIME_ELAPSED:`, Simplify3D `; Build time: …`, KISSlicer `; Estimated Build Time: …`).
//! Only comments whose first letter can start one of these prefixes are examined further.

use crate::command::Meta;

/// What a comment says.
#[derive(Debug, Clone, PartialEq)]
pub enum CommentMeta {
    /// Complete metadata.
    Meta(Meta),
    /// A layer starts; its Z follows in a later comment (`;Z:` / `; Z_HEIGHT:`).
    LayerStart,
    /// The Z of the layer just started.
    LayerZ(f64),
}

/// The bytes that may begin (after blanks) a comment [`comment_meta`] recognises.
const META_FIRST_BYTES: &[u8] = b"LZTCFflBps'eE";

/// [`META_FIRST_BYTES`] as a table, for one look-up per comment.
const MAY_START_META: [bool; 256] = {
    let mut table = [false; 256];
    let mut i = 0;
    while i < META_FIRST_BYTES.len() {
        table[META_FIRST_BYTES[i] as usize] = true;
        i += 1;
    }
    table
};

/// False when a comment whose text (after blanks) begins with `first` can hold no metadata: a
/// quick test that lets the reader skip most comments without looking further.
pub fn may_start_meta(first: u8) -> bool {
    MAY_START_META[usize::from(first)]
}

/// Recognises metadata in a `;` comment's text (the text after `;`).
pub fn comment_meta(text: &str) -> Option<CommentMeta> {
    let text = text.trim_start_matches([' ', '\t']);
    let first = *text.as_bytes().first()?;
    if !may_start_meta(first) {
        return None;
    }
    match first {
        b'L' => layer_upper(text),
        b'Z' => layer_z(text),
        b'T' => text
            .strip_prefix("TYPE:")
            .map(feature)
            .or_else(|| cura_time(text)),
        b'C' => (text.trim_end() == "CHANGE_LAYER").then_some(CommentMeta::LayerStart),
        b'F' => text.strip_prefix("FEATURE:").map(feature),
        b'f' => text.strip_prefix("feature ").map(feature),
        b'l' => simplify3d_layer(text),
        b'B' => kisslicer_layer(text).or_else(|| simplify3d_time(text)),
        b'e' => prusa_time(text),
        b'E' => kisslicer_time(text),
        b'\'' => kisslicer_feature(text),
        b'p' => {
            object_name(text, "printing object ").map(|n| CommentMeta::Meta(Meta::ObjectStart(n)))
        }
        b's' => object_name(text, "stop printing object ")
            .map(|n| CommentMeta::Meta(Meta::ObjectEnd(n))),
        _ => None,
    }
}

fn feature(name: &str) -> CommentMeta {
    CommentMeta::Meta(Meta::Feature(name.trim().to_owned()))
}

/// `LAYER_CHANGE` (Prusa) or `LAYER:n` (Cura).
fn layer_upper(text: &str) -> Option<CommentMeta> {
    if text.trim_end() == "LAYER_CHANGE" {
        return Some(CommentMeta::LayerStart);
    }
    let index = text.strip_prefix("LAYER:")?.trim().parse::<i64>().ok()?;
    Some(CommentMeta::Meta(Meta::LayerChange {
        index: Some(index),
        z: None,
    }))
}

/// `Z:0.2` (Prusa) or `Z_HEIGHT: 0.2` (Bambu).
fn layer_z(text: &str) -> Option<CommentMeta> {
    let value = text
        .strip_prefix("Z:")
        .or_else(|| text.strip_prefix("Z_HEIGHT:"))?;
    finite(value).map(CommentMeta::LayerZ)
}

/// `layer 3, Z = 0.720` (Simplify3D).
fn simplify3d_layer(text: &str) -> Option<CommentMeta> {
    let (index, z) = text.strip_prefix("layer ")?.split_once(", Z = ")?;
    let index = index.trim().parse::<i64>().ok()?;
    let z = finite(z)?;
    Some(CommentMeta::Meta(Meta::LayerChange {
        index: Some(index),
        z: Some(z),
    }))
}

/// `BEGIN_LAYER_OBJECT z=0.50` (KISSlicer).
fn kisslicer_layer(text: &str) -> Option<CommentMeta> {
    let z = finite(text.strip_prefix("BEGIN_LAYER_OBJECT z=")?)?;
    Some(CommentMeta::Meta(Meta::LayerChange {
        index: None,
        z: Some(z),
    }))
}

/// `'Perimeter', 0.2 [feed mm/s], 11.5 [head mm/s]` (KISSlicer); a bare `'name'` is not a feature.
fn kisslicer_feature(text: &str) -> Option<CommentMeta> {
    let (name, rest) = text[1..].split_once('\'')?;
    rest.starts_with(',').then(|| feature(name))
}

/// Cura's `TIME:1479` (the whole print) and `TIME_ELAPSED:12.5` (up to here), seconds.
fn cura_time(text: &str) -> Option<CommentMeta> {
    if let Some(value) = text.strip_prefix("TIME_ELAPSED:") {
        return finite(value).map(|s| CommentMeta::Meta(Meta::TimeElapsed(s)));
    }
    let seconds = finite(text.strip_prefix("TIME:")?)?;
    Some(estimate(seconds, false))
}

fn estimate(seconds: f64, silent: bool) -> CommentMeta {
    CommentMeta::Meta(Meta::PrintTimeEstimate { seconds, silent })
}

/// `estimated printing time (normal mode) = 1d 2h 3m 4s` (PrusaSlicer, SuperSlicer, OrcaSlicer, Bambu Studio);
/// `(silent mode)` is PrusaSlicer's stealth-mode estimate.
fn prusa_time(text: &str) -> Option<CommentMeta> {
    let rest = text.strip_prefix("estimated printing time (")?;
    let (mode, value) = rest.split_once(") =")?;
    let silent = match mode {
        "normal mode" => false,
        "silent mode" => true,
        _ => return None,
    };
    Some(estimate(dhms_seconds(value)?, silent))
}

/// Seconds of a duration written `1d 2h 3m 4s` (any of the parts, in that order).
pub fn dhms_seconds(text: &str) -> Option<f64> {
    let mut total = 0.0;
    let mut any = false;
    for part in text.split_whitespace() {
        let unit = part.chars().last()?;
        let scale = match unit {
            'd' => 86_400.0,
            'h' => 3_600.0,
            'm' => 60.0,
            's' => 1.0,
            _ => return None,
        };
        total += finite(&part[..part.len() - 1])? * scale;
        any = true;
    }
    any.then_some(total)
}

/// `Build time: 0 hours 31 minutes` (Simplify3D).
fn simplify3d_time(text: &str) -> Option<CommentMeta> {
    let rest = text.strip_prefix("Build time:")?;
    let words: Vec<&str> = rest.split_whitespace().collect();
    let mut seconds = 0.0;
    for pair in words.chunks(2) {
        let [value, unit] = pair else { return None };
        let scale = match unit.trim_end_matches('s') {
            "hour" => 3_600.0,
            "minute" => 60.0,
            "second" => 1.0,
            _ => return None,
        };
        seconds += finite(value)? * scale;
    }
    (!words.is_empty()).then(|| estimate(seconds, false))
}

/// `Estimated Build Time:   7.01 minutes` (KISSlicer).
fn kisslicer_time(text: &str) -> Option<CommentMeta> {
    let rest = text.strip_prefix("Estimated Build Time:")?;
    let minutes = finite(rest.trim().strip_suffix("minutes")?)?;
    Some(estimate(minutes * 60.0, false))
}

fn object_name(text: &str, prefix: &str) -> Option<String> {
    text.strip_prefix(prefix).map(|name| name.trim().to_owned())
}

/// A finite decimal (comment values are not G-code words, so std's parser is fine here).
fn finite(text: &str) -> Option<f64> {
    text.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(text: &str) -> Option<CommentMeta> {
        comment_meta(text)
    }

    #[test]
    fn slicer_layer_markers() {
        assert_eq!(meta("LAYER_CHANGE"), Some(CommentMeta::LayerStart));
        assert_eq!(meta("Z:0.2"), Some(CommentMeta::LayerZ(0.2)));
        assert_eq!(meta(" CHANGE_LAYER"), Some(CommentMeta::LayerStart));
        assert_eq!(meta(" Z_HEIGHT: 0.4"), Some(CommentMeta::LayerZ(0.4)));
        assert_eq!(
            meta("LAYER:12"),
            Some(CommentMeta::Meta(Meta::LayerChange {
                index: Some(12),
                z: None
            }))
        );
        assert_eq!(
            meta(" layer 2, Z = 0.720"),
            Some(CommentMeta::Meta(Meta::LayerChange {
                index: Some(2),
                z: Some(0.72)
            }))
        );
        assert_eq!(
            meta(" BEGIN_LAYER_OBJECT z=0.50"),
            Some(CommentMeta::Meta(Meta::LayerChange {
                index: None,
                z: Some(0.5)
            }))
        );
        assert_eq!(meta("LAYER_COUNT:10"), None);
        assert_eq!(meta(" layer end"), None);
        assert_eq!(meta(" END_LAYER_OBJECT z=0.50"), None);
    }

    #[test]
    fn features_and_objects() {
        let feature = |s: &str| Some(CommentMeta::Meta(Meta::Feature(s.to_owned())));
        assert_eq!(meta("TYPE:WALL-OUTER"), feature("WALL-OUTER"));
        assert_eq!(meta(" FEATURE: Outer wall"), feature("Outer wall"));
        assert_eq!(meta(" feature inner perimeter"), feature("inner perimeter"));
        assert_eq!(
            meta(" 'Loop', 0.5 [feed mm/s], 29.8 [head mm/s]"),
            feature("Loop")
        );
        assert_eq!(meta(" 'cube.gcode'"), None);
        assert_eq!(
            meta(" printing object Vase.stl id:0 copy 0"),
            Some(CommentMeta::Meta(Meta::ObjectStart(
                "Vase.stl id:0 copy 0".to_owned()
            )))
        );
        assert_eq!(
            meta(" stop printing object Vase.stl id:0 copy 0"),
            Some(CommentMeta::Meta(Meta::ObjectEnd(
                "Vase.stl id:0 copy 0".to_owned()
            )))
        );
        assert_eq!(meta(" printing_by_object_gcode = "), None);
    }

    #[test]
    fn slicer_time_estimates() {
        let total = |s: f64, silent| {
            Some(CommentMeta::Meta(Meta::PrintTimeEstimate {
                seconds: s,
                silent,
            }))
        };
        assert_eq!(
            meta(" estimated printing time (normal mode) = 1h 6m 40s"),
            total(4000.0, false)
        );
        assert_eq!(
            meta(" estimated printing time (normal mode) = 34s"),
            total(34.0, false)
        );
        assert_eq!(
            meta(" estimated printing time (silent mode) = 1d 3m 47s"),
            total(86_400.0 + 227.0, true)
        );
        assert_eq!(meta("TIME:1479"), total(1479.0, false));
        assert_eq!(
            meta("TIME_ELAPSED:12.5"),
            Some(CommentMeta::Meta(Meta::TimeElapsed(12.5)))
        );
        assert_eq!(
            meta("   Build time: 0 hours 31 minutes"),
            total(1860.0, false)
        );
        assert_eq!(
            meta(" Estimated Build Time:   7.5 minutes"),
            total(450.0, false)
        );
        assert_eq!(meta(" estimated printing time (first layer) = 5s"), None);
        assert_eq!(meta(" estimated printing time (normal mode) = soon"), None);
        assert_eq!(meta("TIME:"), None);
        assert_eq!(meta(" Estimated Build Volume: 0.681 cm^3"), None);
        assert_eq!(meta(" extrusion_multiplier = 1"), None);
    }
}
