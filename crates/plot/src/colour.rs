//! Colours and colour scales (a perceptually ordered blue–green–yellow map, linear or logarithmic).

/// An sRGB colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    pub const BLACK: Rgb = Rgb(0, 0, 0);
    pub const WHITE: Rgb = Rgb(255, 255, 255);
    /// Cells with no value (unreachable).
    pub const NO_DATA: Rgb = Rgb(205, 205, 205);
    pub const AXIS: Rgb = Rgb(60, 60, 60);
    pub const GRID: Rgb = Rgb(232, 232, 232);

    /// `#rrggbb`.
    pub fn hex(self) -> String {
        format!("#{:02x}{:02x}{:02x}", self.0, self.1, self.2)
    }
}

/// Control points of the colour map (viridis-like: dark blue, teal, green, yellow).
const MAP: [(f64, Rgb); 9] = [
    (0.0, Rgb(68, 1, 84)),
    (0.125, Rgb(71, 44, 122)),
    (0.25, Rgb(59, 81, 139)),
    (0.375, Rgb(44, 113, 142)),
    (0.5, Rgb(33, 144, 141)),
    (0.625, Rgb(39, 173, 129)),
    (0.75, Rgb(92, 200, 99)),
    (0.875, Rgb(170, 220, 50)),
    (1.0, Rgb(253, 231, 37)),
];

/// Colour at `f ∈ [0, 1]` (clamped).
pub fn colour_map(f: f64) -> Rgb {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let i = MAP
        .iter()
        .position(|(x, _)| *x >= f)
        .unwrap_or(MAP.len() - 1)
        .max(1);
    let ((x0, c0), (x1, c1)) = (MAP[i - 1], MAP[i]);
    let w = if x1 > x0 { (f - x0) / (x1 - x0) } else { 0.0 };
    let mix = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * w).round() as u8;
    Rgb(mix(c0.0, c1.0), mix(c0.1, c1.1), mix(c0.2, c1.2))
}

/// Number of colour bands of heat maps (finer than the eye separates on the colour bar).
pub const COLOUR_LEVELS: usize = 96;

/// Maps values to colours, with a label (quantity and unit) for the colour bar.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourScale {
    pub min: f64,
    pub max: f64,
    pub label: String,
    /// Logarithmic scale (needs `min > 0`); for values that span orders of magnitude.
    pub log: bool,
}

impl ColourScale {
    /// A scale spanning the finite values given; logarithmic when they are positive and span more than 20×.
    pub fn fit(values: impl IntoIterator<Item = f64>, label: impl Into<String>) -> Self {
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values.into_iter().filter(|v| v.is_finite()) {
            min = min.min(v);
            max = max.max(v);
        }
        if min > max {
            (min, max) = (0.0, 1.0);
        } else if max - min <= 1e-9 * max.abs().max(min.abs()) {
            // A constant (up to rounding noise): centre it on a ±10 % scale rather than stretch the noise.
            let v = 0.5 * (min + max);
            let half = if v == 0.0 { 1.0 } else { 0.1 * v.abs() };
            (min, max) = (v - half, v + half);
        }
        let log = min > 0.0 && max / min > 20.0;
        ColourScale {
            min,
            max,
            label: label.into(),
            log,
        }
    }

    /// Position of `v` on the scale, 0..1 (clamped).
    pub fn fraction(&self, v: f64) -> f64 {
        let (lo, hi, x) = if self.log && self.min > 0.0 {
            (self.min.ln(), self.max.ln(), v.max(f64::MIN_POSITIVE).ln())
        } else {
            (self.min, self.max, v)
        };
        if hi > lo {
            ((x - lo) / (hi - lo)).clamp(0.0, 1.0)
        } else {
            0.5
        }
    }

    /// Value at position `f ∈ [0, 1]` of the scale.
    pub fn value_at(&self, f: f64) -> f64 {
        if self.log && self.min > 0.0 {
            (self.min.ln() + f * (self.max.ln() - self.min.ln())).exp()
        } else {
            self.min + f * (self.max - self.min)
        }
    }

    pub fn colour(&self, v: f64) -> Rgb {
        colour_map(self.fraction(v))
    }

    /// Colour from one of [`COLOUR_LEVELS`] bands: neighbouring heat-map cells of nearly equal value share
    /// a colour, so runs merge into one SVG rectangle (a 2-mm polar map: 6.4 MB → under 1 MB).
    pub fn banded_colour(&self, v: f64) -> Rgb {
        let levels = COLOUR_LEVELS as f64;
        colour_map(((self.fraction(v) * levels).floor().min(levels - 1.0) + 0.5) / levels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_ends_and_clamping() {
        assert_eq!(colour_map(0.0), Rgb(68, 1, 84));
        assert_eq!(colour_map(1.0), Rgb(253, 231, 37));
        assert_eq!(colour_map(7.0), Rgb(253, 231, 37));
        assert_eq!(colour_map(f64::NAN), Rgb(68, 1, 84));
    }

    #[test]
    fn constant_values_get_a_centred_scale() {
        let s = ColourScale::fit([0.0125, 0.0125 + 1e-17, 0.0125 - 1e-17], "mm");
        assert!(!s.log);
        assert!((s.fraction(0.0125) - 0.5).abs() < 1e-6);
        assert_eq!(s.banded_colour(0.0125), s.banded_colour(0.0125 + 1e-17));
    }

    #[test]
    fn log_scale_puts_the_geometric_mean_in_the_middle() {
        let s = ColourScale::fit([0.001, 0.1], "mm");
        assert!(s.log);
        assert!((s.fraction(0.01) - 0.5).abs() < 1e-12);
        assert!((s.value_at(0.5) - 0.01).abs() < 1e-12);
        assert_eq!(Rgb(1, 2, 255).hex(), "#0102ff");
    }
}
