//! Deviation metrics of a replay: running max/RMS per layer and overall, and the decimated path kept for
//! pictures and feature checks (bounded: the decimation distance doubles whenever the cap is reached).

use serde::Serialize;

/// One simulated instant: where the nozzle should be and where it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub time: f64,
    pub intended: [f64; 3],
    pub actual: [f64; 3],
    /// |actual − intended| in XY at the same time (mm).
    pub time_error: f64,
    /// XY distance from the actual position to the intended path near this time (mm).
    pub path_deviation: f64,
    /// XY distance between where the true machine and the believed machine put the nozzle for the same
    /// motor state (the assembly error alone, without step quantisation; 0 on a perfect machine).
    pub model_error: f64,
    /// The extruder is pushing filament while the toolhead moves.
    pub deposited: bool,
    /// Local step resolution: XY displacement of one step of every motor, summed (mm), when tracked.
    pub resolution: Option<f64>,
}

/// Running statistics of deviations.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DeviationStats {
    pub samples: u64,
    pub max_path_deviation: f64,
    sum_sq_path: f64,
    pub max_time_error: f64,
    sum_sq_time: f64,
    pub max_z_error: f64,
    pub max_model_error: f64,
    sum_sq_model: f64,
    /// Intended XY where the largest path deviation happened.
    pub worst_at: [f64; 2],
}

impl DeviationStats {
    pub fn add(&mut self, s: &Sample) {
        self.samples += 1;
        if s.path_deviation > self.max_path_deviation || self.samples == 1 {
            self.max_path_deviation = s.path_deviation;
            self.worst_at = [s.intended[0], s.intended[1]];
        }
        self.sum_sq_path += s.path_deviation * s.path_deviation;
        self.max_time_error = self.max_time_error.max(s.time_error);
        self.sum_sq_time += s.time_error * s.time_error;
        self.max_model_error = self.max_model_error.max(s.model_error);
        self.sum_sq_model += s.model_error * s.model_error;
        self.max_z_error = self.max_z_error.max((s.actual[2] - s.intended[2]).abs());
    }

    pub fn rms_path_deviation(&self) -> f64 {
        rms(self.sum_sq_path, self.samples)
    }

    pub fn rms_time_error(&self) -> f64 {
        rms(self.sum_sq_time, self.samples)
    }

    pub fn rms_model_error(&self) -> f64 {
        rms(self.sum_sq_model, self.samples)
    }

    /// The serialisable summary.
    pub fn summary(&self) -> StatsSummary {
        StatsSummary {
            samples: self.samples,
            max_path_deviation: self.max_path_deviation,
            rms_path_deviation: self.rms_path_deviation(),
            max_time_error: self.max_time_error,
            rms_time_error: self.rms_time_error(),
            max_z_error: self.max_z_error,
            max_model_error: self.max_model_error,
            rms_model_error: self.rms_model_error(),
            worst_at: self.worst_at,
        }
    }
}

fn rms(sum_sq: f64, n: u64) -> f64 {
    if n == 0 {
        0.0
    } else {
        (sum_sq / n as f64).sqrt()
    }
}

/// Deviation statistics as reported (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StatsSummary {
    pub samples: u64,
    /// Distance of the deposited path from the intended path: what changes the printed shape.
    pub max_path_deviation: f64,
    pub rms_path_deviation: f64,
    /// Distance from where the nozzle should be at the same instant (includes lag along the path).
    pub max_time_error: f64,
    pub rms_time_error: f64,
    pub max_z_error: f64,
    /// True vs believed machine at the same motor state: the assembly error without step quantisation.
    pub max_model_error: f64,
    pub rms_model_error: f64,
    pub worst_at: [f64; 2],
}

/// Statistics of one layer (deposited samples at one intended Z).
#[derive(Debug, Clone, PartialEq)]
pub struct LayerStats {
    pub z: f64,
    pub stats: DeviationStats,
}

/// One kept point of the path; `deviation` is the largest path deviation of the samples it stands for
/// (those since the previous kept point, all with the same deposition flag).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PathPoint {
    pub time: f64,
    pub intended: [f64; 3],
    pub actual: [f64; 3],
    pub deviation: f64,
    pub deposited: bool,
    /// Index into the layer list (deposited points), or the last layer started.
    pub layer: usize,
}

/// Collects statistics and the decimated path.
#[derive(Debug, Clone)]
pub(crate) struct Analysis {
    pub(crate) all: DeviationStats,
    pub(crate) deposited: DeviationStats,
    pub(crate) layers: Vec<LayerStats>,
    pub(crate) path: Vec<PathPoint>,
    pub(crate) decimate: f64,
    max_points: usize,
    pending_deviation: f64,
    /// The latest sample not kept (with its layer), to close a run when the deposition flag changes.
    unkept: Option<(Sample, usize)>,
    pub(crate) worst_resolution_ratio: Option<f64>,
}

/// Two deposited samples belong to the same layer when their intended Z differ by less than this (mm).
const LAYER_Z_TOLERANCE: f64 = 1e-6;

impl Analysis {
    pub(crate) fn new(decimate: f64, max_points: usize) -> Self {
        Analysis {
            all: DeviationStats::default(),
            deposited: DeviationStats::default(),
            layers: Vec::new(),
            path: Vec::new(),
            decimate,
            max_points: max_points.max(16),
            pending_deviation: 0.0,
            unkept: None,
            worst_resolution_ratio: None,
        }
    }

    pub(crate) fn record(&mut self, s: &Sample) {
        self.all.add(s);
        if let Some(res) = s.resolution.filter(|r| *r > 0.0) {
            let ratio = s.time_error / res;
            self.worst_resolution_ratio =
                Some(self.worst_resolution_ratio.map_or(ratio, |w| w.max(ratio)));
        }
        let mut new_layer = false;
        if s.deposited {
            self.deposited.add(s);
            let same = self
                .layers
                .last()
                .is_some_and(|l| (l.z - s.intended[2]).abs() < LAYER_Z_TOLERANCE);
            if !same {
                self.layers.push(LayerStats {
                    z: s.intended[2],
                    stats: DeviationStats::default(),
                });
                new_layer = true;
            }
            if let Some(layer) = self.layers.last_mut() {
                layer.stats.add(s);
            }
        }
        self.keep(s, new_layer);
    }

    fn keep(&mut self, s: &Sample, new_layer: bool) {
        let layer = self.layers.len().saturating_sub(1);
        let flag_changed = self.path.last().is_some_and(|p| p.deposited != s.deposited);
        if flag_changed && let Some((prev, prev_layer)) = self.unkept.take() {
            // The last sample of the finished run closes it, with the deviations it stands for.
            self.push(&prev, prev_layer);
        }
        self.pending_deviation = self.pending_deviation.max(s.path_deviation);
        let far = self.path.last().is_none_or(|p| {
            p.deposited != s.deposited
                || (p.actual[0] - s.actual[0]).hypot(p.actual[1] - s.actual[1]) >= self.decimate
        });
        if far || new_layer {
            self.push(s, layer);
        } else {
            self.unkept = Some((*s, layer));
        }
    }

    fn push(&mut self, s: &Sample, layer: usize) {
        self.path.push(PathPoint {
            time: s.time,
            intended: s.intended,
            actual: s.actual,
            deviation: self.pending_deviation,
            deposited: s.deposited,
            layer,
        });
        self.pending_deviation = 0.0;
        self.unkept = None;
        if self.path.len() >= self.max_points {
            self.thin();
        }
    }

    /// Halve the kept points (every other one, carrying its deviation over) and double the spacing.
    fn thin(&mut self) {
        let old = std::mem::take(&mut self.path);
        let mut kept: Vec<PathPoint> = Vec::with_capacity(old.len() / 2 + 1);
        for pair in old.chunks(2) {
            let mut p = pair[pair.len() - 1];
            p.deviation = pair.iter().map(|q| q.deviation).fold(0.0, f64::max);
            if pair.iter().any(|q| q.deposited != p.deposited) {
                kept.extend_from_slice(pair);
            } else {
                kept.push(p);
            }
        }
        self.path = kept;
        self.decimate *= 2.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f64, dev: f64, z: f64) -> Sample {
        Sample {
            time: x,
            intended: [x, 0.0, z],
            actual: [x, dev, z],
            time_error: dev,
            path_deviation: dev,
            model_error: 0.0,
            deposited: true,
            resolution: None,
        }
    }

    #[test]
    fn stats_match_closed_form() {
        let mut a = Analysis::new(0.05, 1000);
        for (i, d) in [0.0, 0.3, 0.4].iter().enumerate() {
            a.record(&sample(i as f64, *d, 0.2));
        }
        a.record(&sample(3.0, 0.1, 0.4));
        assert_eq!(a.layers.len(), 2);
        assert!((a.deposited.rms_path_deviation() - (0.26f64 / 4.0).sqrt()).abs() < 1e-12);
        assert_eq!(a.layers[0].stats.max_path_deviation, 0.4);
        assert_eq!(a.layers[0].stats.worst_at, [2.0, 0.0]);
        assert_eq!(a.layers[1].stats.samples, 1);
    }

    #[test]
    fn kept_path_stays_bounded_and_keeps_the_maximum() {
        let mut a = Analysis::new(0.01, 100);
        for i in 0..10_000 {
            let dev = if i == 5_000 { 1.0 } else { 0.001 };
            a.record(&sample(i as f64 * 0.02, dev, 0.2));
        }
        assert!(a.path.len() < 100);
        assert!(a.decimate > 0.01);
        let max = a.path.iter().map(|p| p.deviation).fold(0.0, f64::max);
        assert_eq!(max, 1.0);
    }
}
