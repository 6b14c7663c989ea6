//! jointspace's own test prints: the demo's slicer-like print (rings, a square, a star and an arc, with layer
//! markers and feature types: [`TestPrint`]) and the simulator's measurement print (circles and squares whose
//! roundness, sides and corners the deviation metrics fit: [`test_print_gcode`]), on the same geometry helpers.

use std::f64::consts::TAU;
use std::fmt::Write;

/// Where and how large to print.
#[derive(Debug, Clone, Copy)]
pub struct TestPrint {
    /// Centre of the print on the bed (mm).
    pub centre: [f64; 2],
    /// Outer ring radius (mm); the other features scale with it.
    pub size: f64,
    pub layers: u32,
    pub first_layer_z: f64,
    pub layer_height: f64,
    /// Printing and travel speeds (mm/s).
    pub print_speed: f64,
    pub travel_speed: f64,
}

impl TestPrint {
    pub fn new(centre: [f64; 2], size: f64) -> Self {
        TestPrint {
            centre,
            size,
            layers: 4,
            first_layer_z: 0.3,
            layer_height: 0.2,
            print_speed: 60.0,
            travel_speed: 150.0,
        }
    }

    /// The G-code text.
    pub fn gcode(&self) -> String {
        let mut g = Gcode::new(self);
        g.header();
        for layer in 0..self.layers {
            let z = self.first_layer_z + f64::from(layer) * self.layer_height;
            g.line(&format!(";LAYER_CHANGE\n;Z:{z:.3}\nG1 Z{z:.3} F600"));
            g.feature("Outer wall");
            g.polygon(&circle(self.centre, self.size, 120));
            g.feature("Inner wall");
            g.polygon(&circle(self.centre, 0.75 * self.size, 90));
            g.feature("Square");
            let half = 0.45 * self.size;
            g.polygon(&square(self.centre, half));
            g.feature("Star");
            g.polygon(&star(self.centre, 0.4 * self.size, 0.2 * self.size, 5));
            g.feature("Arc");
            g.arc(self.centre, 0.6 * self.size);
        }
        g.footer();
        g.text
    }
}

/// A test print: `layers` layers of circles (centre, radius; 128 segments each) and axis-aligned squares
/// (centre, side), starting with `SET_KINEMATIC_POSITION` at `start` when given.
pub fn test_print_gcode(
    circles: &[([f64; 2], f64)],
    squares: &[([f64; 2], f64)],
    layers: usize,
    start: Option<[f64; 3]>,
) -> String {
    let mut s = String::from("; jointspace sim: circle and square test print\n");
    if let Some([x, y, z]) = start {
        let _ = writeln!(s, "SET_KINEMATIC_POSITION X={x:.3} Y={y:.3} Z={z:.3}");
    }
    s.push_str("G90\nM83\n");
    const SEGMENTS: usize = 128;
    const E_PER_MM: f64 = 0.05;
    for layer in 0..layers {
        let z = 0.3 + 0.2 * layer as f64;
        let _ = writeln!(s, ";LAYER:{layer}\nG0 Z{z:.3} F600");
        for &(centre, r) in circles {
            let _ = writeln!(s, "G0 X{:.4} Y{:.4} F6000", centre[0] + r, centre[1]);
            let e = TAU * r / SEGMENTS as f64 * E_PER_MM;
            for k in 1..=SEGMENTS {
                let p = polar_point(centre, r, TAU * k as f64 / SEGMENTS as f64);
                let _ = writeln!(s, "G1 X{:.4} Y{:.4} E{e:.5} F1800", p[0], p[1]);
            }
        }
        for &(centre, side) in squares {
            let corners = square(centre, 0.5 * side);
            let _ = writeln!(s, "G0 X{:.4} Y{:.4} F6000", corners[0][0], corners[0][1]);
            for c in corners[1..].iter().chain(&corners[..1]) {
                let _ = writeln!(
                    s,
                    "G1 X{:.4} Y{:.4} E{:.5} F1800",
                    c[0],
                    c[1],
                    side * E_PER_MM
                );
            }
        }
    }
    s
}

/// Filament per mm of path for a 0.45 × 0.2 mm bead of 1.75 mm filament.
const E_PER_MM: f64 = 0.45 * 0.2 / (std::f64::consts::PI * 0.875 * 0.875);

struct Gcode<'a> {
    spec: &'a TestPrint,
    text: String,
    at: [f64; 2],
}

impl<'a> Gcode<'a> {
    fn new(spec: &'a TestPrint) -> Self {
        Gcode {
            spec,
            text: String::with_capacity(64 * 1024),
            at: [f64::NAN; 2],
        }
    }

    fn line(&mut self, s: &str) {
        self.text.push_str(s);
        self.text.push('\n');
    }

    fn header(&mut self) {
        let s = self.spec;
        self.line("; jointspace test print: rings, square, star and an arc");
        self.line(&format!(
            "; centre {:.1},{:.1} mm, outer radius {:.1} mm, {} layers",
            s.centre[0], s.centre[1], s.size, s.layers
        ));
        self.line("G21\nG90\nM83\nM104 S210\nM109 S210\nG92 E0");
    }

    fn footer(&mut self) {
        self.line("G1 E-1 F2400\nG91\nG1 Z5 F600\nG90\nM104 S0\nM84");
    }

    fn feature(&mut self, name: &str) {
        self.line(&format!(";TYPE:{name}"));
    }

    /// Travel to `p`, around the print centre rather than across it (on a polar machine the centre is where
    /// the bed angle is undefined).
    fn travel(&mut self, p: [f64; 2]) {
        let f = self.spec.travel_speed * 60.0;
        if let Some(via) = detour(self.at, p, self.spec.centre, 0.1 * self.spec.size) {
            self.line(&format!("G0 X{:.3} Y{:.3} F{f:.0}", via[0], via[1]));
        }
        self.line(&format!("G0 X{:.3} Y{:.3} F{f:.0}", p[0], p[1]));
        self.at = p;
    }

    fn polygon(&mut self, points: &[[f64; 2]]) {
        let Some(&first) = points.first() else { return };
        self.travel(first);
        let f = self.spec.print_speed * 60.0;
        let mut feed = format!(" F{f:.0}");
        for &p in points.iter().skip(1).chain(std::iter::once(&first)) {
            let e = (p[0] - self.at[0]).hypot(p[1] - self.at[1]) * E_PER_MM;
            let _ = writeln!(self.text, "G1 X{:.3} Y{:.3} E{e:.5}{feed}", p[0], p[1]);
            feed.clear();
            self.at = p;
        }
    }

    /// A half circle as one G2 arc.
    fn arc(&mut self, c: [f64; 2], r: f64) {
        self.travel([c[0] + r, c[1]]);
        let e = std::f64::consts::PI * r * E_PER_MM;
        let f = self.spec.print_speed * 60.0;
        let _ = writeln!(
            self.text,
            "G2 X{:.3} Y{:.3} I{:.3} J0 E{e:.5} F{f:.0}",
            c[0] - r,
            c[1],
            -r
        );
        self.at = [c[0] - r, c[1]];
    }
}

/// A waypoint that keeps the straight travel `a → b` at least `clearance` from `c`, when it would pass closer.
fn detour(a: [f64; 2], b: [f64; 2], c: [f64; 2], clearance: f64) -> Option<[f64; 2]> {
    if !a[0].is_finite() {
        return None;
    }
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    if len2 == 0.0 {
        return None;
    }
    let t = (((c[0] - a[0]) * d[0] + (c[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0);
    let closest = [a[0] + t * d[0], a[1] + t * d[1]];
    if (closest[0] - c[0]).hypot(closest[1] - c[1]) >= clearance {
        return None;
    }
    // Step sideways from the centre, perpendicular to the travel, far enough that both legs clear it.
    let len = len2.sqrt();
    let side = [-d[1] / len, d[0] / len];
    Some([
        c[0] + 4.0 * clearance * side[0],
        c[1] + 4.0 * clearance * side[1],
    ])
}

fn circle(c: [f64; 2], r: f64, n: usize) -> Vec<[f64; 2]> {
    (0..n)
        .map(|i| polar_point(c, r, TAU * i as f64 / n as f64))
        .collect()
}

fn square(c: [f64; 2], half: f64) -> Vec<[f64; 2]> {
    vec![
        [c[0] - half, c[1] - half],
        [c[0] + half, c[1] - half],
        [c[0] + half, c[1] + half],
        [c[0] - half, c[1] + half],
    ]
}

fn star(c: [f64; 2], outer: f64, inner: f64, points: usize) -> Vec<[f64; 2]> {
    (0..2 * points)
        .map(|i| {
            let r = if i % 2 == 0 { outer } else { inner };
            polar_point(c, r, TAU * i as f64 / (2 * points) as f64 + 0.25 * TAU)
        })
        .collect()
}

fn polar_point(c: [f64; 2], r: f64, angle: f64) -> [f64; 2] {
    [c[0] + r * angle.cos(), c[1] + r * angle.sin()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn test_print_parses_and_extrudes_what_its_geometry_says() {
        let spec = TestPrint::new([0.0, 0.0], 30.0);
        let text = spec.gcode();
        let stats = gcode::file_stats(text.as_bytes(), "test").expect("parses");
        assert_eq!(stats.layers, 4);
        assert_eq!(stats.arcs, 4);
        // Per layer: two rings, the square, the star and the half-circle arc.
        let star_edge = {
            let a = polar_point([0.0, 0.0], 12.0, 0.25 * TAU);
            let b = polar_point([0.0, 0.0], 6.0, 0.25 * TAU + TAU / 10.0);
            (a[0] - b[0]).hypot(a[1] - b[1])
        };
        let ring = |r: f64, n: f64| 2.0 * n * r * (std::f64::consts::PI / n).sin();
        let per_layer = ring(30.0, 120.0)
            + ring(22.5, 90.0)
            + 4.0 * 27.0
            + 10.0 * star_edge
            + std::f64::consts::PI * 18.0;
        let expected = 4.0 * per_layer * E_PER_MM;
        assert!(
            (stats.total_extrusion - expected).abs() < 1e-3 * expected,
            "{} vs {expected}",
            stats.total_extrusion
        );
        let bbox = stats.extrusion_bbox.expect("extrudes");
        assert!((bbox.max[0] - 30.0).abs() < 1e-3 && (bbox.min[1] + 30.0).abs() < 1e-3);
    }
}
