//! The simulated Hall-sensor scan of a polar bed's magnets, and the magnet map drawn from a scan's result.

use calibrate::scan::{CentreResult, ScanParams};
use plot::{Figure, Layer, Rgb};
use std::path::Path;

/// A simulated bed: its magnets, the sensor's noise, and the arm offsets to find.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedBed {
    pub magnets: usize,
    /// Sensor noise (mT, 1σ).
    pub noise_mt: f64,
    pub seed: u64,
    /// True arm offsets `dx, dy` (mm); random up to 2 mm when `None`.
    pub offset: Option<[f64; 2]>,
}

/// Scan a simulated bed; the result and the true offsets.
pub fn simulate_scan(
    simulated: &SimulatedBed,
    params: &ScanParams,
) -> miette::Result<(CentreResult, [f64; 2])> {
    let mut bed = sim::hall::HallBedConfig {
        magnet_count: simulated.magnets,
        seed: simulated.seed,
        ..Default::default()
    };
    bed.sensor.noise = simulated.noise_mt * 1e-3;
    bed = match simulated.offset {
        Some([dx, dy]) => sim::hall::HallBedConfig {
            arm_zero_offset: dx,
            arm_lateral_offset: dy,
            ..bed
        },
        None => bed.random_offsets(2.0, simulated.seed),
    };
    let truth = [bed.arm_zero_offset, bed.arm_lateral_offset];
    let mut scanner = sim::hall::HallScanner::new(bed).map_err(|e| miette::miette!("{e}"))?;
    let result =
        calibrate::scan::scan_centre(&mut scanner, params).map_err(|e| miette::miette!("{e}"))?;
    Ok((result, truth))
}

/// The magnet map: measured magnet centres, the fitted ring and the residuals (×100), as PNG and SVG.
pub fn draw_magnet_map(r: &CentreResult, png: &Path) -> miette::Result<()> {
    let data = r.plot_data();
    let mut figure = Figure::new("Magnet map: measured magnet centres and the fitted ring");
    figure.notes.push(format!(
        "centre offset dx {:+.4} mm, dy {:+.4} mm; residuals drawn ×100",
        r.arm_zero_offset, r.arm_lateral_offset
    ));
    if let Some(ring) = data.ring {
        figure = figure.with_layer(Layer::Circle {
            centre: [ring.cx, ring.cy],
            radius: ring.r,
            colour: Rgb(120, 120, 120),
            width: 1.0,
        });
    }
    let segments: Vec<[[f64; 2]; 2]> = data
        .points
        .iter()
        .zip(&data.residual_vectors)
        .map(|(p, v)| {
            [
                [p[0] - v[0], p[1] - v[1]],
                [p[0] - v[0] + 100.0 * v[0], p[1] - v[1] + 100.0 * v[1]],
            ]
        })
        .collect();
    for segment in segments {
        figure = figure.with_layer(Layer::Polyline {
            points: segment.to_vec(),
            colour: Rgb(200, 60, 40),
            width: 2.0,
        });
    }
    figure = figure
        .with_layer(Layer::Points {
            points: data.points.clone(),
            colour: Rgb(30, 90, 200),
            radius_px: 4.0,
        })
        .with_layer(Layer::Points {
            points: vec![data.rotation_centre],
            colour: Rgb(0, 0, 0),
            radius_px: 3.0,
        });
    figure.write_png(png).map_err(|e| miette::miette!("{e}"))?;
    figure
        .write_svg(&png.with_extension("svg"))
        .map_err(|e| miette::miette!("{e}"))?;
    Ok(())
}
