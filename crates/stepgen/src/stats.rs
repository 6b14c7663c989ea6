//! Per-motor step statistics for summaries: counts, net steps, clock range, minimum interval and peak rates.

use std::collections::VecDeque;

use crate::sink::StepSink;

/// Collects statistics from a motor's step stream (a [`StepSink`]).
#[derive(Debug, Clone)]
pub struct StepStats {
    window_ticks: u64,
    steps: u64,
    net: i64,
    first_clock: Option<u64>,
    last_clock: u64,
    min_interval: Option<u64>,
    window: VecDeque<u64>,
    peak_in_window: usize,
}

/// Finished statistics of one motor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorStats {
    pub steps: u64,
    /// Sum of +1 / −1 over all steps.
    pub net_steps: i64,
    pub first_clock: Option<u64>,
    pub last_clock: Option<u64>,
    /// Smallest gap between consecutive steps (ticks).
    pub min_interval_ticks: Option<u64>,
    /// `clock_hz / min_interval` (steps/s); infinite when two steps share a tick.
    pub peak_rate_min_interval: f64,
    /// Most steps in any 1 ms window, per second.
    pub peak_rate_1ms: f64,
    /// Step pairs removed by the step+dir+step filter.
    pub filtered_pairs: u64,
}

impl StepStats {
    /// Statistics for a motor whose MCU clock runs at `clock_hz`.
    pub fn new(clock_hz: f64) -> Self {
        StepStats {
            window_ticks: (clock_hz * 1e-3).round().max(1.0) as u64,
            steps: 0,
            net: 0,
            first_clock: None,
            last_clock: 0,
            min_interval: None,
            window: VecDeque::new(),
            peak_in_window: 0,
        }
    }

    /// The finished numbers; `filtered_pairs` comes from the motor (see `MotorStepper::filtered_pairs`).
    pub fn summary(&self, clock_hz: f64, filtered_pairs: u64) -> MotorStats {
        let peak_rate_min_interval = match self.min_interval {
            Some(0) => f64::INFINITY,
            Some(ticks) => clock_hz / ticks as f64,
            None => 0.0,
        };
        MotorStats {
            steps: self.steps,
            net_steps: self.net,
            first_clock: self.first_clock,
            last_clock: self.first_clock.map(|_| self.last_clock),
            min_interval_ticks: self.min_interval,
            peak_rate_min_interval,
            peak_rate_1ms: self.peak_in_window as f64 * 1e3,
            filtered_pairs,
        }
    }
}

impl StepSink for StepStats {
    fn step(&mut self, clock: u64, dir: bool) {
        if self.first_clock.is_none() {
            self.first_clock = Some(clock);
        } else {
            let gap = clock.saturating_sub(self.last_clock);
            self.min_interval = Some(self.min_interval.map_or(gap, |m| m.min(gap)));
        }
        self.last_clock = clock;
        self.steps += 1;
        self.net += if dir { 1 } else { -1 };
        // Sliding window of steps within the last millisecond (half-open: (clock − 1 ms, clock]).
        while self
            .window
            .front()
            .is_some_and(|&c| c + self.window_ticks <= clock)
        {
            self.window.pop_front();
        }
        self.window.push_back(clock);
        self.peak_in_window = self.peak_in_window.max(self.window.len());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_intervals_and_window() {
        let mut stats = StepStats::new(16e6);
        // 5 steps 1000 ticks apart (within 1 ms = 16000 ticks), then one far away, backwards.
        for i in 0..5 {
            stats.step(1_000_000 + i * 1000, true);
        }
        stats.step(2_000_000, false);
        let s = stats.summary(16e6, 3);
        assert_eq!(s.steps, 6);
        assert_eq!(s.net_steps, 4);
        assert_eq!(s.first_clock, Some(1_000_000));
        assert_eq!(s.last_clock, Some(2_000_000));
        assert_eq!(s.min_interval_ticks, Some(1000));
        assert_eq!(s.peak_rate_min_interval, 16_000.0);
        assert_eq!(s.peak_rate_1ms, 5_000.0);
        assert_eq!(s.filtered_pairs, 3);
    }

    #[test]
    fn empty_stream_has_no_clocks() {
        let s = StepStats::new(16e6).summary(16e6, 0);
        assert_eq!(s.steps, 0);
        assert_eq!(s.first_clock, None);
        assert_eq!(s.peak_rate_min_interval, 0.0);
    }
}
