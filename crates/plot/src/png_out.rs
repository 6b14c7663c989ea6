//! PNG output: the [`Canvas`] operations drawn by plotters' bitmap backend into an RGB buffer (text with
//! the bundled DejaVu Sans through ab_glyph), then encoded with the `png` crate.

use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::canvas::{Anchor, Canvas};
use crate::colour::Rgb;
use crate::error::PlotError;

/// Family name under which the bundled font is registered with plotters.
const FONT_FAMILY: &str = "jointspace-sans";
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// Registers the bundled font once; plotters' text drawing needs it (never system fontconfig).
fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(PlotError::Render("bundled font could not be loaded".into()))
    }
}

struct PngCanvas<'a> {
    area: DrawingArea<BitMapBackend<'a>, Shift>,
    error: Option<String>,
}

fn colour(c: Rgb) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

fn px(v: f64) -> i32 {
    if v.is_finite() {
        v.round().clamp(-1e6, 1e6) as i32
    } else {
        0
    }
}

impl PngCanvas<'_> {
    fn record<E: std::fmt::Debug>(&mut self, r: Result<(), E>) {
        if let Err(e) = r {
            self.error.get_or_insert_with(|| format!("{e:?}"));
        }
    }
}

impl Canvas for PngCanvas<'_> {
    fn fill_rect(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, fill: Rgb) {
        // Rounded edges shared by neighbouring cells leave no gaps: plotters fills opaque rectangles
        // half-open, [l, r) × [t, b).
        let (l, r) = (px(x0.min(x1)), px(x0.max(x1)));
        let (t, b) = (px(y0.min(y1)), px(y0.max(y1)));
        if r <= l || b <= t {
            return;
        }
        let res = self
            .area
            .draw(&Rectangle::new([(l, t), (r, b)], colour(fill).filled()));
        self.record(res);
    }

    fn polyline(&mut self, points: &[(f64, f64)], c: Rgb, width: f64) {
        let pts: Vec<(i32, i32)> = points.iter().map(|(x, y)| (px(*x), px(*y))).collect();
        let style = ShapeStyle {
            color: colour(c).to_rgba(),
            filled: false,
            stroke_width: width.round().max(1.0) as u32,
        };
        let res = self.area.draw(&PathElement::new(pts, style));
        self.record(res);
    }

    fn circle(&mut self, cx: f64, cy: f64, r: f64, stroke: Option<(Rgb, f64)>, fill: Option<Rgb>) {
        let radius = r.round().clamp(0.0, 1e6) as i32;
        if let Some(f) = fill {
            let res = self
                .area
                .draw(&Circle::new((px(cx), px(cy)), radius, colour(f).filled()));
            self.record(res);
        }
        if let Some((c, w)) = stroke {
            // A closed polyline: plotters' thick circle outlines leave gaps at the four compass points.
            let n = (r * 0.5).clamp(32.0, 720.0) as usize;
            let ring: Vec<(f64, f64)> = (0..=n)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    (cx + r * a.cos(), cy + r * a.sin())
                })
                .collect();
            self.polyline(&ring, c, w);
        }
    }

    fn text(&mut self, x: f64, y: f64, text: &str, size: f64, c: Rgb, anchor: Anchor) {
        if text.is_empty() {
            return;
        }
        let h = match anchor {
            Anchor::Start => HPos::Left,
            Anchor::Middle => HPos::Center,
            Anchor::End => HPos::Right,
        };
        let fill = colour(c);
        let style = TextStyle::from((FONT_FAMILY, size).into_font())
            .color(&fill)
            .pos(Pos::new(h, VPos::Center));
        let res = self
            .area
            .draw(&Text::new(text.to_string(), (px(x), px(y)), style));
        self.record(res);
    }
}

/// Draws with `draw` onto a `width × height` bitmap and returns the PNG bytes.
pub(crate) fn render(
    width: u32,
    height: u32,
    draw: impl FnOnce(&mut dyn Canvas),
) -> Result<Vec<u8>, PlotError> {
    render_over(
        vec![255u8; width as usize * height as usize * 3],
        width,
        height,
        draw,
    )
}

/// Draws with `draw` over `rgb` (a `width × height` picture, 8-bit RGB) and returns the PNG bytes.
pub(crate) fn render_over(
    mut rgb: Vec<u8>,
    width: u32,
    height: u32,
    draw: impl FnOnce(&mut dyn Canvas),
) -> Result<Vec<u8>, PlotError> {
    ensure_font()?;
    if rgb.len() != width as usize * height as usize * 3 {
        return Err(PlotError::Render(format!(
            "{} bytes are not a {width} × {height} RGB picture",
            rgb.len()
        )));
    }
    {
        let backend = BitMapBackend::with_buffer(&mut rgb, (width, height));
        let mut canvas = PngCanvas {
            area: backend.into_drawing_area(),
            error: None,
        };
        draw(&mut canvas);
        let presented = canvas.area.present();
        canvas.record(presented);
        if let Some(e) = canvas.error {
            return Err(PlotError::Render(e));
        }
    }
    encode(width, height, &rgb)
}

fn encode(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, PlotError> {
    let err = |e: png::EncodingError| PlotError::Encode {
        path: "<memory>".into(),
        message: e.to_string(),
    };
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(err)?;
        writer.write_image_data(rgb).map_err(err)?;
        writer.finish().map_err(err)?;
    }
    Ok(out)
}
