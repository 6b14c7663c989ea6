//! The page: the template (`viewer/src/`) with the vendored uPlot (`viewer/vendor/`), the summary as JSON and the
//! bulk data as typed arrays, all inlined, so the one file works offline.

use std::io::{self, Write};

use printjob::Estimate;
use serde_json::json;

use crate::View;
use crate::collect::refused_segments;
use crate::decimate::{JUMP, Segment};
use crate::encode::{Array, fraction, script_json, write_array};

const TEMPLATE: &str = include_str!("../../../viewer/src/view.html");
const VIEW_CSS: &str = include_str!("../../../viewer/src/view.css");
const VIEW_JS: &str = include_str!("../../../viewer/src/view.js");
const UPLOT_JS: &str = include_str!("../../../viewer/vendor/uPlot.iife.min.js");
const UPLOT_CSS: &str = include_str!("../../../viewer/vendor/uPlot.min.css");

/// Where the data marker sits in the template.
const DATA: &str = "<!--{{data}}-->";

/// What the page says it shows.
#[derive(Debug, Clone)]
pub struct PageMeta {
    /// The G-code file and the config, as the estimate names them.
    pub file: String,
    pub config: String,
}

/// `text` safe inside HTML text and attribute values.
fn html_escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Write the whole page.
pub fn write_page(
    w: &mut dyn Write,
    estimate: &Estimate,
    view: &View,
    meta: &PageMeta,
) -> io::Result<()> {
    let title = html_escape(&format!("{} on {}", meta.file, meta.config));
    let page = TEMPLATE
        .replace("{{title}}", &title)
        .replace("/*{{uplot.css}}*/", UPLOT_CSS)
        .replace("/*{{view.css}}*/", VIEW_CSS);
    let (head, tail) = page.split_once(DATA).unwrap_or((&page, ""));
    w.write_all(head.as_bytes())?;
    let summary = summary(estimate, view, meta).map_err(io::Error::other)?;
    writeln!(
        w,
        "<script type=\"application/json\" id=\"summary\">{}</script>",
        script_json(&summary)
    )?;
    for (name, array) in arrays(view) {
        write_array(w, &name, &array)?;
    }
    for (name, array) in view
        .map
        .as_ref()
        .map(|m| m.arrays.as_slice())
        .unwrap_or(&[])
    {
        write_array(w, name, array)?;
    }
    let scripts = format!("<script>{UPLOT_JS}</script>\n<script>{VIEW_JS}</script>\n");
    w.write_all(scripts.as_bytes())?;
    w.write_all(tail.as_bytes())
}

/// The page's numbers: the estimate as `estimate --json` gives it, and what the view adds.
fn summary(
    estimate: &Estimate,
    view: &View,
    meta: &PageMeta,
) -> serde_json::Result<serde_json::Value> {
    let mut numbers = serde_json::to_value(estimate)?;
    numbers["file"] = meta.file.clone().into();
    numbers["config"] = meta.config.clone().into();
    let c = &view.collected;
    let mut first = 0;
    let layers: Vec<serde_json::Value> = c
        .layers
        .iter()
        .map(|l| {
            let entry = json!({"name": l.name, "z": l.z, "line": l.line, "first": first,
                "count": l.segments.len(), "planned": l.planned, "whole": l.whole});
            first += l.segments.len();
            entry
        })
        .collect();
    let refused: Vec<serde_json::Value> = c
        .refused
        .iter()
        .map(|r| {
            let layer = c.layers.iter().rposition(|l| l.line <= r.line).unwrap_or(0);
            json!({"line": r.line, "from": r.from, "to": r.to, "reason": r.reason, "layer": layer})
        })
        .collect();
    Ok(json!({
        "estimate": numbers,
        "machine": view.machine,
        "motors": view.motors,
        "limits": view.limits,
        "layers": layers,
        "refused": refused,
        "refused_total": c.refused_total,
        "scales": {"speed": c.scales.speed, "motor_speed": c.scales.motor_speed,
                   "motor_accel": c.scales.motor_accel},
        "tolerance": c.tolerance,
        "stride": c.stride,
        "segments": {"kept": first, "planned": c.layers.iter().map(|l| l.planned).sum::<usize>()},
        "series_points": c.series.time.len(),
        "map": view.map.as_ref().map_or_else(|e| json!({"error": e}), |m| m.meta.clone()),
    }))
}

/// The segments (every layer, then the refused moves) and the motor series as typed arrays.
fn arrays(view: &View) -> Vec<(String, Array)> {
    let c = &view.collected;
    let motors = view.motors.len();
    let refused = refused_segments(&c.refused);
    let all: Vec<&Segment> = c
        .layers
        .iter()
        .flat_map(|l| l.segments.iter())
        .chain(refused.iter())
        .collect();
    let f32s = |f: &dyn Fn(&Segment) -> f32| Array::F32(all.iter().map(|s| f(s)).collect());
    let speed_scale = c.scales.speed.max(1e-9);
    let mut to = Vec::with_capacity(all.len() * 3);
    let mut jump_from = Vec::new();
    for s in &all {
        to.extend(s.to);
        if s.flags & JUMP != 0 {
            jump_from.extend(s.from);
        }
    }
    let mut out = vec![
        ("to".to_string(), Array::F32(to)),
        ("jump-from".to_string(), Array::F32(jump_from)),
        ("start".to_string(), f32s(&|s| s.start as f32)),
        ("duration".to_string(), f32s(&|s| s.duration as f32)),
        (
            "speed".to_string(),
            Array::U16(
                all.iter()
                    .map(|s| fraction(f64::from(s.speed), speed_scale))
                    .collect(),
            ),
        ),
        (
            "requested".to_string(),
            Array::F32(all.iter().map(|s| s.requested).collect()),
        ),
        (
            "cause".to_string(),
            Array::U8(all.iter().map(|s| s.cause).collect()),
        ),
        (
            "flags".to_string(),
            Array::U8(all.iter().map(|s| s.flags).collect()),
        ),
        (
            "line".to_string(),
            Array::U32(
                all.iter()
                    .map(|s| u32::try_from(s.line).unwrap_or(u32::MAX))
                    .collect(),
            ),
        ),
    ];
    for m in 0..motors {
        let scaled = |values: &dyn Fn(&Segment) -> f32, full: f64| {
            Array::U16(
                all.iter()
                    .map(|s| fraction(f64::from(values(s)), full))
                    .collect(),
            )
        };
        let full_speed = c.scales.motor_speed.get(m).copied().unwrap_or(0.0);
        let full_accel = c.scales.motor_accel.get(m).copied().unwrap_or(0.0);
        out.push((
            format!("motor{m}-speed"),
            scaled(&|s| s.motor_speed[m], full_speed),
        ));
        out.push((
            format!("motor{m}-accel"),
            scaled(&|s| s.motor_accel[m], full_accel),
        ));
    }
    out.extend(series_arrays(&c.series));
    out
}

/// The motors against time.
fn series_arrays(series: &crate::series::Columns) -> Vec<(String, Array)> {
    let mut out = Vec::new();
    out.push(("series-time".into(), Array::F32(series.time.clone())));
    out.push(("series-nozzle".into(), Array::F32(series.nozzle.clone())));
    for m in 0..series.position.len() {
        out.push((
            format!("series{m}-position"),
            Array::F32(series.position[m].clone()),
        ));
        out.push((
            format!("series{m}-speed"),
            Array::F32(series.speed[m].clone()),
        ));
        out.push((
            format!("series{m}-accel"),
            Array::F32(series.accel[m].clone()),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_template_has_every_marker_and_no_script_closes_early() {
        for marker in [
            "{{title}}",
            "/*{{uplot.css}}*/",
            "/*{{view.css}}*/",
            super::DATA,
        ] {
            assert!(super::TEMPLATE.contains(marker), "{marker}");
        }
        for (name, text) in [("uPlot", super::UPLOT_JS), ("view.js", super::VIEW_JS)] {
            assert!(
                !text.contains("</script"),
                "{name} would close its script element"
            );
        }
    }
}
