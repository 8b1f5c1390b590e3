//! The bound of every iterative loop: a run's [`Deadline`] (a time, or a
//! stop request) and the [`Budget`] of iterations a loop takes its steps
//! from.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// When a run must end: at a time (a time budget), or as soon as a stop
/// is requested (Ctrl-C in the Python package), whichever comes first.
/// Long back-ends check it between steps and return their best model by
/// then, marked as cut short; a caller that requested the stop discards it.
#[derive(Debug, Clone, Default)]
pub struct Deadline {
    at: Option<Instant>,
    stop: Option<Arc<AtomicBool>>,
}

/// Two deadlines are equal when they end at the same time on the same
/// stop flag.
impl PartialEq for Deadline {
    fn eq(&self, other: &Self) -> bool {
        self.at == other.at
            && match (&self.stop, &other.stop) {
                (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                (a, b) => a.is_none() && b.is_none(),
            }
    }
}

impl Deadline {
    /// No deadline: the run ends when its work is done.
    pub const fn none() -> Self {
        Self {
            at: None,
            stop: None,
        }
    }

    /// The run ends at `at` (or when it is done).
    pub fn at(at: Instant) -> Self {
        Self {
            at: Some(at),
            stop: None,
        }
    }

    /// A time budget of `seconds` from now; `None` unless it is a positive
    /// finite number. A budget too long to represent (`Duration` ends near
    /// 1.8e19 s, an `Instant` may end sooner) is no deadline at all.
    pub fn after_seconds(seconds: f64) -> Option<Self> {
        if !(seconds.is_finite() && seconds > 0.0) {
            return None;
        }
        let at = Duration::try_from_secs_f64(seconds)
            .ok()
            .and_then(|d| Instant::now().checked_add(d));
        Some(Self { at, stop: None })
    }

    /// The same deadline, also passed once `flag` is raised.
    pub fn with_stop(self, flag: Arc<AtomicBool>) -> Self {
        Self {
            stop: Some(flag),
            ..self
        }
    }

    /// True once the time is up or a stop was requested.
    pub fn passed(&self) -> bool {
        self.stop_requested() || self.at.is_some_and(|t| Instant::now() >= t)
    }

    /// True when a stop was requested.
    pub fn stop_requested(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
    }

    /// Time left (zero once passed), or `None` without a time limit.
    pub fn remaining(&self) -> Option<Duration> {
        if self.stop_requested() {
            return Some(Duration::ZERO);
        }
        self.at.map(|t| t.saturating_duration_since(Instant::now()))
    }

    /// Whether start `index` of independent starts (restarts, seeds,
    /// searches) may run: the first always does, so a run cut short still
    /// has a result; the others only before the deadline.
    pub fn admits(&self, index: usize) -> bool {
        index == 0 || !self.passed()
    }
}

/// The bound of an iterative method's loop: at most `max` iterations, none
/// begun after the run's [`Deadline`]. A loop takes each iteration from its
/// budget ([`Budget::begin`]), which says why the loop must end before the
/// method's own convergence test ends it.
#[derive(Debug)]
pub struct Budget<'d> {
    max: usize,
    taken: usize,
    deadline: &'d Deadline,
}

/// Why a [`Budget`] gives no further iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exhausted {
    /// The iteration bound was reached.
    IterationLimit,
    /// The deadline passed, or a stop was requested.
    TimeBudget,
}

impl<'d> Budget<'d> {
    /// At most `max` iterations, none begun after `deadline`.
    pub fn new(max: usize, deadline: &'d Deadline) -> Self {
        Self {
            max,
            taken: 0,
            deadline,
        }
    }

    /// One more iteration, counted; or why none may begin (the bound is
    /// asked before the deadline).
    pub fn begin(&mut self) -> Result<(), Exhausted> {
        if self.taken >= self.max {
            return Err(Exhausted::IterationLimit);
        }
        if self.deadline.passed() {
            return Err(Exhausted::TimeBudget);
        }
        self.taken += 1;
        Ok(())
    }

    /// Iterations taken.
    pub fn taken(&self) -> usize {
        self.taken
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_counts_its_iterations_and_ends_at_its_bound_or_deadline() {
        let none = Deadline::none();
        let mut b = Budget::new(2, &none);
        assert_eq!((b.begin(), b.begin()), (Ok(()), Ok(())));
        assert_eq!(b.begin(), Err(Exhausted::IterationLimit));
        assert_eq!(b.taken(), 2);
        let passed = Deadline::at(Instant::now());
        let mut b = Budget::new(2, &passed);
        assert_eq!((b.begin(), b.taken()), (Err(Exhausted::TimeBudget), 0));
        // The bound is asked first.
        assert_eq!(
            Budget::new(0, &passed).begin(),
            Err(Exhausted::IterationLimit)
        );
        assert!(passed.admits(0) && !passed.admits(1) && none.admits(7));
    }

    #[test]
    fn a_deadline_passes_at_its_time_or_on_a_stop_request() {
        assert!(!Deadline::none().passed());
        assert_eq!(Deadline::none().remaining(), None);
        let now = Instant::now();
        assert!(Deadline::at(now).passed());
        let later = Deadline::at(now + Duration::from_secs(3600));
        assert!(!later.passed());
        let flag = Arc::new(AtomicBool::new(false));
        let stoppable = later.clone().with_stop(Arc::clone(&flag));
        assert!(!stoppable.passed() && !stoppable.stop_requested());
        let copy = stoppable.clone();
        flag.store(true, Ordering::Relaxed);
        assert!(copy.passed() && copy.stop_requested());
        assert_eq!(copy.remaining(), Some(Duration::ZERO));
        assert_eq!(copy, stoppable);
        assert_ne!(copy, later);
    }
}
