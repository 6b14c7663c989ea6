//! Time → clock conversion and Klipper's step+dir+step filter.
//!
//! Semantics learnt from Klipper's `stepcompress.c`: the newest step is held back ("pending"). When the next
//! step goes the other way and is less than the filter time later (compared in ticks), both steps are dropped
//! and nothing is pending afterwards, so in a chain of reversals the following step starts afresh. A pending
//! step becomes final when a step in the same direction follows, when a reversal comes late enough, or when the
//! solver reports that the motor has fully reached the step's position ([`StepFilter::commit`]).

use crate::sink::StepSink;

/// Final steps kept before they go to the sink in one slice.
const OUT_CAPACITY: usize = 64;

/// Converts solver times to clocks and filters rapid step+dir+step sequences for one motor.
///
/// Final steps are collected and handed to the sink in slices of one direction (when the slice is full, when
/// the direction changes, and on [`StepFilter::flush`]), so a sink is called once per many steps even when
/// pieces bring one or two steps each.
#[derive(Debug, Clone)]
pub struct StepFilter {
    clock_hz: f64,
    /// Filter window in ticks (Klipper compares the tick difference, as a double, with `0.000750 · freq`).
    window_ticks: f64,
    pending: Option<(u64, bool)>,
    filtered_pairs: u64,
    last_emitted: u64,
    /// Final steps not yet handed to the sink (`out[..out_len]`, all in direction `out_dir`).
    out: [u64; OUT_CAPACITY],
    out_len: usize,
    out_dir: bool,
    /// The smallest gap between neighbours of `out[..out_len]` (`u64::MAX` below two steps), told to the sink.
    out_gap: u64,
}

impl StepFilter {
    pub fn new(clock_hz: f64, filter_time: f64) -> Self {
        StepFilter {
            clock_hz,
            window_ticks: filter_time * clock_hz,
            pending: None,
            filtered_pairs: 0,
            last_emitted: 0,
            out: [0; OUT_CAPACITY],
            out_len: 0,
            out_dir: false,
            out_gap: u64::MAX,
        }
    }

    /// Round an absolute print time to the nearest clock tick. Times are finite and ≥ 0 by construction; the
    /// float-to-integer cast truncates, which is `floor` for these non-negative values. The cast goes through
    /// `i64` (one instruction; a direct `u64` cast needs several) and saturates; `max(0)` keeps it
    /// non-negative.
    #[inline]
    pub fn clock_of(&self, time: f64) -> u64 {
        clock_at(time, self.clock_hz)
    }

    /// A new step at absolute print time `time`.
    #[inline]
    pub fn push<S: StepSink + ?Sized>(&mut self, time: f64, dir: bool, sink: &mut S) {
        self.push_clock(self.clock_of(time), dir, sink);
    }

    /// Steps at `clocks` (non-decreasing), all in direction `dir`: the same as pushing them one by one. Only
    /// the first can meet a reversal; each later one makes the step before it final, so all but the last
    /// become final here, in one pass, and the last is held back in turn.
    #[inline]
    pub fn push_run<S: StepSink + ?Sized>(&mut self, clocks: &[u64], dir: bool, sink: &mut S) {
        let Some(&first) = clocks.first() else {
            return;
        };
        let mut body = clocks;
        if let Some((pending_clock, pending_dir)) = self.pending.take() {
            if self.cancels(pending_clock, pending_dir, first, dir) {
                self.filtered_pairs += 1;
                body = &clocks[1..];
            } else {
                self.emit(pending_clock, pending_dir, sink);
            }
        }
        let Some((&last, middle)) = body.split_last() else {
            return;
        };
        if !middle.is_empty() {
            self.emit_run(middle, dir, sink);
        }
        self.pending = Some((last, dir));
    }

    /// The steps at `clocks`, all final, into the outgoing slice. Each is kept no earlier than the one before
    /// it, so the gaps between neighbours are plain differences, and their minimum is kept for the sink.
    #[inline]
    fn emit_run<S: StepSink + ?Sized>(&mut self, clocks: &[u64], dir: bool, sink: &mut S) {
        if self.out_len > 0 && self.out_dir != dir {
            self.flush(sink);
        }
        let mut rest = clocks;
        while let Some((&first, after_first)) = rest.split_first() {
            if self.out_len == OUT_CAPACITY {
                self.flush(sink);
            }
            if self.out_len == 0 {
                // The first step of a slice has no neighbour before it in the slice.
                self.emit(first, dir, sink);
                rest = after_first;
                continue;
            }
            let room = OUT_CAPACITY - self.out_len;
            let (now, later) = rest.split_at(room.min(rest.len()));
            let (mut previous, mut gap) = (self.last_emitted, self.out_gap);
            let slots = &mut self.out[self.out_len..self.out_len + now.len()];
            for (slot, &clock) in slots.iter_mut().zip(now) {
                let kept = previous.max(clock);
                gap = gap.min(kept - previous);
                previous = kept;
                *slot = kept;
            }
            self.out_len += now.len();
            self.last_emitted = previous;
            self.out_gap = gap;
            rest = later;
        }
    }

    /// Whether a step at `clock` in direction `dir` removes the pending step with it (a quick reversal).
    #[inline]
    fn cancels(&self, pending_clock: u64, pending_dir: bool, clock: u64, dir: bool) -> bool {
        pending_dir != dir && ((clock as i64 - pending_clock as i64) as f64) < self.window_ticks
    }

    #[inline]
    fn push_clock<S: StepSink + ?Sized>(&mut self, clock: u64, dir: bool, sink: &mut S) {
        if let Some((pending_clock, pending_dir)) = self.pending {
            if self.cancels(pending_clock, pending_dir, clock, dir) {
                self.pending = None;
                self.filtered_pairs += 1;
                return;
            }
            self.emit(pending_clock, pending_dir, sink);
        }
        self.pending = Some((clock, dir));
    }

    /// The motor reached the pending step's full position: the step can no longer be rolled back.
    #[inline(always)]
    pub fn commit<S: StepSink + ?Sized>(&mut self, sink: &mut S) {
        if let Some((clock, dir)) = self.pending.take() {
            self.emit(clock, dir, sink);
        }
    }

    /// Hand the final steps collected so far to the sink (the held-back step stays held back).
    pub fn flush<S: StepSink + ?Sized>(&mut self, sink: &mut S) {
        if self.out_len > 0 {
            sink.steps_with_gap(&self.out[..self.out_len], self.out_dir, self.out_gap);
            self.out_len = 0;
            self.out_gap = u64::MAX;
        }
    }

    /// One final step into the outgoing slice.
    #[inline]
    fn emit<S: StepSink + ?Sized>(&mut self, clock: u64, dir: bool, sink: &mut S) {
        if self.out_len == OUT_CAPACITY || (self.out_len > 0 && self.out_dir != dir) {
            self.flush(sink);
        }
        // Rounding can put a step one tick before the previous one only if both are within a tick; keep the
        // stream monotonic for consumers.
        let clock = clock.max(self.last_emitted);
        if self.out_len > 0 {
            self.out_gap = self.out_gap.min(clock - self.last_emitted);
        }
        self.last_emitted = clock;
        self.out[self.out_len] = clock;
        self.out_len += 1;
        self.out_dir = dir;
    }

    /// Number of step pairs removed so far.
    pub fn filtered_pairs(&self) -> u64 {
        self.filtered_pairs
    }

    pub fn clock_hz(&self) -> f64 {
        self.clock_hz
    }
}

/// See [`StepFilter::clock_of`].
#[inline(always)]
pub(crate) fn clock_at(time: f64, clock_hz: f64) -> u64 {
    ((time * clock_hz + 0.5) as i64).max(0) as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sink::Step;

    fn run(steps: &[(f64, bool)]) -> (Vec<Step>, u64) {
        let mut filter = StepFilter::new(16e6, 750e-6);
        let mut out = Vec::new();
        for &(t, dir) in steps {
            filter.push(t, dir, &mut out);
        }
        filter.commit(&mut out);
        filter.flush(&mut out);
        (out, filter.filtered_pairs())
    }

    /// Klipper's rule written plainly, one step at a time with nothing collected: the reference.
    #[derive(Default)]
    struct Reference {
        pending: Option<(u64, bool)>,
        last: u64,
        out: Vec<Step>,
        pairs: u64,
    }

    impl Reference {
        fn push(&mut self, clock: u64, dir: bool) {
            if let Some((pending_clock, pending_dir)) = self.pending.take() {
                if pending_dir != dir && ((clock as i64 - pending_clock as i64) as f64) < 12_000.0 {
                    self.pairs += 1;
                    return;
                }
                self.emit(pending_clock, pending_dir);
            }
            self.pending = Some((clock, dir));
        }

        fn commit(&mut self) {
            if let Some((clock, dir)) = self.pending.take() {
                self.emit(clock, dir);
            }
        }

        fn emit(&mut self, clock: u64, dir: bool) {
            self.last = self.last.max(clock);
            self.out.push(Step {
                clock: self.last,
                dir,
            });
        }
    }

    #[test]
    fn clock_rounds_to_nearest_tick() {
        let filter = StepFilter::new(16e6, 750e-6);
        assert_eq!(filter.clock_of(1.0), 16_000_000);
        assert_eq!(filter.clock_of(1.0 + 0.4 / 16e6), 16_000_000);
        assert_eq!(filter.clock_of(1.0 + 0.6 / 16e6), 16_000_001);
    }

    #[test]
    fn quick_reversal_removes_both_steps() {
        let (out, pairs) = run(&[(1.0, true), (1.0005, false), (1.002, false)]);
        assert_eq!(
            out,
            vec![Step {
                clock: 16_032_000,
                dir: false
            }]
        );
        assert_eq!(pairs, 1);
    }

    #[test]
    fn slow_reversal_keeps_both_steps() {
        let (out, pairs) = run(&[(1.0, true), (1.001, false)]);
        assert_eq!(out.len(), 2);
        assert_eq!(pairs, 0);
    }

    #[test]
    fn window_is_compared_in_ticks() {
        // 11999 ticks apart is filtered, 12000 is not.
        let (out, _) = run(&[(1.0, true), (1.0 + 11999.0 / 16e6, false)]);
        assert!(out.is_empty());
        let (out, _) = run(&[(1.0, true), (1.0 + 12000.0 / 16e6, false)]);
        assert_eq!(out.len(), 2);
    }

    #[test]
    fn chain_of_reversals_restarts_after_a_removed_pair() {
        // + - removed, then + becomes pending afresh, then - removes it with the next.
        let (out, pairs) = run(&[
            (1.0, true),
            (1.0001, false),
            (1.0002, true),
            (1.0003, false),
            (1.0004, true),
        ]);
        assert_eq!(pairs, 2);
        assert_eq!(
            out,
            vec![Step {
                clock: 16_006_400,
                dir: true
            }]
        );
    }

    proptest::proptest! {
        /// Runs of steps (with quick and slow reversals between them, commits and flushes) give the stream and
        /// count of removed pairs of the plain reference, whether pushed as runs or one at a time.
        #[test]
        fn runs_match_single_steps_and_the_reference(
            runs in proptest::collection::vec(
                (1usize..150, proptest::bool::ANY, 1u32..2000, 0u8..4),
                1..12,
            )
        ) {
            let mut by_run = StepFilter::new(16e6, 750e-6);
            let mut by_step = StepFilter::new(16e6, 750e-6);
            let mut reference = Reference::default();
            let (mut out_run, mut out_step) = (GapChecked::default(), GapChecked::default());
            let mut print_time = 1.0;
            for (len, dir, gap_us, after) in runs {
                // Steps `gap_us` µs apart, some sharing a tick after rounding.
                let times: Vec<f64> = (0..len).map(|i| (i / 2) as f64 * gap_us as f64 * 1e-6).collect();
                let clocks: Vec<u64> = times.iter().map(|&t| by_run.clock_of(print_time + t)).collect();
                for chunk in clocks.chunks(STEP_BATCH_FOR_TEST) {
                    by_run.push_run(chunk, dir, &mut out_run);
                }
                for &t in &times {
                    by_step.push(print_time + t, dir, &mut out_step);
                    reference.push(by_step.clock_of(print_time + t), dir);
                }
                // After a run: 0 nothing, 1 commit, 2 flush, 3 both.
                if after & 1 == 1 {
                    by_run.commit(&mut out_run);
                    by_step.commit(&mut out_step);
                    reference.commit();
                }
                if after & 2 == 2 {
                    by_run.flush(&mut out_run);
                }
                print_time += times.last().copied().unwrap_or(0.0) + gap_us as f64 * 0.7e-6;
            }
            for (filter, out) in [(&mut by_run, &mut out_run), (&mut by_step, &mut out_step)] {
                filter.commit(out);
                filter.flush(out);
            }
            reference.commit();
            proptest::prop_assert_eq!(&out_run.0, &reference.out);
            proptest::prop_assert_eq!(&out_step.0, &reference.out);
            proptest::prop_assert_eq!(by_run.filtered_pairs(), reference.pairs);
            proptest::prop_assert_eq!(by_step.filtered_pairs(), reference.pairs);
        }
    }

    /// Collects steps, checking the gap the filter tells with each slice.
    #[derive(Default)]
    struct GapChecked(Vec<Step>);

    impl StepSink for GapChecked {
        fn step(&mut self, clock: u64, dir: bool) {
            self.0.push(Step { clock, dir });
        }

        fn steps_with_gap(&mut self, clocks: &[u64], dir: bool, inner_gap: u64) {
            let gaps = clocks.windows(2).map(|w| w[1].saturating_sub(w[0]));
            assert_eq!(inner_gap, gaps.min().unwrap_or(u64::MAX), "{clocks:?}");
            self.steps(clocks, dir);
        }
    }

    /// Step generation hands runs of at most this many steps; longer ones exercise the chunking too.
    const STEP_BATCH_FOR_TEST: usize = 100;

    #[test]
    fn committed_step_is_not_rolled_back() {
        let mut filter = StepFilter::new(16e6, 750e-6);
        let mut out = Vec::new();
        filter.push(1.0, true, &mut out);
        filter.commit(&mut out);
        filter.push(1.0001, false, &mut out);
        filter.commit(&mut out);
        filter.flush(&mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(filter.filtered_pairs(), 0);
    }
}
