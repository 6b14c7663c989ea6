//! One magnet's centre, from where the search saw it strongest: sensor profiles with a parabola's vertex
//! ([`PeakMethod::Interpolated`]), or the thesis' comparator grid ([`PeakMethod::ThesisAveraging`]).

use super::error::ScanError;
use super::hardware::{ScanHardware, Scanner};
use super::params::PeakMethod;
use super::result::Detection;

impl<H: ScanHardware> Scanner<'_, H> {
    /// The magnet's centre near (r, θ), by the configured method.
    pub(super) fn refine(&mut self, r: f64, theta: f64) -> Result<Detection, ScanError> {
        match self.p.method {
            PeakMethod::Interpolated => self.peak_interpolated(r, theta),
            PeakMethod::ThesisAveraging => self.peak_thesis(r, theta),
        }
    }

    /// Alternate θ and R profiles; each profile's vertex re-centres the next.
    fn peak_interpolated(&mut self, mut r: f64, mut theta: f64) -> Result<Detection, ScanError> {
        let mut peak = 0.0;
        for _ in 0..self.p.peak_rounds.max(1) {
            let (t, _) = self.profile(r, theta, Axis::Bed)?;
            theta = t;
            let (rr, b) = self.profile(r, theta, Axis::Arm)?;
            r = rr;
            peak = b;
        }
        Ok(Detection { r, theta, peak })
    }

    /// One 1-D profile through (r, θ) along `axis`; returns the vertex coordinate and the peak value.
    /// If the vertex falls outside the sampled window the window moves to the best sample and retries.
    fn profile(&mut self, r: f64, theta: f64, axis: Axis) -> Result<(f64, f64), ScanError> {
        let p = self.p;
        let n = (p.peak_half_width / p.fine_step).round().max(2.0) as i64;
        let step = match axis {
            Axis::Arm => p.fine_step,
            Axis::Bed => p.fine_step * self.rad_per_mm(r),
        };
        let mut centre = match axis {
            Axis::Arm => r,
            Axis::Bed => theta,
        };
        for _ in 0..4 {
            let mut xs = Vec::with_capacity(2 * n as usize + 1);
            let mut ys = Vec::with_capacity(2 * n as usize + 1);
            for k in -n..=n {
                let target = centre + k as f64 * step;
                let (rr, tt, b) = match axis {
                    Axis::Arm => self.sample(target, theta)?,
                    Axis::Bed => self.sample(r, target)?,
                };
                xs.push(match axis {
                    Axis::Arm => rr,
                    Axis::Bed => tt,
                });
                ys.push(b);
            }
            let half = n as f64 * step;
            if let Some((x, y)) =
                parabola_vertex(&xs, &ys, centre).filter(|(x, _)| (x - centre).abs() <= 0.5 * half)
            {
                return Ok((x, y));
            }
            let best = ys
                .iter()
                .enumerate()
                .fold(0, |bi, (i, y)| if *y > ys[bi] { i } else { bi });
            centre = xs[best];
        }
        let (rr, tt, b) = self.sample(r, theta)?;
        Ok((if axis == Axis::Arm { rr } else { tt }, b))
    }

    /// Thesis-style peak: step grid over the magnet, mean of the positions where the comparator fires.
    fn peak_thesis(&mut self, r: f64, theta: f64) -> Result<Detection, ScanError> {
        let p = self.p;
        let n = (p.thesis_half_width / p.fine_step).round() as i64;
        let dth = p.fine_step * self.rad_per_mm(r);
        let (mut sr, mut st, mut count, mut peak) = (0.0, 0.0, 0usize, 0.0f64);
        for (row, i) in (-n..=n).enumerate() {
            for j in -n..=n {
                let j = if row % 2 == 0 { j } else { -j };
                let (rr, tt, b) =
                    self.sample(r + i as f64 * p.fine_step, theta + j as f64 * dth)?;
                if b >= p.comparator_threshold {
                    sr += rr;
                    st += tt;
                    count += 1;
                    peak = peak.max(b);
                }
            }
        }
        if count == 0 {
            return Ok(Detection {
                r,
                theta,
                peak: 0.0,
            });
        }
        Ok(Detection {
            r: sr / count as f64,
            theta: st / count as f64,
            peak,
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Axis {
    Arm,
    Bed,
}

/// Least-squares parabola through (x, y) in coordinates relative to `origin`; its vertex if it is a maximum.
pub(crate) fn parabola_vertex(xs: &[f64], ys: &[f64], origin: f64) -> Option<(f64, f64)> {
    let mut ata = nalgebra::Matrix3::zeros();
    let mut atb = nalgebra::Vector3::zeros();
    for (x, y) in xs.iter().zip(ys) {
        let u = x - origin;
        let row = nalgebra::Vector3::new(u * u, u, 1.0);
        ata += row * row.transpose();
        atb += row * *y;
    }
    let s = ata.lu().solve(&atb)?;
    let (a, b, c) = (s[0], s[1], s[2]);
    if a.is_nan() || a >= 0.0 {
        return None;
    }
    let u = -b / (2.0 * a);
    let v = c - b * b / (4.0 * a);
    (u.is_finite() && v.is_finite()).then_some((origin + u, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parabola_vertex_of_exact_parabola() {
        let xs: Vec<f64> = (0..9).map(|i| i as f64 * 0.3).collect();
        let ys: Vec<f64> = xs.iter().map(|x| 5.0 - 2.0 * (x - 1.1).powi(2)).collect();
        let (x, y) = parabola_vertex(&xs, &ys, 1.2).expect("vertex");
        assert!((x - 1.1).abs() < 1e-12 && (y - 5.0).abs() < 1e-12);
        let up: Vec<f64> = xs.iter().map(|x| x * x).collect();
        assert!(parabola_vertex(&xs, &up, 0.0).is_none());
    }
}
