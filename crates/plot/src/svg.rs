//! Our own small SVG writer: the [`Canvas`] operations as plain SVG elements.

use std::fmt::Write;

use crate::canvas::{Anchor, Canvas};
use crate::colour::Rgb;

#[derive(Debug)]
pub(crate) struct SvgCanvas {
    out: String,
}

impl SvgCanvas {
    pub(crate) fn new(width: u32, height: u32) -> Self {
        let mut out = String::with_capacity(64 * 1024);
        out.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        let _ = writeln!(
            out,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" \
             viewBox=\"0 0 {width} {height}\" font-family=\"DejaVu Sans, Verdana, sans-serif\">"
        );
        // Heat-map cells meet edge to edge: no anti-aliased seams between them.
        out.push_str("<style>rect{shape-rendering:crispEdges}</style>\n");
        SvgCanvas { out }
    }

    pub(crate) fn finish(mut self) -> String {
        self.out.push_str("</svg>\n");
        self.out
    }
}

/// Escapes text for element content and attribute values.
pub(crate) fn escape(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' => {}
            c => s.push(c),
        }
    }
    s
}

/// Pixel coordinate with two decimals, trailing zeros dropped.
fn n(v: f64) -> String {
    let v = if v.is_finite() { v } else { 0.0 };
    let s = format!("{v:.1}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

impl Canvas for SvgCanvas {
    fn fill_rect(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, fill: Rgb) {
        let (x, y) = (x0.min(x1), y0.min(y1));
        let (w, h) = ((x1 - x0).abs(), (y1 - y0).abs());
        let _ = writeln!(
            self.out,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>",
            n(x),
            n(y),
            n(w),
            n(h),
            fill.hex()
        );
    }

    fn polyline(&mut self, points: &[(f64, f64)], colour: Rgb, width: f64) {
        if points.len() < 2 {
            return;
        }
        let pts: Vec<String> = points
            .iter()
            .map(|(x, y)| format!("{},{}", n(*x), n(*y)))
            .collect();
        let _ = writeln!(
            self.out,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{}\" stroke-linejoin=\"round\" stroke-linecap=\"round\"/>",
            pts.join(" "),
            colour.hex(),
            n(width)
        );
    }

    fn circle(&mut self, cx: f64, cy: f64, r: f64, stroke: Option<(Rgb, f64)>, fill: Option<Rgb>) {
        let fill = fill.map_or("none".to_string(), Rgb::hex);
        let stroke = stroke.map_or(String::new(), |(c, w)| {
            format!(" stroke=\"{}\" stroke-width=\"{}\"", c.hex(), n(w))
        });
        let _ = writeln!(
            self.out,
            "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{fill}\"{stroke}/>",
            n(cx),
            n(cy),
            n(r)
        );
    }

    fn text(&mut self, x: f64, y: f64, text: &str, size: f64, colour: Rgb, anchor: Anchor) {
        let anchor = match anchor {
            Anchor::Start => "start",
            Anchor::Middle => "middle",
            Anchor::End => "end",
        };
        // dy = 0.35em centres the text on y without relying on dominant-baseline support.
        let _ = writeln!(
            self.out,
            "<text x=\"{}\" y=\"{}\" dy=\"0.35em\" font-size=\"{}\" fill=\"{}\" text-anchor=\"{anchor}\">{}</text>",
            n(x),
            n(y),
            n(size),
            colour.hex(),
            escape(text)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_and_numbers_are_short() {
        let mut c = SvgCanvas::new(100, 50);
        c.text(1.5, 2.0, "a<b & \"c\"", 12.0, Rgb::BLACK, Anchor::Start);
        c.fill_rect(0.0, 0.0, 10.5, -0.0, Rgb::WHITE);
        let s = c.finish();
        assert!(s.contains(">a&lt;b &amp; &quot;c&quot;</text>"));
        assert!(s.contains("x=\"1.5\" y=\"2\""));
        assert!(s.contains("width=\"10.5\" height=\"0\""));
        assert!(s.trim_end().ends_with("</svg>"));
    }
}
