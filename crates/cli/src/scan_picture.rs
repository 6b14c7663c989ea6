//! The picture of what a scan showed: the scan greyed, each cross found with its pose number and its residual
//! after the fit (drawn magnified), the poses left out where the fit puts them, and the marks not taken for crosses.
//! `calibrate scara --plot` and the demo draw it.

use calibrate::scara::scan_fit::printer_forward;
use calibrate::scara::scan_image::{ScanCalibration, ScanImage};
use kinematics::ScaraFrame;
use std::path::Path;

/// The scan (greyed, at most 2000 pixels across) with each cross found, its pose number and residual, the
/// missing poses where the fit puts them, and the marks not taken for crosses.
pub fn draw_scan(
    image: &ScanImage,
    cal: &ScanCalibration,
    poses: &[(f64, f64)],
    frame: ScaraFrame,
    png: &Path,
) -> miette::Result<()> {
    let d = image.width.max(image.height).div_ceil(2000).max(1);
    let (w, h) = (image.width.div_ceil(d), image.height.div_ceil(d));
    let mut rgb = Vec::with_capacity(3 * w * h);
    for y in 0..h {
        for x in 0..w {
            let (mut sum, mut n) = (0u32, 0u32);
            for yy in y * d..((y + 1) * d).min(image.height) {
                for xx in x * d..((x + 1) * d).min(image.width) {
                    sum += u32::from(image.ink_at(xx, yy));
                    n += 1;
                }
            }
            let grey = 255 - (sum / n.max(1)) as u8;
            rgb.extend([grey, grey, grey]);
        }
    }
    let marks = scan_marks(cal, poses, frame, d as f64);
    let bytes = plot::overlay_png(rgb, w as u32, h as u32, |c| {
        for m in &marks {
            c.circle(m.at[0], m.at[1], 9.0, Some((m.colour, 2.0)), None);
            if let Some(to) = m.arrow {
                c.polyline(&[(m.at[0], m.at[1]), (to[0], to[1])], m.colour, 2.0);
            }
            c.text(
                m.at[0] + 12.0,
                m.at[1],
                &m.label,
                13.0,
                m.colour,
                plot::canvas::Anchor::Start,
            );
        }
    })
    .map_err(|e| miette::miette!("{}: {e}", png.display()))?;
    crate::output::write_output(png, |w| Ok(w.write_all(&bytes)?)).map_err(crate::cmd::plain)
}

/// One mark on the picture (picture pixels).
struct Mark {
    at: [f64; 2],
    arrow: Option<[f64; 2]>,
    label: String,
    colour: plot::Rgb,
}

/// The picture's marks: crosses found (green, red when left out) with their residual drawn magnified, poses
/// missing (red, where the fit puts them), marks that are not crosses (orange).
fn scan_marks(cal: &ScanCalibration, poses: &[(f64, f64)], frame: ScaraFrame, d: f64) -> Vec<Mark> {
    let (f, k) = (&cal.fit.frame, cal.px_per_mm);
    let worst = cal
        .fit
        .fit
        .residuals
        .iter()
        .map(|r| r[0].hypot(r[1]))
        .fold(1e-6, f64::max);
    let magnify = 40.0 / (worst * k / d);
    let mut marks = Vec::new();
    for (m, r) in cal.fit.measurements.iter().zip(&cal.fit.fit.residuals) {
        let Some(j) = cal.matching.assigned[m.line - 1] else {
            continue;
        };
        let c = cal.detection.crosses[j].centre;
        let (o, e) = (f.to_scan([0.0, 0.0]), f.to_scan(*r));
        let at = [c[0] / d, c[1] / d];
        marks.push(Mark {
            at,
            arrow: Some([
                at[0] + (e[0] - o[0]) * k / d * magnify,
                at[1] + (e[1] - o[1]) * k / d * magnify,
            ]),
            label: format!("{} {:.3} mm", m.line, r[0].hypot(r[1])),
            colour: plot::Rgb(0, 150, 40),
        });
    }
    let g = &cal.fit.fit.geometry;
    for &pose in cal
        .missing
        .iter()
        .chain(cal.left_out.iter().map(|(p, _)| p))
    {
        let (a, b) = poses[pose - 1];
        let q = f.to_scan(printer_forward(g, frame, a, b));
        marks.push(Mark {
            at: [q[0] * k / d, q[1] * k / d],
            arrow: None,
            label: format!("{pose} left out"),
            colour: plot::Rgb(210, 30, 30),
        });
    }
    for r in &cal.detection.rejected {
        marks.push(Mark {
            at: [r.at[0] / d, r.at[1] / d],
            arrow: None,
            label: "not a cross".into(),
            colour: plot::Rgb(230, 130, 0),
        });
    }
    if let Some(first) = marks.first_mut() {
        first.label += &format!(" (residuals drawn ×{magnify:.0})");
    }
    marks
}
