//! The motors against time, for the page's plots: one point per planned move while they are few, then
//! neighbouring points merged two into one, so the series stays within its size whatever the print's length. A
//! merged point keeps the larger peak of the two, so no limit hit disappears from the plot.

use crate::motors::MotorPass;

/// One point: the moves from `start` up to the next point's start.
#[derive(Debug, Clone, PartialEq)]
struct Point {
    start: f64,
    /// Each motor's position at the end of the last move merged here.
    position: Vec<f64>,
    /// Each motor's peak speed and acceleration over the merged moves.
    speed: Vec<f64>,
    accel: Vec<f64>,
    /// The nozzle's peak speed (mm/s).
    nozzle: f64,
}

/// The motors' positions, peak speeds and accelerations, and the nozzle's peak speed, against time.
#[derive(Debug, Clone)]
pub struct Series {
    points: Vec<Point>,
    /// At most this many points (at least `limit / 2` once the print has more moves).
    limit: usize,
    /// Moves per point so far (a power of two).
    per_point: usize,
    /// The moves gathered into the point being filled.
    pending: usize,
}

/// The series as columns, one value per point.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Columns {
    pub time: Vec<f32>,
    /// `[motor][point]`.
    pub position: Vec<Vec<f32>>,
    pub speed: Vec<Vec<f32>>,
    pub accel: Vec<Vec<f32>>,
    pub nozzle: Vec<f32>,
}

impl Series {
    pub fn new(limit: usize) -> Series {
        Series {
            points: Vec::new(),
            limit: limit.max(2),
            per_point: 1,
            pending: 0,
        }
    }

    /// A move starting at `start` with nozzle peak `nozzle` (mm/s) and what its motors did.
    pub fn push(&mut self, start: f64, nozzle: f64, motors: &MotorPass) {
        if self.pending > 0
            && let Some(last) = self.points.last_mut()
        {
            merge_into(last, nozzle, motors);
        } else {
            self.points.push(Point {
                start,
                position: motors.end.clone(),
                speed: motors.speed.clone(),
                accel: motors.accel.clone(),
                nozzle,
            });
        }
        self.pending += 1;
        if self.pending == self.per_point {
            self.pending = 0;
            if self.points.len() >= self.limit {
                self.halve();
            }
        }
    }

    /// Every two neighbouring points become one.
    fn halve(&mut self) {
        let points = std::mem::take(&mut self.points);
        let mut iter = points.into_iter();
        while let Some(mut first) = iter.next() {
            if let Some(second) = iter.next() {
                let pass = MotorPass {
                    end: second.position,
                    speed: second.speed,
                    accel: second.accel,
                    rate: Vec::new(),
                    curvature: Vec::new(),
                };
                merge_into(&mut first, second.nozzle, &pass);
            }
            self.points.push(first);
        }
        self.per_point *= 2;
    }

    pub fn columns(&self) -> Columns {
        let motors = self.points.first().map_or(0, |p| p.position.len());
        let column = |f: &dyn Fn(&Point) -> f64| -> Vec<f32> {
            self.points.iter().map(|p| f(p) as f32).collect()
        };
        Columns {
            time: column(&|p| p.start),
            position: (0..motors).map(|m| column(&|p| p.position[m])).collect(),
            speed: (0..motors).map(|m| column(&|p| p.speed[m])).collect(),
            accel: (0..motors).map(|m| column(&|p| p.accel[m])).collect(),
            nozzle: column(&|p| p.nozzle),
        }
    }
}

/// `point` now also covers a later move (or point).
fn merge_into(point: &mut Point, nozzle: f64, motors: &MotorPass) {
    point.position.clone_from(&motors.end);
    for (mine, theirs) in point.speed.iter_mut().zip(&motors.speed) {
        *mine = mine.max(*theirs);
    }
    for (mine, theirs) in point.accel.iter_mut().zip(&motors.accel) {
        *mine = mine.max(*theirs);
    }
    point.nozzle = point.nozzle.max(nozzle);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merging_keeps_every_peak_and_the_last_position() {
        let mut series = Series::new(8);
        for i in 0..1000 {
            let peak = if i == 777 { 99.0 } else { 1.0 };
            let pass = MotorPass {
                end: vec![i as f64],
                speed: vec![peak],
                accel: vec![peak * 10.0],
                rate: vec![1.0],
                curvature: vec![0.0],
            };
            series.push(i as f64, peak, &pass);
        }
        let c = series.columns();
        assert!(c.time.len() <= 8 && c.time.len() >= 4, "{}", c.time.len());
        assert_eq!(c.speed[0].iter().copied().fold(0.0, f32::max), 99.0);
        assert_eq!(c.accel[0].iter().copied().fold(0.0, f32::max), 990.0);
        assert_eq!(c.position[0].last().copied(), Some(999.0));
        assert_eq!(c.time[0], 0.0);
        assert!(c.time.windows(2).all(|w| w[0] < w[1]));
    }
}
