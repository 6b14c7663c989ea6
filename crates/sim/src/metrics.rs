//! Deviation metrics of a replay: running max/RMS per layer and overall, and the decimated path kept for
//! pictures and feature checks (bounded: the decimation distance doubles whenever the cap is reached).

use serde::Serialize;

/// XY distance from `p` to the segment `a`–`b` (to `a` when the segment is a point), for points of two or
/// three coordinates: the path deviation of a replay and the corner search of the feature finder.
pub(crate) fn segment_distance<const N: usize>(p: [f64; N], a: [f64; N], b: [f64; N]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

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
    /// The statistics of both sample sets together.
    pub fn merge(&mut self, other: &DeviationStats) {
        if other.samples == 0 {
            return;
        }
        if self.samples == 0 || other.max_path_deviation > self.max_path_deviation {
            self.max_path_deviation = other.max_path_deviation;
            self.worst_at = other.worst_at;
        }
        self.samples += other.samples;
        self.sum_sq_path += other.sum_sq_path;
        self.max_time_error = self.max_time_error.max(other.max_time_error);
        self.sum_sq_time += other.sum_sq_time;
        self.max_model_error = self.max_model_error.max(other.max_model_error);
        self.sum_sq_model += other.sum_sq_model;
        self.max_z_error = self.max_z_error.max(other.max_z_error);
    }

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

/// Statistics of one layer, or of consecutive layers merged into one row (deposited samples).
#[derive(Debug, Clone, PartialEq)]
pub struct LayerStats {
    /// Number of the first layer in the row (0-based, in print order).
    pub first: usize,
    /// Layers in the row (1 until the table is merged to stay bounded).
    pub count: usize,
    /// Intended Z at the row's first deposited sample, and the highest intended Z in it.
    pub z: f64,
    pub z_max: f64,
    pub stats: DeviationStats,
}

impl LayerStats {
    fn merge(&mut self, next: &LayerStats) {
        self.count += next.count;
        self.z_max = self.z_max.max(next.z_max);
        self.stats.merge(&next.stats);
    }
}

/// Merges consecutive rows so that at most `max_rows` remain (each row then stands for a run of layers).
pub fn summarise_layers(rows: &[LayerStats], max_rows: usize) -> Vec<LayerStats> {
    let per_row = rows.len().div_ceil(max_rows.max(1)).max(1);
    rows.chunks(per_row)
        .map(|chunk| {
            let mut row = chunk[0].clone();
            for next in &chunk[1..] {
                row.merge(next);
            }
            row
        })
        .collect()
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
    /// Number of the layer (deposited points), or of the last layer started.
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
    /// Layers found so far (rows may hold several once the table is merged).
    pub(crate) layer_count: usize,
    layer: LayerTrack,
}

/// Where the current layer began and how the nozzle has gone since, to find layers from the motion itself.
#[derive(Debug, Clone, Copy, Default)]
struct LayerTrack {
    /// The previous sample deposited (extrusion has gone on without a break).
    depositing: bool,
    /// Intended Z of the previous deposited sample.
    last_z: f64,
    /// XY and Z where the current layer's deposition began.
    start_xy: [f64; 2],
    start_z: f64,
    /// The nozzle has been at least `TURN_AWAY` from `start_xy` since.
    away: bool,
    /// Closest distance to `start_xy` while coming back within `TURN_CLOSE`.
    closest: Option<f64>,
}

/// Deposition resumed (after travel) at a Z differing by more than this (mm) starts a new layer.
const LAYER_Z_TOLERANCE: f64 = 1e-6;
/// Z rising by more than this (mm) between two consecutive deposited samples is a layer change, not the slow
/// climb of a spiral (samples are a millisecond apart; a spiral vase climbs a layer height per turn).
const LAYER_STEP: f64 = 0.02;
/// A spiral (Z climbing while extruding) closes a layer each turn: when the nozzle, having gone at least
/// `TURN_AWAY` (mm) from where the layer began, comes back within `TURN_CLOSE` of it and has passed its
/// closest approach.
const TURN_AWAY: f64 = 3.0;
const TURN_CLOSE: f64 = 1.0;
/// Rows of the per-layer table kept at most: beyond, consecutive rows are merged in pairs (memory stays flat).
pub const MAX_LAYER_ROWS: usize = 2048;

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
            layer_count: 0,
            layer: LayerTrack::default(),
        }
    }

    /// Whether the deposited sample `s` begins a new layer: the first deposition; deposition resumed at another
    /// Z; a Z step between consecutive deposited samples; or a spiral (Z climbing while extruding) back at
    /// the turn's start.
    fn starts_layer(&mut self, s: &Sample) -> bool {
        let t = &mut self.layer;
        let xy = [s.intended[0], s.intended[1]];
        let z = s.intended[2];
        let from_start = (xy[0] - t.start_xy[0]).hypot(xy[1] - t.start_xy[1]);
        let new = if self.layers.is_empty() {
            true
        } else if !t.depositing {
            (z - t.last_z).abs() > LAYER_Z_TOLERANCE && (z - t.start_z).abs() > LAYER_Z_TOLERANCE
        } else if (z - t.last_z).abs() > LAYER_STEP {
            true
        } else if z - t.start_z > LAYER_Z_TOLERANCE && t.away && from_start <= TURN_CLOSE {
            // Back at the turn's start: the turn ends where the nozzle came closest to it.
            let passed = t.closest.is_some_and(|c| from_start > c);
            t.closest = Some(t.closest.map_or(from_start, |c| c.min(from_start)));
            passed
        } else {
            false
        };
        if new {
            t.start_xy = xy;
            t.start_z = z;
            t.away = false;
            t.closest = None;
        } else if from_start >= TURN_AWAY {
            t.away = true;
        }
        t.depositing = true;
        t.last_z = z;
        new
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
            if self.starts_layer(s) {
                if self.layers.len() >= MAX_LAYER_ROWS {
                    self.layers = summarise_layers(&self.layers, MAX_LAYER_ROWS / 2);
                }
                self.layers.push(LayerStats {
                    first: self.layer_count,
                    count: 1,
                    z: s.intended[2],
                    z_max: s.intended[2],
                    stats: DeviationStats::default(),
                });
                self.layer_count += 1;
                new_layer = true;
            }
            if let Some(layer) = self.layers.last_mut() {
                layer.stats.add(s);
                layer.z_max = layer.z_max.max(s.intended[2]);
            }
        } else {
            self.layer.depositing = false;
        }
        self.keep(s, new_layer);
    }

    fn keep(&mut self, s: &Sample, new_layer: bool) {
        let layer = self.layer_count.saturating_sub(1);
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

    #[test]
    fn segment_distance_closed_form() {
        let a = [0.0, 0.0, 0.0];
        let b = [10.0, 0.0, 0.0];
        assert_eq!(segment_distance([5.0, 3.0, 0.0], a, b), 3.0);
        assert_eq!(segment_distance([13.0, 4.0, 0.0], a, b), 5.0);
        assert_eq!(segment_distance([-3.0, -4.0, 0.0], a, a), 5.0);
        assert_eq!(segment_distance([5.0, 3.0], [0.0, 0.0], [10.0, 0.0]), 3.0);
    }

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

    fn at(x: f64, y: f64, z: f64, deposited: bool) -> Sample {
        Sample {
            intended: [x, y, z],
            actual: [x, y, z],
            deposited,
            ..sample(0.0, 0.0, z)
        }
    }

    #[test]
    fn a_spiral_is_one_layer_per_turn_and_discrete_layers_are_one_each() {
        let mut a = Analysis::new(0.05, 100_000);
        let per_turn = 1000;
        for i in 0..5 * per_turn {
            let angle = std::f64::consts::TAU * i as f64 / per_turn as f64;
            let z = 0.2 + 0.2 * i as f64 / per_turn as f64;
            a.record(&at(10.0 * angle.cos(), 10.0 * angle.sin(), z, true));
        }
        assert_eq!(a.layer_count, 5);
        // Each full turn climbs 0.2 mm (the last one stops a sample short).
        for l in &a.layers {
            assert!((l.z_max - l.z - 0.2).abs() < 2e-3, "{l:?}");
        }
        // Travel, then three flat layers: three more.
        let mut b = Analysis::new(0.05, 100_000);
        for layer in 0..3 {
            let z = 0.2 * (layer + 1) as f64;
            b.record(&at(0.0, 0.0, z + 0.4, false));
            for i in 0..=per_turn {
                let angle = std::f64::consts::TAU * i as f64 / per_turn as f64;
                b.record(&at(10.0 * angle.cos(), 10.0 * angle.sin(), z, true));
            }
            // Two islands of the same layer, a hop between them.
            b.record(&at(30.0, 0.0, z + 0.4, false));
            b.record(&at(30.0, 0.0, z, true));
            b.record(&at(31.0, 0.0, z, true));
        }
        assert_eq!(b.layer_count, 3);
    }

    #[test]
    fn the_layer_table_stays_bounded() {
        let mut a = Analysis::new(0.05, 1000);
        let layers = 5 * MAX_LAYER_ROWS + 3;
        for layer in 0..layers {
            let z = 0.1 * (layer + 1) as f64;
            a.record(&at(0.0, 0.0, z, true));
            a.record(&at(1.0, 0.0, z, true));
        }
        assert_eq!(a.layer_count, layers);
        assert!(a.layers.len() <= MAX_LAYER_ROWS, "{} rows", a.layers.len());
        assert_eq!(a.layers.iter().map(|l| l.count).sum::<usize>(), layers);
        assert_eq!(
            a.layers.iter().map(|l| l.stats.samples).sum::<u64>(),
            2 * layers as u64
        );
        let rows = summarise_layers(&a.layers, 200);
        assert!(rows.len() <= 200);
        assert_eq!(rows.iter().map(|l| l.count).sum::<usize>(), layers);
        assert_eq!(rows[0].first, 0);
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
