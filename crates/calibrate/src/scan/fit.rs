//! From detections to the result: each magnet's near/far pair gives the offsets exactly, the pairs are
//! screened against their median and averaged (with the covariance of the mean), the magnets are placed on the
//! bed with the fitted offsets, the ring is fitted to them, and what looked wrong is flagged.

use super::detections::DetectionSlots;
use super::error::ScanError;
use super::params::ScanParams;
use super::result::{CentreResult, Detection, MagnetRecord};
use crate::circle::{self, CircleFit, Point};
use std::f64::consts::{PI, TAU};

/// Offsets from one magnet seen on both sides (exact for any magnet placement). With `h = (r⁺ − r⁻)/2` the
/// sensor is at `(h, dy)` on the near side and `(−h, dy)` on the far side, and the magnet's bed angle is
/// `θ⁺ + atan(dy/h) = θ⁻ + π − atan(dy/h)`: `θ⁺ − θ⁻ = π − 2·atan(dy/h)`.
pub fn pair_offsets(near: &Detection, far: &Detection) -> [f64; 2] {
    let dx = -0.5 * (near.r + far.r);
    let h = 0.5 * (near.r - far.r);
    let delta = PI - (near.theta - far.theta).rem_euclid(TAU);
    [dx, h * (0.5 * delta).tan()]
}

/// Fit the offsets from recorded detections (e.g. a scan file): `near[k]` and `far[k]` are magnet `k` seen
/// on the near and far side. Uses `pair_tolerance`, `ring_tolerance` and `method` (recorded only) from
/// `params`; the scan time and read count are zero.
pub fn centre_from_detections(
    params: &ScanParams,
    near: Vec<Option<Detection>>,
    far: Vec<Option<Detection>>,
) -> Result<CentreResult, ScanError> {
    if near.len() != far.len() {
        return Err(ScanError::InvalidParams(format!(
            "{} near-side and {} far-side magnet slots",
            near.len(),
            far.len()
        )));
    }
    let p = ScanParams {
        magnet_count: near.len(),
        ..params.clone()
    };
    assemble(&p, near, far, 0.0, 0)
}

/// The centre from the detections of a ring of `params.magnet_count` magnets: a magnet without a detection anywhere
/// on the ring (the last slot included) is flagged as missing; detections of more magnets than the ring has are
/// refused.
pub fn centre_from_ring(
    params: &ScanParams,
    mut slots: DetectionSlots,
) -> Result<CentreResult, ScanError> {
    let n = params.magnet_count;
    let found = slots.near.len().max(slots.far.len());
    if found > n {
        return Err(ScanError::InvalidParams(format!(
            "the detections name magnet {} but the ring has {n} magnets",
            found - 1
        )));
    }
    slots.near.resize(n, None);
    slots.far.resize(n, None);
    centre_from_detections(params, slots.near, slots.far)
}

/// Combine the pairs robustly and build the magnet map and the result.
pub(super) fn assemble(
    params: &ScanParams,
    near: Vec<Option<Detection>>,
    far: Vec<Option<Detection>>,
    scan_time: f64,
    sensor_reads: usize,
) -> Result<CentreResult, ScanError> {
    let mut magnets = magnet_records(&near, &far);
    let med = screen_pairs(params, &mut magnets)?;
    let used: Vec<[f64; 2]> = magnets
        .iter()
        .filter(|m| m.used)
        .filter_map(|m| m.pair_offset)
        .collect();
    if used.len() < 3 {
        return Err(ScanError::TooFewPairs { found: used.len() });
    }
    let (mean, mut cov) = mean_and_covariance(&used);
    let sigma_scan = [cov[0][0].sqrt(), cov[1][1].sqrt()];
    let alignment = params.sensor_alignment * params.sensor_alignment;
    cov[0][0] += alignment;
    cov[1][1] += alignment;
    let [dx, dy] = mean;
    place_on_bed(&mut magnets, dx, dy);
    let map: Vec<Point> = magnets.iter().filter_map(|m| m.position).collect();
    let ring = circle::robust(&map, params.ring_tolerance).ok();
    if let Some(fit) = &ring {
        for m in &mut magnets {
            m.ring_residual = m.position.map(|p| fit.circle.residual(p));
        }
    }
    let map_centroid = circle::centroid(&map).ok();
    let flags = flags(params, &magnets, med, ring.as_ref());
    Ok(CentreResult {
        arm_zero_offset: dx,
        arm_lateral_offset: dy,
        sigma_arm_zero_offset: cov[0][0].sqrt(),
        sigma_arm_lateral_offset: cov[1][1].sqrt(),
        covariance: cov,
        sigma_scan,
        sensor_alignment: params.sensor_alignment,
        flags,
        magnet_count: params.magnet_count,
        detected: magnets
            .iter()
            .filter(|m| m.near.is_some() || m.far.is_some())
            .count(),
        pairs_used: used.len(),
        magnets,
        ring,
        map_centroid,
        scan_time,
        sensor_reads,
        method: params.method,
        tilt: None,
    })
}

/// One record per magnet slot, with the offsets its pair gives when it was seen on both sides.
fn magnet_records(near: &[Option<Detection>], far: &[Option<Detection>]) -> Vec<MagnetRecord> {
    near.iter()
        .zip(far)
        .enumerate()
        .map(|(index, (n, f))| MagnetRecord {
            index,
            near: *n,
            far: *f,
            pair_offset: n.zip(*f).map(|(a, b)| pair_offsets(&a, &b)),
            used: false,
            position: None,
            ring_residual: None,
        })
        .collect()
}

/// Mark the pairs within the tolerance of the pairs' median (`pair_tolerance`, or 4 robust σ if larger) as
/// used; returns the median.
fn screen_pairs(params: &ScanParams, magnets: &mut [MagnetRecord]) -> Result<[f64; 2], ScanError> {
    let pairs: Vec<[f64; 2]> = magnets.iter().filter_map(|m| m.pair_offset).collect();
    if pairs.len() < 3 {
        return Err(ScanError::TooFewPairs { found: pairs.len() });
    }
    let med = [
        median(&pairs.iter().map(|p| p[0]).collect::<Vec<_>>()),
        median(&pairs.iter().map(|p| p[1]).collect::<Vec<_>>()),
    ];
    let mad = |axis: usize| {
        1.4826
            * median(
                &pairs
                    .iter()
                    .map(|p| (p[axis] - med[axis]).abs())
                    .collect::<Vec<_>>(),
            )
    };
    let tol = [
        params.pair_tolerance.max(4.0 * mad(0)),
        params.pair_tolerance.max(4.0 * mad(1)),
    ];
    for m in magnets {
        m.used = m
            .pair_offset
            .is_some_and(|p| (p[0] - med[0]).abs() <= tol[0] && (p[1] - med[1]).abs() <= tol[1]);
    }
    Ok(med)
}

/// Mean of the used pairs' offsets and the covariance of that mean (mm²), from at least two pairs.
fn mean_and_covariance(used: &[[f64; 2]]) -> ([f64; 2], [[f64; 2]; 2]) {
    let k = used.len() as f64;
    let mean = [
        used.iter().map(|p| p[0]).sum::<f64>() / k,
        used.iter().map(|p| p[1]).sum::<f64>() / k,
    ];
    let mut cov = [[0.0; 2]; 2];
    for p in used {
        let d = [p[0] - mean[0], p[1] - mean[1]];
        for a in 0..2 {
            for b in 0..2 {
                // Sample covariance of one pair, divided by k for the covariance of the mean.
                cov[a][b] += d[a] * d[b] / ((k - 1.0) * k);
            }
        }
    }
    (mean, cov)
}

/// Each magnet's position in the bed frame with the offsets (dx, dy): the mean of its detections.
fn place_on_bed(magnets: &mut [MagnetRecord], dx: f64, dy: f64) {
    for m in magnets {
        // The bed point under the sensor: Rot(θ)·(r + dx, dy).
        let to_bed = |d: &Detection| -> Point {
            let (x, y) = (d.r + dx, dy);
            let (s, c) = d.theta.sin_cos();
            [c * x - s * y, s * x + c * y]
        };
        let pts: Vec<Point> = m.near.iter().chain(m.far.iter()).map(to_bed).collect();
        if !pts.is_empty() {
            let c = pts.len() as f64;
            m.position = Some([
                pts.iter().map(|p| p[0]).sum::<f64>() / c,
                pts.iter().map(|p| p[1]).sum::<f64>() / c,
            ]);
        }
    }
}

/// What a scan found wrong with the ring (see [`CentreResult::flags`]).
fn flags(
    params: &ScanParams,
    magnets: &[MagnetRecord],
    median_offset: [f64; 2],
    ring: Option<&CircleFit>,
) -> Vec<String> {
    let mut flags = Vec::new();
    flag_pairs(&mut flags, magnets, median_offset);
    flag_peaks(&mut flags, params, magnets);
    if let Some(fit) = ring {
        flag_ring_outliers(&mut flags, magnets, fit);
    }
    flags
}

/// Magnets missing, seen on one side only, or whose pair the screen left out.
fn flag_pairs(flags: &mut Vec<String>, magnets: &[MagnetRecord], median_offset: [f64; 2]) {
    for m in magnets {
        let k = m.index;
        match (m.near, m.far, m.pair_offset) {
            (None, None, _) => flags.push(format!("magnet {k} was not found (missing?)")),
            (Some(_), None, _) => flags.push(format!(
                "magnet {k} was seen on the near side only: not used"
            )),
            (None, Some(_), _) => flags.push(format!(
                "magnet {k} was seen on the far side only: not used"
            )),
            (_, _, Some(p)) if !m.used => flags.push(format!(
                "magnet {k}'s pair gives dx {:+.4}, dy {:+.4} mm, {:.4} mm from the others' median: not used \
                 (moved between the two sides, or not a magnet of the ring)",
                p[0],
                p[1],
                (p[0] - median_offset[0]).hypot(p[1] - median_offset[1])
            )),
            _ => {}
        }
    }
}

/// Magnets whose peak field is off the ring's median by more than `peak_tolerance` (each named once).
fn flag_peaks(flags: &mut Vec<String>, params: &ScanParams, magnets: &[MagnetRecord]) {
    let peaks: Vec<(usize, f64)> = magnets
        .iter()
        .flat_map(|m| {
            m.near
                .iter()
                .chain(m.far.iter())
                .map(move |d| (m.index, d.peak))
        })
        .filter(|(_, p)| *p != 0.0)
        .collect();
    if peaks.len() < 3 {
        return;
    }
    let typical = median(&peaks.iter().map(|p| p.1).collect::<Vec<_>>());
    let mut flagged = Vec::new();
    for (k, peak) in peaks {
        if (peak - typical).abs() > params.peak_tolerance * typical.abs() && !flagged.contains(&k) {
            flagged.push(k);
            flags.push(format!(
                "magnet {k} peaks at {:.1} mT against the ring's {:.1} mT (a different, damaged or sunk \
                 magnet?)",
                peak * 1e3,
                typical * 1e3
            ));
        }
    }
}

/// Magnets the ring fit found off the ring (its outliers index the placed magnets).
fn flag_ring_outliers(flags: &mut Vec<String>, magnets: &[MagnetRecord], fit: &CircleFit) {
    let placed: Vec<&MagnetRecord> = magnets.iter().filter(|m| m.position.is_some()).collect();
    for &i in &fit.outliers {
        if let Some(m) = placed.get(i)
            && let Some(residual) = m.ring_residual
        {
            flags.push(format!(
                "magnet {} is {:.3} mm off the ring (placement; dx and dy do not depend on it)",
                m.index,
                residual.abs()
            ));
        }
    }
}

/// Median of a non-empty slice.
pub(crate) fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_offsets_invert_the_geometry() {
        // Magnet at bed-frame angle α, radius ρ; sensor line offset (dx, dy).
        let (rho, alpha, dx, dy) = (97.3f64, 0.8f64, 1.2f64, -0.7f64);
        let h = (rho * rho - dy * dy).sqrt();
        let near = Detection {
            r: h - dx,
            theta: alpha - dy.atan2(h),
            peak: 0.0,
        };
        let far = Detection {
            r: -h - dx,
            theta: alpha - dy.atan2(-h) + 4.0 * PI,
            peak: 0.0,
        };
        let [ex, ey] = pair_offsets(&near, &far);
        assert!((ex - dx).abs() < 1e-12 && (ey - dy).abs() < 1e-12);
    }
}
