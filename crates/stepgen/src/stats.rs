//! Per-motor step statistics for summaries: counts, net steps, clock range, minimum interval and peak rates.

use crate::audit::{StepProblem, first_short_step, min_step_ticks};
use crate::sink::StepSink;

/// Collects statistics from a motor's step stream (a [`StepSink`]).
#[derive(Debug, Clone)]
pub struct StepStats {
    clock_hz: f64,
    window_ticks: u64,
    steps: u64,
    net: i64,
    /// Clock of the first step (meaningful once `steps > 0`).
    first_clock: u64,
    last_clock: u64,
    /// Smallest gap so far (`u64::MAX` before the second step).
    min_interval: u64,
    /// The most recent clocks, step `i` at `recent[i & (len − 1)]`; the length is a power of two above
    /// `peak_in_window`, so the step `peak_in_window` places back is always still there.
    recent: Vec<u64>,
    /// Most steps in one window (meaningful once `steps > 0`: the first step makes a window of one).
    peak_in_window: usize,
    /// The last run handed over: its length and smallest gap (from the step before it on).
    previous_run: (usize, u64),
    /// The step audit: the shortest gap an MCU may be given (see [`crate::min_step_ticks`]), and the first step
    /// found closer than that.
    min_ticks: u64,
    problem: Option<StepProblem>,
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
            clock_hz,
            window_ticks: (clock_hz * 1e-3).round().max(1.0) as u64,
            steps: 0,
            net: 0,
            first_clock: 0,
            last_clock: 0,
            min_interval: u64::MAX,
            recent: vec![0; 16],
            peak_in_window: 1,
            previous_run: (0, 0),
            min_ticks: 1,
            problem: None,
        }
    }

    /// Audit the stream for a motor stepping at most `max_step_rate` steps/s (besides never two steps on one
    /// tick, which is always checked).
    pub fn audited(mut self, max_step_rate: Option<f64>) -> Self {
        self.min_ticks = min_step_ticks(max_step_rate, self.clock_hz);
        self
    }

    /// The first step closer to the one before it than the audit allows, if any.
    pub fn problem(&self) -> Option<StepProblem> {
        self.problem
    }

    #[cold]
    fn note_short_run(&mut self, clocks: &[u64], previous: u64) {
        if self.problem.is_none() {
            self.problem = first_short_step(clocks, Some(previous), self.min_ticks);
        }
    }

    /// The finished numbers; `filtered_pairs` comes from the motor (see `MotorStepper::filtered_pairs`).
    pub fn summary(&self, clock_hz: f64, filtered_pairs: u64) -> MotorStats {
        let any = self.steps > 0;
        let min_interval = (self.steps > 1).then_some(self.min_interval);
        let peak_rate_min_interval = match min_interval {
            Some(0) => f64::INFINITY,
            Some(ticks) => clock_hz / ticks as f64,
            None => 0.0,
        };
        MotorStats {
            steps: self.steps,
            net_steps: self.net,
            first_clock: any.then_some(self.first_clock),
            last_clock: any.then_some(self.last_clock),
            min_interval_ticks: min_interval,
            peak_rate_min_interval,
            peak_rate_1ms: if any {
                self.peak_in_window as f64 * 1e3
            } else {
                0.0
            },
            filtered_pairs,
        }
    }
}

impl StepStats {
    /// Double the ring of recent clocks, keeping the steps before `end` at their places.
    #[cold]
    fn grow_recent(&mut self, end: usize) {
        let old_len = self.recent.len();
        let mut grown = vec![0; 2 * old_len];
        for i in end.saturating_sub(old_len)..end {
            grown[i & (2 * old_len - 1)] = self.recent[i & (old_len - 1)];
        }
        self.recent = grown;
    }

    /// The peak is the most steps in a window (clock − 1 ms, clock] ending at any step. A window ending at a
    /// step holds at most one step more than the window ending at the step before, so the peak grows by one
    /// exactly when the step `peak` places back is still inside the new window: one comparison per step,
    /// whatever the step rate. `clocks` follow at least one earlier step, so `peak ≤ index` throughout;
    /// `run_min_interval` is the smallest gap in `clocks` (from the step before them on).
    fn update_peak(&mut self, clocks: &[u64], run_min_interval: u64) {
        if self.peak_unchanged_by(clocks, run_min_interval) {
            self.remember_tail(clocks);
            return;
        }
        let mut index = self.steps as usize;
        let mut peak = self.peak_in_window;
        let mut rest = clocks;
        while !rest.is_empty() {
            let ring = &mut self.recent[..];
            let mask = ring.len() - 1;
            let mut taken = 0;
            for &clock in rest {
                peak += usize::from(ring[(index - peak) & mask] + self.window_ticks > clock);
                ring[index & mask] = clock;
                index += 1;
                taken += 1;
                if peak >= ring.len() {
                    break;
                }
            }
            rest = &rest[taken..];
            if peak >= self.recent.len() {
                self.grow_recent(index);
            }
        }
        self.peak_in_window = peak;
    }

    /// Whether no step of `clocks` has its step `peak` places back inside its window (the common case: the
    /// peak is set by the fastest stretch so far). When the previous run held at least `peak` steps, every
    /// window that ends in `clocks` spans `peak` gaps of this run or that one, so `peak` gaps of the smaller
    /// of their smallest sizes spanning the window settle it at once. Otherwise two branch-free passes: the
    /// steps whose step `peak` back is in the ring, then those whose step `peak` back is in `clocks` itself.
    fn peak_unchanged_by(&self, clocks: &[u64], run_min_interval: u64) -> bool {
        let peak = self.peak_in_window;
        let spans_window = |gap: u64| gap.saturating_mul(peak as u64) >= self.window_ticks;
        let (previous_len, previous_min_interval) = self.previous_run;
        if previous_len >= peak && spans_window(run_min_interval.min(previous_min_interval)) {
            return true;
        }
        let index = self.steps as usize;
        let mask = self.recent.len() - 1;
        let from_ring = clocks
            .iter()
            .take(peak)
            .enumerate()
            .fold(true, |ok, (i, &clock)| {
                ok & (self.recent[(index + i - peak) & mask] + self.window_ticks <= clock)
            });
        let within = spans_window(run_min_interval)
            || clocks
                .iter()
                .skip(peak)
                .zip(clocks)
                .fold(true, |ok, (&clock, &back)| {
                    ok & (back + self.window_ticks <= clock)
                });
        from_ring & within
    }

    /// Keep the last clocks of `clocks` in the ring: only the last `peak` are ever looked back at.
    fn remember_tail(&mut self, clocks: &[u64]) {
        let mask = self.recent.len() - 1;
        let first = clocks.len().saturating_sub(self.peak_in_window);
        let index = self.steps as usize;
        for (i, &clock) in clocks.iter().enumerate().skip(first) {
            self.recent[(index + i) & mask] = clock;
        }
    }
}

impl StepStats {
    /// Take a run of clocks; `inner_gap` is the smallest gap between its neighbours when the caller knows it.
    #[inline]
    fn record(&mut self, clocks: &[u64], dir: bool, inner_gap: Option<u64>) {
        let Some((&first, later)) = clocks.split_first() else {
            return;
        };
        let rest = if self.steps == 0 {
            // The first step: a window of one, no interval yet.
            self.first_clock = first;
            self.last_clock = first;
            self.recent[0] = first;
            self.steps = 1;
            later
        } else {
            clocks
        };
        let (Some(&next), Some(&last)) = (rest.first(), rest.last()) else {
            self.net += if dir { 1 } else { -1 };
            return;
        };
        // The gaps of `rest`, the first from the clock before it (on the very first run that gap is inside
        // `clocks` too).
        let run_min_interval = match inner_gap {
            Some(gap) => gap.min(next.saturating_sub(self.last_clock)),
            None => smallest_gap(self.last_clock, rest),
        };
        self.min_interval = self.min_interval.min(run_min_interval);
        if run_min_interval < self.min_ticks {
            self.note_short_run(rest, self.last_clock);
        }
        self.update_peak(rest, run_min_interval);
        self.previous_run = (rest.len(), run_min_interval);
        self.last_clock = last;
        self.steps += rest.len() as u64;
        let count = clocks.len() as i64;
        self.net += if dir { count } else { -count };
    }
}

/// The smallest gap between consecutive clocks of `clocks`, the first from `previous` (a clock before the one
/// ahead of it makes a gap of 0).
#[inline]
fn smallest_gap(previous: u64, clocks: &[u64]) -> u64 {
    let mut before = previous;
    let mut smallest = u64::MAX;
    for &clock in clocks {
        smallest = smallest.min(clock.saturating_sub(before));
        before = clock;
    }
    smallest
}

impl StepSink for StepStats {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        self.record(&[clock], dir, None);
    }

    #[inline]
    fn steps(&mut self, clocks: &[u64], dir: bool) {
        self.record(clocks, dir, None);
    }

    #[inline]
    fn steps_with_gap(&mut self, clocks: &[u64], dir: bool, inner_gap: u64) {
        self.record(clocks, dir, Some(inner_gap));
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

    /// The peak by brute force: for every step, the steps in (clock − window, clock].
    fn brute_peak(clocks: &[u64], window: u64) -> usize {
        (0..clocks.len())
            .map(|i| {
                clocks[..=i]
                    .iter()
                    .filter(|&&c| c + window > clocks[i])
                    .count()
            })
            .max()
            .unwrap_or(0)
    }

    /// Bursts of steps sharing ticks (the ring has to grow past 16), gaps, and steady rates.
    fn bursty_clocks() -> Vec<u64> {
        let mut clocks = Vec::new();
        let mut clock = 5u64;
        for round in 0..40u64 {
            let burst = (round * 7) % 45;
            clocks.extend(std::iter::repeat_n(clock, burst as usize));
            for k in 0..(round % 9) {
                clock += 1000 + 3000 * k;
                clocks.push(clock);
            }
            clock += 16_000 * (round % 3);
        }
        clocks
    }

    #[test]
    fn peak_window_matches_brute_force_through_bursts() {
        let clocks = bursty_clocks();
        let mut stats = StepStats::new(16e6);
        for &c in &clocks {
            stats.step(c, true);
        }
        let summary = stats.summary(16e6, 0);
        assert_eq!(
            summary.peak_rate_1ms,
            brute_peak(&clocks, 16_000) as f64 * 1e3
        );
        assert!(summary.peak_rate_1ms >= 44_000.0);
    }

    #[test]
    fn runs_of_any_length_give_the_same_statistics_as_single_steps() {
        let clocks = bursty_clocks();
        let mut one_by_one = StepStats::new(16e6);
        for &c in &clocks {
            one_by_one.step(c, false);
        }
        for run in [1, 2, 3, 7, 16, 17, 64, 500] {
            let mut in_runs = StepStats::new(16e6);
            for chunk in clocks.chunks(run) {
                in_runs.steps(chunk, false);
            }
            assert_eq!(
                in_runs.summary(16e6, 0),
                one_by_one.summary(16e6, 0),
                "runs of {run}"
            );
        }
        assert_eq!(
            one_by_one.summary(16e6, 0).peak_rate_1ms,
            brute_peak(&clocks, 16_000) as f64 * 1e3
        );
    }

    proptest::proptest! {
        /// Stretches of steady gaps (bursts of shared ticks, rates near the peak, slow steps) handed over in
        /// any run lengths give the brute-force peak and smallest gap.
        #[test]
        fn random_streams_match_brute_force(
            stretches in proptest::collection::vec(
                (proptest::prop_oneof![0u64..3, 900u64..1400, 1000u64..40_000], 1usize..60),
                1..12,
            ),
            run in 1usize..80,
        ) {
            let gaps: Vec<u64> = stretches
                .iter()
                .flat_map(|&(gap, count)| std::iter::repeat_n(gap, count))
                .collect();
            let clocks: Vec<u64> = gaps.iter().scan(100u64, |c, g| { *c += g; Some(*c) }).collect();
            let mut stats = StepStats::new(16e6);
            for chunk in clocks.chunks(run) {
                stats.steps(chunk, true);
            }
            let summary = stats.summary(16e6, 0);
            proptest::prop_assert_eq!(summary.peak_rate_1ms, brute_peak(&clocks, 16_000) as f64 * 1e3);
            proptest::prop_assert_eq!(
                summary.min_interval_ticks,
                gaps.get(1..).and_then(|later| later.iter().min().copied())
            );
        }
    }

    #[test]
    fn runs_told_their_gaps_give_the_same_statistics() {
        let clocks = bursty_clocks();
        let mut plain = StepStats::new(16e6);
        for chunk in clocks.chunks(7) {
            plain.steps(chunk, true);
        }
        for run in [1, 2, 7, 64] {
            let mut told = StepStats::new(16e6).audited(Some(20_000.0));
            let mut untold = StepStats::new(16e6).audited(Some(20_000.0));
            for chunk in clocks.chunks(run) {
                let inner = chunk
                    .windows(2)
                    .map(|w| w[1] - w[0])
                    .min()
                    .unwrap_or(u64::MAX);
                told.steps_with_gap(chunk, false, inner);
                untold.steps(chunk, false);
            }
            assert_eq!(
                told.summary(16e6, 0),
                untold.summary(16e6, 0),
                "runs of {run}"
            );
            assert_eq!(told.problem(), untold.problem(), "runs of {run}");
            assert_eq!(told.summary(16e6, 0).steps, plain.summary(16e6, 0).steps);
        }
    }

    #[test]
    fn first_interval_of_a_first_run_counts() {
        let mut stats = StepStats::new(16e6);
        stats.steps(&[1000, 1010, 20_000, 40_000], true);
        let s = stats.summary(16e6, 0);
        assert_eq!(s.min_interval_ticks, Some(10));
        assert_eq!((s.steps, s.net_steps), (4, 4));
        assert_eq!((s.first_clock, s.last_clock), (Some(1000), Some(40_000)));
        assert_eq!(s.peak_rate_1ms, 2_000.0);
    }

    #[test]
    fn empty_stream_has_no_clocks() {
        let s = StepStats::new(16e6).summary(16e6, 0);
        assert_eq!(s.steps, 0);
        assert_eq!(s.first_clock, None);
        assert_eq!(s.peak_rate_min_interval, 0.0);
    }
}
