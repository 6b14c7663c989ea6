//! The centre scan as a printer runs it: continuous sweeps instead of stop-and-read.
//!
//! The arm stops at a series of radii (passes) across the magnet ring, on the near side of the rotation centre
//! and then on the far side, and at each the bed turns a full revolution while the MCU's ADC reports the Hall
//! sensor. Every sample carries the arm and bed readings at its own time (from the steppers' position history),
//! so the speed profile of the passes does not matter. A magnet's centre is then found from the field alone:
//! along a pass the field is symmetric about the magnet's angle, and across passes each pass's peak field is
//! symmetric about the magnet's radius. The centre of each symmetric profile is taken as the centroid of the
//! part above half its peak, over the piecewise-linear profile: unbiased for any symmetric field shape (a
//! parabola fit is not, when the samples sit unevenly about the peak). The detections then go through the same
//! fit as a logged scan ([`crate::scan::centre_from_detections`]).

use crate::scan::{Detection, DetectionSlots, ScanError, median, parabola_vertex};
use std::f64::consts::{PI, TAU};

/// How the Hall sensor's ADC reading (Klipper's 0..1 of full scale) becomes a field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HallAdc {
    /// The ADC's reference voltage (V): 3.3 V on most 32-bit boards, 5 V on AVR boards.
    pub reference: f64,
    /// The sensor's sensitivity (V/T): a 49E-class IC gives about 16 V/T (1.6 mV/G) at 5 V, proportionally
    /// less at 3.3 V.
    pub sensitivity: f64,
    /// Field beyond which the sensor is not linear (T); a scan that reaches it is refused.
    pub saturation: f64,
}

impl Default for HallAdc {
    fn default() -> Self {
        Self {
            reference: 3.3,
            sensitivity: 16.0 * 3.3 / 5.0,
            saturation: 0.1,
        }
    }
}

/// What the sweep covers and how magnets are told from noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepParams {
    pub magnet_count: usize,
    /// Nominal radius of the magnet ring (mm).
    pub ring_radius: f64,
    /// Largest expected |dx|, |dy| (mm).
    pub max_offset: f64,
    /// Radial spacing of the passes (mm).
    pub pass_pitch: f64,
    /// How far from a magnet its field stays above half the peak, with margin (mm): the band of passes reaches
    /// this far beyond the ring on both sides, and a pass reads this far along the bed on both sides.
    pub field_reach: f64,
    /// Field that counts as "a magnet here" (T).
    pub detection_threshold: f64,
    pub adc: HallAdc,
}

impl Default for SweepParams {
    fn default() -> Self {
        Self {
            magnet_count: 16,
            ring_radius: 100.0,
            max_offset: 2.0,
            pass_pitch: 0.5,
            field_reach: 4.0,
            detection_threshold: 0.010,
            adc: HallAdc::default(),
        }
    }
}

/// One ADC report: the pass it was taken in, the arm (mm) and bed (rad, the kinematics' sign) readings at its
/// time, and the ADC value (0..1 of full scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepSample {
    pub pass: usize,
    pub arm: f64,
    pub bed: f64,
    pub adc: f64,
}

impl SweepParams {
    fn validate(&self) -> Result<(), ScanError> {
        let positive = [
            ("ring_radius", self.ring_radius),
            ("pass_pitch", self.pass_pitch),
            ("field_reach", self.field_reach),
            ("detection_threshold", self.detection_threshold),
            ("adc reference", self.adc.reference),
            ("sensitivity", self.adc.sensitivity),
            ("saturation", self.adc.saturation),
        ];
        if let Some((name, v)) = positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Err(ScanError::InvalidParams(format!(
                "{name} must be a positive number, got {v}"
            )));
        }
        if !(self.max_offset.is_finite() && self.max_offset >= 0.0) {
            return Err(ScanError::InvalidParams(format!(
                "max_offset must be a non-negative number, got {}",
                self.max_offset
            )));
        }
        if !(3..=1000).contains(&self.magnet_count) {
            return Err(ScanError::InvalidParams(format!(
                "the ring needs 3 to 1000 magnets, got {}",
                self.magnet_count
            )));
        }
        if self.band() >= self.ring_radius || self.band() / self.pass_pitch > 500.0 {
            return Err(ScanError::InvalidParams(format!(
                "a band of ±{:.1} mm at {} mm pitch does not fit a ring of radius {} mm",
                self.band(),
                self.pass_pitch,
                self.ring_radius
            )));
        }
        Ok(())
    }

    /// Half width of the radial band the passes cover around the ring (mm).
    fn band(&self) -> f64 {
        self.max_offset + self.field_reach
    }

    /// Along-the-bed half window of a magnet at arm reading `arm` (rad): its field's reach, with margin for the
    /// estimate of its angle.
    fn window(&self, arm: f64) -> f64 {
        1.5 * self.field_reach / arm.abs().max(0.5 * self.ring_radius)
    }

    /// How far past a full revolution each pass must turn the bed, at both ends (rad), so that every magnet
    /// is read whole in one stretch of every pass.
    pub fn bed_overlap(&self) -> f64 {
        self.window(self.ring_radius - self.band()) + 0.01
    }
}

/// The arm readings of the passes, in the order to run them: the near side from outside inwards, then the far
/// side from the centre outwards (one short crossing of the centre between them). Each pass turns the bed one
/// full revolution (with some overlap at both ends for the speed ramps).
pub fn pass_arms(p: &SweepParams) -> Result<Vec<f64>, ScanError> {
    p.validate()?;
    let count = (2.0 * p.band() / p.pass_pitch).round() as usize + 1;
    let step = 2.0 * p.band() / (count - 1) as f64;
    let near = (0..count).map(|i| p.ring_radius + p.band() - i as f64 * step);
    let far = (0..count).map(|i| -(p.ring_radius - p.band() + i as f64 * step));
    Ok(near.chain(far).collect())
}

/// The field each sample reads (T), positive at the magnets whichever pole faces up: the ADC reading minus its
/// median (most of a revolution sees no magnet), scaled by the sensor. Refuses a sensor at its limits.
fn fields(p: &SweepParams, samples: &[SweepSample]) -> Result<Vec<f64>, ScanError> {
    if samples.is_empty() {
        return Err(ScanError::NoSamples);
    }
    if let Some(i) = samples
        .iter()
        .position(|s| !(s.arm.is_finite() && s.bed.is_finite() && s.adc.is_finite()))
    {
        return Err(ScanError::InvalidParams(format!(
            "sample {i} is not a finite reading"
        )));
    }
    let at_rail = samples
        .iter()
        .filter(|s| s.adc <= 0.001 || s.adc >= 0.999)
        .count();
    if at_rail > 0 {
        return Err(ScanError::Saturated(format!(
            "{at_rail} of {} ADC readings are at the end of the ADC's range (a 5 V sensor on a 3.3 V ADC, or \
             magnets too close)",
            samples.len()
        )));
    }
    let baseline = median(&samples.iter().map(|s| s.adc).collect::<Vec<_>>());
    let scale = p.adc.reference / p.adc.sensitivity;
    let raw: Vec<f64> = samples.iter().map(|s| (s.adc - baseline) * scale).collect();
    let extreme = raw
        .iter()
        .fold(0.0f64, |e, &b| if b.abs() > e.abs() { b } else { e });
    if extreme.abs() >= p.adc.saturation {
        return Err(ScanError::Saturated(format!(
            "the field reaches {:.1} mT, beyond the sensor's linear range ({:.1} mT): raise the sensor or use \
             weaker magnets",
            extreme.abs() * 1e3,
            p.adc.saturation * 1e3
        )));
    }
    let sign = if extreme < 0.0 { -1.0 } else { 1.0 };
    Ok(raw.into_iter().map(|b| sign * b).collect())
}

/// One pass: its arm reading and its (bed, field) readings in bed order, equal bed readings merged.
struct Pass {
    arm: f64,
    profile: Vec<(f64, f64)>,
}

fn passes(samples: &[SweepSample], fields: &[f64]) -> Vec<Pass> {
    let count = samples.iter().map(|s| s.pass + 1).max().unwrap_or(0);
    let mut grouped: Vec<Vec<(f64, f64, f64)>> = vec![Vec::new(); count];
    for (s, &b) in samples.iter().zip(fields) {
        grouped[s.pass].push((s.bed, b, s.arm));
    }
    grouped
        .into_iter()
        .filter(|g| !g.is_empty())
        .map(|mut g| {
            g.sort_by(|a, b| a.0.total_cmp(&b.0));
            let arm = median(&g.iter().map(|x| x.2).collect::<Vec<_>>());
            let mut profile: Vec<(f64, f64, usize)> = Vec::with_capacity(g.len());
            for (bed, b, _) in g {
                match profile.last_mut() {
                    Some(last) if last.0 == bed => {
                        last.1 += b;
                        last.2 += 1;
                    }
                    _ => profile.push((bed, b, 1)),
                }
            }
            let profile = profile
                .into_iter()
                .map(|(bed, sum, n)| (bed, sum / n as f64))
                .collect();
            Pass { arm, profile }
        })
        .collect()
}

/// The centre of a symmetric peak in a piecewise-linear profile, and the peak's height: the centroid of the part
/// above half the peak around the highest point. `None` when that part runs into either end of the profile.
pub fn symmetric_centre(profile: &[(f64, f64)]) -> Option<(f64, f64)> {
    let top = (0..profile.len()).max_by(|&a, &b| profile[a].1.total_cmp(&profile[b].1))?;
    let peak = peak_height(profile, top);
    let level = 0.5 * peak;
    let mut first = top;
    while first > 0 && profile[first - 1].1 >= level {
        first -= 1;
    }
    let mut last = top;
    while last + 1 < profile.len() && profile[last + 1].1 >= level {
        last += 1;
    }
    if first == 0 || last + 1 == profile.len() {
        return None;
    }
    let (mut area, mut moment) = (0.0, 0.0);
    for pair in profile[first - 1..=last + 1].windows(2) {
        let (a, m) = segment_above(pair[0], pair[1], level);
        area += a;
        moment += m;
    }
    (area > 0.0).then(|| (moment / area, peak))
}

/// Area and first moment of `max(f − level, 0)` over one linear segment.
fn segment_above((x0, y0): (f64, f64), (x1, y1): (f64, f64), level: f64) -> (f64, f64) {
    let (g0, g1) = (y0 - level, y1 - level);
    // Clip the segment to where it is above the level (g is linear along it).
    let (xa, ga, xb, gb) = match (g0 >= 0.0, g1 >= 0.0) {
        (true, true) => (x0, g0, x1, g1),
        (false, false) => return (0.0, 0.0),
        (true, false) => (x0, g0, x0 + (x1 - x0) * g0 / (g0 - g1), 0.0),
        (false, true) => (x1 - (x1 - x0) * g1 / (g1 - g0), 0.0, x1, g1),
    };
    let h = xb - xa;
    (
        0.5 * (ga + gb) * h,
        h * (xa * (2.0 * ga + gb) + xb * (ga + 2.0 * gb)) / 6.0,
    )
}

/// The peak height from a parabola through the points above 80% of the highest (less noisy than the highest
/// reading alone).
fn peak_height(profile: &[(f64, f64)], top: usize) -> f64 {
    let highest = profile[top].1;
    let near_top: Vec<&(f64, f64)> = profile.iter().filter(|p| p.1 >= 0.8 * highest).collect();
    let xs: Vec<f64> = near_top.iter().map(|p| p.0).collect();
    let ys: Vec<f64> = near_top.iter().map(|p| p.1).collect();
    match parabola_vertex(&xs, &ys, profile[top].0) {
        Some((_, y)) if near_top.len() >= 3 && y >= highest && y <= 1.5 * highest => y,
        _ => highest,
    }
}

/// Which side of the centre a pass is on; the far side sees each magnet with the bed turned by π.
fn side_turn(arm: f64) -> f64 {
    if arm < 0.0 { PI } else { 0.0 }
}

/// The magnets' approximate bed-frame angles on one side: the highest reading of every run above the threshold,
/// grouped by angle (one group per magnet).
fn magnet_angles(p: &SweepParams, side: &[&Pass]) -> Vec<f64> {
    let mut hits: Vec<(f64, f64)> = Vec::new();
    for pass in side {
        let turn = side_turn(pass.arm);
        let mut best: Option<(f64, f64)> = None;
        for &(bed, b) in &pass.profile {
            if b >= p.detection_threshold {
                if best.is_none_or(|(_, top)| b > top) {
                    best = Some((bed, b));
                }
            } else if let Some((bed_top, top)) = best.take() {
                hits.push(((bed_top + turn).rem_euclid(TAU), top));
            }
        }
    }
    hits.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gap = 0.5 * TAU / p.magnet_count as f64;
    let mut groups: Vec<(f64, f64)> = Vec::new();
    for (angle, top) in hits {
        match groups.last_mut() {
            Some(g) if angle - g.0 < gap => {
                if top > g.1 {
                    *g = (angle, top);
                }
            }
            _ => groups.push((angle, top)),
        }
    }
    // The group at the end of the circle may be the one at its start.
    if groups.len() > 1 && groups[0].0 + TAU - groups[groups.len() - 1].0 < gap {
        let wrapped = groups.pop().unwrap_or_default();
        if wrapped.1 > groups[0].1 {
            groups[0] = wrapped;
        }
    }
    groups.into_iter().map(|g| g.0).collect()
}

/// One pass's reading of the magnet at bed-frame angle `angle`: (bed angle at the field's centre, peak field),
/// from the stretch of the pass around it that the pass covers completely.
fn pass_reading(p: &SweepParams, pass: &Pass, angle: f64) -> Option<(f64, f64)> {
    let (lo, hi) = (pass.profile.first()?.0, pass.profile.last()?.0);
    let window = p.window(pass.arm);
    let target = angle - side_turn(pass.arm);
    let k = ((lo + window - target) / TAU).ceil();
    let centre = target + k * TAU;
    if centre + window > hi {
        return None;
    }
    let stretch: Vec<(f64, f64)> = pass
        .profile
        .iter()
        .copied()
        .filter(|(bed, _)| (bed - centre).abs() <= window)
        .collect();
    symmetric_centre(&stretch)
}

/// One magnet on one side: its centre across the passes, or why it could not be taken.
fn magnet_detection(p: &SweepParams, side: &[&Pass], angle: f64) -> Result<Detection, String> {
    let mut readings: Vec<(f64, f64, f64)> = side
        .iter()
        .filter_map(|pass| pass_reading(p, pass, angle).map(|(bed, b)| (pass.arm, bed, b)))
        .collect();
    readings.sort_by(|a, b| a.0.total_cmp(&b.0));
    let radial: Vec<(f64, f64)> = readings.iter().map(|r| (r.0, r.2)).collect();
    let (r, peak) = symmetric_centre(&radial).ok_or(
        "its field does not fall to half its peak inside the band of passes (widen hall_max_offset)",
    )?;
    // The bed angle at the centre moves slowly with the arm (by dy/r²): a straight line through the readings
    // above half the peak, taken at the centre.
    let mut strong: Vec<(f64, f64)> = readings
        .iter()
        .filter(|x| x.2 >= 0.5 * peak)
        .map(|x| (x.0, x.1))
        .collect();
    let first = strong.first().map(|s| s.1).ok_or("no pass reads it")?;
    for s in &mut strong {
        s.1 -= ((s.1 - first) / TAU).round() * TAU;
    }
    Ok(Detection {
        r,
        theta: line_at(&strong, r),
        peak,
    })
}

/// Least-squares line through `points`, evaluated at `x` (the mean for a single point or equal xs).
fn line_at(points: &[(f64, f64)], x: f64) -> f64 {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx > 0.0 {
        my + sxy / sxx * (x - mx)
    } else {
        my
    }
}

/// Every magnet on one side, in the order of their bed-frame angles.
fn side_detections(
    p: &SweepParams,
    side: &[&Pass],
    name: &str,
) -> Result<Vec<(f64, Detection)>, ScanError> {
    let angles = magnet_angles(p, side);
    if angles.len() != p.magnet_count {
        return Err(ScanError::WrongMagnetCount {
            side: name.to_string(),
            found: angles.len(),
            expected: p.magnet_count,
        });
    }
    angles
        .into_iter()
        .map(|angle| {
            magnet_detection(p, side, angle)
                .map(|d| (angle, d))
                .map_err(|why| ScanError::BadPeak {
                    side: name.to_string(),
                    angle_deg: angle.to_degrees(),
                    why,
                })
        })
        .collect()
}

/// The magnet detections of a sweep: each magnet peaked on the near and the far side, indexed by the near side's
/// order of angles (the far side matched to the nearest angle).
pub fn detect(p: &SweepParams, samples: &[SweepSample]) -> Result<DetectionSlots, ScanError> {
    p.validate()?;
    let fields = fields(p, samples)?;
    let passes = passes(samples, &fields);
    let near_passes: Vec<&Pass> = passes.iter().filter(|s| s.arm > 0.0).collect();
    let far_passes: Vec<&Pass> = passes.iter().filter(|s| s.arm < 0.0).collect();
    let near = side_detections(p, &near_passes, "near")?;
    let far = side_detections(p, &far_passes, "far")?;
    let mut slots = DetectionSlots {
        near: near.iter().map(|(_, d)| Some(*d)).collect(),
        far: vec![None; near.len()],
        // Each side found exactly the ring's magnets (`side_detections` refuses another count).
        ring: Some(p.magnet_count),
    };
    for (angle, d) in far {
        let distance = |a: f64| (a - angle + PI).rem_euclid(TAU) - PI;
        let nearest = (0..near.len())
            .min_by(|&a, &b| {
                distance(near[a].0)
                    .abs()
                    .total_cmp(&distance(near[b].0).abs())
            })
            .unwrap_or(0);
        if slots.far[nearest].replace(d).is_some() {
            return Err(ScanError::BadPeak {
                side: "far".into(),
                angle_deg: angle.to_degrees(),
                why: "two far-side peaks match the same near-side magnet".into(),
            });
        }
    }
    Ok(slots)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bump(x: f64, centre: f64) -> f64 {
        // A symmetric, non-parabolic peak (the dipole's shape is not a parabola either).
        1.0 / (1.0 + ((x - centre) / 1.3).powi(2)).powf(2.5)
    }

    #[test]
    fn symmetric_centre_is_exact_for_symmetric_shapes_sampled_unevenly() {
        for centre in [0.0, 0.17, 0.31, -0.42] {
            let xs: Vec<f64> = (-40..=40).map(|i| i as f64 * 0.25 + 0.03).collect();
            let profile: Vec<(f64, f64)> = xs.iter().map(|&x| (x, bump(x, centre))).collect();
            let (c, peak) = symmetric_centre(&profile).expect("centre");
            assert!((c - centre).abs() < 2e-3, "{c} vs {centre}");
            assert!((peak - 1.0).abs() < 0.01, "{peak}");
        }
    }

    #[test]
    fn a_peak_cut_by_the_profile_end_has_no_centre() {
        let profile: Vec<(f64, f64)> = (0..20)
            .map(|i| (i as f64 * 0.25, bump(i as f64 * 0.25, 0.5)))
            .collect();
        assert_eq!(symmetric_centre(&profile), None);
    }

    #[test]
    fn segment_integrals_match_closed_forms() {
        // g = x on [0, 2] above level 0: area 2, moment 8/3.
        let (a, m) = segment_above((0.0, 0.0), (2.0, 2.0), 0.0);
        assert!((a - 2.0).abs() < 1e-12 && (m - 8.0 / 3.0).abs() < 1e-12);
        // Crossing the level halfway: only [1, 2] counts, g = x − 1.
        let (a, m) = segment_above((0.0, 0.0), (2.0, 2.0), 1.0);
        assert!(
            (a - 0.5).abs() < 1e-12 && (m - (4.0 / 3.0 - 0.5 + 0.0)).abs() < 1e-12,
            "{m}"
        );
    }

    #[test]
    fn passes_span_the_band_on_both_sides() {
        let p = SweepParams::default();
        let arms = pass_arms(&p).expect("passes");
        assert_eq!(arms.len(), 2 * 25);
        assert_eq!(arms[0], 106.0);
        assert!((arms[24] - 94.0).abs() < 1e-12 && (arms[25] + 94.0).abs() < 1e-12);
        assert!((arms[49] + 106.0).abs() < 1e-12);
        let bad = SweepParams {
            max_offset: 99.0,
            ..p
        };
        assert!(pass_arms(&bad).is_err());
    }

    #[test]
    fn saturation_and_empty_scans_are_refused() {
        let p = SweepParams::default();
        assert_eq!(detect(&p, &[]), Err(ScanError::NoSamples));
        let rail = [SweepSample {
            pass: 0,
            arm: 100.0,
            bed: 0.0,
            adc: 1.0,
        }];
        assert!(matches!(detect(&p, &rail), Err(ScanError::Saturated(_))));
    }
}
