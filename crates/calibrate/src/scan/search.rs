//! The stop-and-read scan: find the first magnet from outside the bed, peak every magnet of the ring on the
//! near side, then each again on the far side of the centre, and hand the detections to the fit.

use super::error::ScanError;
use super::fit::{assemble, pair_offsets};
use super::hardware::{ScanHardware, Scanner};
use super::params::{ScanParams, validate};
use super::result::{CentreResult, Detection};
use std::f64::consts::{PI, TAU};

/// Run the centre scan on `hw`. See the module docs for the geometry and conventions.
pub fn scan_centre<H: ScanHardware>(
    hw: &mut H,
    params: &ScanParams,
) -> Result<CentreResult, ScanError> {
    validate(params)?;
    let mut s = Scanner::new(hw, params);
    s.go(params.arm_home, 0.0)?;
    let near = scan_near_side(&mut s)?;
    let far = scan_far_side(&mut s, &near)?;
    let (time, reads) = (s.time, s.reads);
    assemble(params, near, far, time, reads)
}

/// Find the first magnet from outside the bed, then every other one a magnet spacing further round, each
/// searched for where the previous one was found along the arm.
fn scan_near_side<H: ScanHardware>(
    s: &mut Scanner<'_, H>,
) -> Result<Vec<Option<Detection>>, ScanError> {
    let params = s.p;
    let n = params.magnet_count;
    let spacing = TAU / n as f64;
    let (r_hit, t_hit) = s.find_first()?;
    let first = s.refine(r_hit, t_hit)?;
    let window = 2.0 * params.coarse_step;
    let mut near: Vec<Option<Detection>> = vec![None; n];
    near[0] = Some(first);
    let mut last_r = first.r;
    for (k, slot) in near.iter_mut().enumerate().skip(1) {
        let found = s.locate(last_r, first.theta + k as f64 * spacing, window)?;
        if let Some(d) = found {
            last_r = d.r;
        }
        *slot = found;
    }
    Ok(near)
}

/// Visit every near-side magnet again on the far side of the centre (bed turned by ≈ π, arm at ≈ −r⁺).
fn scan_far_side<H: ScanHardware>(
    s: &mut Scanner<'_, H>,
    near: &[Option<Detection>],
) -> Result<Vec<Option<Detection>>, ScanError> {
    let p = s.p;
    let n = near.len();
    let mut far: Vec<Option<Detection>> = vec![None; n];
    // Visit in increasing unwrapped bed angle from where the bed is now.
    let (_, now) = s.hw.position();
    let mut order: Vec<(usize, f64)> = near
        .iter()
        .enumerate()
        .filter_map(|(k, d)| d.map(|d| (k, d.theta + PI)))
        .map(|(k, t)| (k, t + ((now - t) / TAU).ceil().max(0.0) * TAU))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut estimate: Option<[f64; 2]> = None;
    let wide = 2.0 * p.max_offset + p.coarse_step;
    for (k, target) in order {
        let Some(nd) = near[k] else { continue };
        let turn = target - (nd.theta + PI);
        let found = match estimate {
            None => s.locate(-nd.r, target, wide)?,
            Some([dx, dy]) => {
                let h = nd.r + dx;
                let r_pred = -nd.r - 2.0 * dx;
                let t_pred = nd.theta + PI + 2.0 * (dy / h).atan() + turn;
                s.locate(r_pred, t_pred, 2.0 * p.coarse_step)?
            }
        };
        if let Some(fd) = found {
            let d = Detection {
                theta: fd.theta - turn,
                ..fd
            };
            if estimate.is_none() {
                estimate = Some(pair_offsets(&nd, &d));
            }
            far[k] = Some(d);
        }
    }
    Ok(far)
}

impl<H: ScanHardware> Scanner<'_, H> {
    /// Strongest reading on a grid around (r, θ): `r_half`, `arc_half` half widths (mm), `step` (mm).
    /// Rows alternate direction so the bed does not rewind.
    fn grid_max(
        &mut self,
        r: f64,
        theta: f64,
        r_half: f64,
        arc_half: f64,
        step: f64,
    ) -> Result<(f64, f64, f64), ScanError> {
        let nr = (r_half / step).ceil() as i64;
        let nt = (arc_half / step).ceil() as i64;
        let dth = step * self.rad_per_mm(r);
        let mut best = (r, theta, f64::NEG_INFINITY);
        for (row, i) in (-nr..=nr).enumerate() {
            let rr = r + i as f64 * step;
            for j in -nt..=nt {
                let j = if row % 2 == 0 { j } else { -j };
                let s = self.sample(rr, theta + j as f64 * dth)?;
                if s.2 > best.2 {
                    best = s;
                }
            }
        }
        Ok(best)
    }

    /// The thesis' first search: from outside the bed step the arm inwards; at each arm step sweep the bed
    /// over one magnet spacing until the field exceeds the detection threshold.
    fn find_first(&mut self) -> Result<(f64, f64), ScanError> {
        let p = self.p;
        let spacing = TAU / p.magnet_count as f64;
        let stop = p.ring_radius - 2.0 * p.max_offset - p.peak_half_width;
        let mut r = p.arm_home;
        let mut forward = true;
        while r >= stop {
            let dth = p.coarse_step * self.rad_per_mm(r);
            let n = (spacing / dth).ceil() as i64 + 1;
            for k in 0..=n {
                let theta = if forward {
                    k as f64 * dth
                } else {
                    (n - k) as f64 * dth
                };
                let (rr, tt, b) = self.sample(r, theta)?;
                if b >= p.detection_threshold {
                    return Ok((rr, tt));
                }
            }
            forward = !forward;
            r -= p.coarse_step;
        }
        Err(ScanError::NoMagnetFound {
            from: p.arm_home,
            to: stop,
        })
    }

    /// Coarse grid around a prediction, then the peak; `None` when nothing exceeds the threshold.
    fn locate(&mut self, r: f64, theta: f64, half: f64) -> Result<Option<Detection>, ScanError> {
        let (rr, tt, b) = self.grid_max(r, theta, half, half, self.p.coarse_step)?;
        if b < self.p.detection_threshold {
            return Ok(None);
        }
        self.refine(rr, tt).map(Some)
    }
}
