//! Where generated steps go: the [`StepSink`] trait and simple sinks (vectors, counters, pairs of sinks).

/// One step: MCU clock tick and direction (`true` = the motor position increases).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Step {
    pub clock: u64,
    pub dir: bool,
}

/// Receiver of one motor's final (filtered) steps, in non-decreasing clock order.
pub trait StepSink {
    fn step(&mut self, clock: u64, dir: bool);

    /// Several steps in one direction, in order (step generation hands runs over this way; a sink with
    /// per-step state can keep it in registers over the run).
    #[inline]
    fn steps(&mut self, clocks: &[u64], dir: bool) {
        for &clock in clocks {
            self.step(clock, dir);
        }
    }

    /// [`Self::steps`] for `clocks` whose smallest gap between neighbours is `inner_gap` (`u64::MAX` for
    /// fewer than two): step generation knows it as it makes them, so a sink that needs it (statistics) need
    /// not pass over the clocks again.
    #[inline]
    fn steps_with_gap(&mut self, clocks: &[u64], dir: bool, inner_gap: u64) {
        let _ = inner_gap;
        self.steps(clocks, dir);
    }

    /// The error the sink met, if any. Asked between chunks of work, not per step (a
    /// `Result` per step would cost the hot loop), so a failed sink stops its motor, and the run, early.
    fn failure(&self) -> Option<String> {
        None
    }
}

impl StepSink for Vec<Step> {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        self.push(Step { clock, dir });
    }
}

impl<S: StepSink + ?Sized> StepSink for &mut S {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        (**self).step(clock, dir);
    }

    #[inline]
    fn steps(&mut self, clocks: &[u64], dir: bool) {
        (**self).steps(clocks, dir);
    }

    #[inline]
    fn steps_with_gap(&mut self, clocks: &[u64], dir: bool, inner_gap: u64) {
        (**self).steps_with_gap(clocks, dir, inner_gap);
    }

    fn failure(&self) -> Option<String> {
        (**self).failure()
    }
}

/// An optional sink: `None` takes the steps and drops them.
impl<S: StepSink> StepSink for Option<S> {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        if let Some(sink) = self {
            sink.step(clock, dir);
        }
    }

    #[inline]
    fn steps(&mut self, clocks: &[u64], dir: bool) {
        if let Some(sink) = self {
            sink.steps(clocks, dir);
        }
    }

    #[inline]
    fn steps_with_gap(&mut self, clocks: &[u64], dir: bool, inner_gap: u64) {
        if let Some(sink) = self {
            sink.steps_with_gap(clocks, dir, inner_gap);
        }
    }

    fn failure(&self) -> Option<String> {
        self.as_ref()?.failure()
    }
}

/// Counts steps and keeps the net position change; for benchmarks and quick checks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CountSink {
    pub steps: u64,
    pub net: i64,
    pub last_clock: u64,
}

impl StepSink for CountSink {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        self.steps += 1;
        self.net += if dir { 1 } else { -1 };
        self.last_clock = clock;
    }
}

/// Sends every step to two sinks (e.g. a file writer and statistics).
#[derive(Debug, Clone, Default)]
pub struct Tee<A, B>(pub A, pub B);

impl<A: StepSink, B: StepSink> StepSink for Tee<A, B> {
    #[inline]
    fn step(&mut self, clock: u64, dir: bool) {
        self.0.step(clock, dir);
        self.1.step(clock, dir);
    }

    #[inline]
    fn steps(&mut self, clocks: &[u64], dir: bool) {
        self.0.steps(clocks, dir);
        self.1.steps(clocks, dir);
    }

    #[inline]
    fn steps_with_gap(&mut self, clocks: &[u64], dir: bool, inner_gap: u64) {
        self.0.steps_with_gap(clocks, dir, inner_gap);
        self.1.steps_with_gap(clocks, dir, inner_gap);
    }

    fn failure(&self) -> Option<String> {
        self.0.failure().or_else(|| self.1.failure())
    }
}
