//! Locating an event inside an integration step: the step length at which
//! a regime ends, bracketed between a length that ends without the event
//! (`lo`) and one that ends in it (`hi`) until the bracket is narrower than
//! [`LOCATE_RESOLUTION`] of the step.
//!
//! The trial lengths come from the event's margin, a scalar that is not
//! negative where the event has happened (a stop's signed distance, a
//! sliding velocity, a guard's surface): regula falsi between the
//! bracket's margins with the Illinois modification (the end kept twice
//! has its margin halved; Dowell and Jarratt, BIT 11, 1971), each trial
//! kept at least half the resolution inside the bracket, so that a
//! converged estimate closes it from the other side. Where the margin is
//! not known or disagrees with the event test (another event came first,
//! a condition failed), and after [`FALSE_POSITION_TRIALS`], the trials are
//! midpoints: the bracket then narrows as a bisection's would. Smooth
//! margins close it in a handful of trials instead of a bisection's forty.
//!
//! ```
//! use hysid_numerics::event_location::Bracket;
//!
//! // A velocity v(t) = 1 - 4t reaches zero at t = 0.25 in a step of 1.
//! let v = |t: f64| 1.0 - 4.0 * t;
//! let mut b = Bracket::new(1.0, Some(-v(0.0)), Some(-v(1.0)));
//! while let Some(t) = b.trial() {
//!     b.update(t, v(t) <= 0.0, Some(-v(t)));
//! }
//! assert!(b.lo < 0.25 && 0.25 <= b.hi && b.hi - b.lo < 1e-12);
//! ```

/// The bracket's final width, relative to the sub-step (a bisection's 40
/// halvings).
pub const LOCATE_RESOLUTION: f64 = 1.0 / (1u64 << 40) as f64;

/// Trials by regula falsi before the rest are midpoints.
pub const FALSE_POSITION_TRIALS: usize = 16;

/// Bound on the trials of one event's location: the regula falsi's, then
/// a bisection's.
pub const LOCATE_TRIALS: usize = FALSE_POSITION_TRIALS + 41;

/// Which end of the bracket a trial replaced.
#[derive(Debug, Clone, Copy, PartialEq)]
enum End {
    Lo,
    Hi,
}

/// The bracket of an event's step length and the margins at its ends.
#[derive(Debug, Clone)]
pub struct Bracket {
    /// The longest step known to end without the event.
    pub lo: f64,
    /// The shortest step known to end in it.
    pub hi: f64,
    /// The margins at `lo` (negative) and `hi` (not negative), while they
    /// agree with the event test.
    margins: Option<(f64, f64)>,
    resolution: f64,
    /// The end replaced by the last trial.
    last: Option<End>,
    /// Trials taken.
    trials: usize,
}

impl Bracket {
    /// The bracket `[0, length]` of a step that ends in the event, with
    /// the event's margins at the step's start and end when known.
    pub fn new(length: f64, start: Option<f64>, end: Option<f64>) -> Self {
        let margins = match (start, end) {
            (Some(a), Some(b)) if a < 0.0 && b >= 0.0 && (b - a).is_finite() => Some((a, b)),
            _ => None,
        };
        Bracket {
            lo: 0.0,
            hi: length,
            margins,
            resolution: length * LOCATE_RESOLUTION,
            last: None,
            trials: 0,
        }
    }

    /// The next step length to try, or `None` when the bracket is closed
    /// (narrower than the resolution, or no length between its ends).
    pub fn trial(&self) -> Option<f64> {
        let (lo, hi) = (self.lo, self.hi);
        let width = hi - lo;
        if width <= self.resolution {
            return None;
        }
        let mid = 0.5 * (lo + hi);
        let edge = 0.5 * self.resolution;
        // The edges kept off the ends; they may cross by rounding when the
        // bracket is barely wider than the resolution.
        let (low, high) = (lo + edge, hi - edge);
        let t = match self.margins {
            Some((a, b)) if self.trials < FALSE_POSITION_TRIALS && low <= high => {
                let estimate = lo + width * (a / (a - b));
                if estimate.is_finite() {
                    estimate.clamp(low, high)
                } else {
                    mid
                }
            }
            _ => mid,
        };
        (t > lo && t < hi).then_some(t)
    }

    /// Takes the trial `t`: `ended` whether the step to `t` ends in an
    /// event, `margin` the event's margin there.
    pub fn update(&mut self, t: f64, ended: bool, margin: Option<f64>) {
        self.trials += 1;
        let end = if ended { End::Hi } else { End::Lo };
        let agrees = margin.filter(|m| (*m >= 0.0) == ended && m.is_finite());
        self.margins = match (self.margins, agrees) {
            (Some((a, b)), Some(m)) => {
                let twice = self.last == Some(end);
                Some(match end {
                    End::Hi => (if twice { 0.5 * a } else { a }, m),
                    End::Lo => (m, if twice { 0.5 * b } else { b }),
                })
            }
            _ => None,
        };
        match end {
            End::Hi => self.hi = t,
            End::Lo => self.lo = t,
        }
        self.last = Some(end);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Runs the bracket on the event test `ends` with the margin
    /// `margin`; the bracket and the trials taken.
    fn locate(
        length: f64,
        ends: impl Fn(f64) -> bool,
        margin: impl Fn(f64) -> Option<f64>,
    ) -> (Bracket, usize) {
        let mut b = Bracket::new(length, margin(0.0), margin(length));
        let mut trials = 0;
        while let Some(t) = b.trial() {
            assert!(trials < LOCATE_TRIALS, "no end after {trials} trials");
            b.update(t, ends(t), margin(t));
            trials += 1;
        }
        (b, trials)
    }

    proptest! {
        /// A smooth margin whose slope changes at most threefold over the
        /// step (a cubic through its root) is closed around its root, to
        /// the resolution, in far fewer trials than a bisection.
        #[test]
        fn a_smooth_margin_closes_around_its_root(
            root in 0.01f64..0.99,
            slope in 0.1f64..10.0,
            curve in -0.5f64..0.5,
            cube in -0.5f64..0.5,
        ) {
            let f = |t: f64| {
                let d = t - root;
                slope * (d + curve * d * d + cube * d * d * d)
            };
            let length = 2.5e-4;
            let (b, trials) = locate(length, |t| f(t / length) >= 0.0, |t| Some(f(t / length)));
            prop_assert!(b.hi - b.lo <= length * LOCATE_RESOLUTION);
            prop_assert!(f(b.lo / length) < 0.0 && f(b.hi / length) >= 0.0);
            prop_assert!(trials <= 12, "{trials} trials");
        }

        /// Where the margin is unknown or misleads (the event test switches
        /// at another point than the margin's root), the bracket still
        /// closes around the test's switch within a bisection's trials.
        #[test]
        fn a_misleading_margin_still_brackets_the_test(
            switch in 0.01f64..0.99,
            root in 0.01f64..0.99,
            known in any::<bool>(),
        ) {
            let margin = |t: f64| known.then_some(t - root);
            let (b, trials) = locate(1.0, |t| t >= switch, margin);
            prop_assert!(b.hi - b.lo <= LOCATE_RESOLUTION);
            prop_assert!(b.lo < switch && b.hi >= switch);
            prop_assert!(trials <= 2 * 41, "{trials} trials");
        }
    }

    /// Without margins the trials are a bisection's midpoints.
    #[test]
    fn without_margins_it_bisects() {
        let (b, trials) = locate(1.0, |t| t >= 0.3, |_| None);
        assert_eq!(trials, 40);
        assert_eq!(b.hi - b.lo, LOCATE_RESOLUTION);
    }
}
