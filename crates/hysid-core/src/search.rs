//! The option values a back-end's automatic selection tries.
//!
//! A back-end declares a [`SearchSpace`] (`Identifier::search_space`): axes
//! of values for its options, for the prior `modes`, or for the orders `na`
//! and `nb`. The selection (`hysid identify --auto`) fits every point of
//! the grid on the fit rows and keeps the one whose free-run simulation
//! scores best on the selection rows. `--grid key=v1,v2,...` replaces the
//! declared space with the user's, in the syntax of `hysid sweep`.

use crate::options::{OptionError, Settings, first_repeated};
use crate::priors::Priors;
use hysid_model::regressors::RegressorSpec;
use serde::Serialize;

/// One axis: a key and the values tried, as text (`--set` syntax).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Axis {
    /// A back-end option, or `modes`, `na`, `nb`.
    pub key: String,
    /// Values in the order they are tried.
    pub values: Vec<String>,
}

/// The grid of candidate settings: the Cartesian product of its axes.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
pub struct SearchSpace {
    /// Axes, outermost first.
    pub axes: Vec<Axis>,
}

/// One point of a [`SearchSpace`]: a value for each axis key.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Candidate {
    /// `(key, value)` in axis order.
    pub values: Vec<(String, String)>,
}

impl SearchSpace {
    /// Adds an axis (builder style); an axis without values is left out.
    pub fn with(mut self, key: &str, values: impl IntoIterator<Item = impl ToString>) -> Self {
        let values: Vec<String> = values.into_iter().map(|v| v.to_string()).collect();
        if !values.is_empty() {
            self.axes.push(Axis {
                key: key.to_string(),
                values,
            });
        }
        self
    }

    /// The space with a `modes` axis from one ordinary mode (the affine
    /// model, plus the stop modes of the priors) to `max_modes`, or to
    /// `default_most` ordinary modes without it; unchanged when the priors
    /// fix `modes`.
    pub fn with_mode_counts(self, priors: &Priors, default_most: usize) -> Self {
        if priors.modes.is_some() {
            return self;
        }
        let stops = priors.saturation.len();
        let most = priors.max_modes.unwrap_or(stops + default_most);
        self.with("modes", stops + 1..=most)
    }

    /// Parses `KEY=V1,V2,...` items (the `--grid` syntax of `hysid sweep`).
    pub fn parse_grid<S: AsRef<str>>(items: &[S]) -> Result<Self, OptionError> {
        let mut axes: Vec<Axis> = Vec::new();
        for it in items {
            let it = it.as_ref();
            let (k, v) = it
                .split_once('=')
                .ok_or_else(|| OptionError::Syntax(it.to_string()))?;
            let key = k.trim().to_string();
            let values: Vec<String> = v.split(',').map(|x| x.trim().to_string()).collect();
            if key.is_empty() || values.iter().any(String::is_empty) {
                return Err(OptionError::Syntax(it.to_string()));
            }
            if axes.iter().any(|a| a.key == key) {
                return Err(OptionError::Duplicate(key));
            }
            if let Some(value) = first_repeated(&values) {
                return Err(OptionError::Duplicate(format!("{key}={value}")));
            }
            axes.push(Axis { key, values });
        }
        Ok(Self { axes })
    }

    /// The space without the axes whose key `settings` gives: an option
    /// the user set is knowledge, not a choice.
    pub fn without_given(mut self, settings: &Settings) -> Self {
        self.axes.retain(|a| settings.get(&a.key).is_none());
        self
    }

    /// True when the axis `key` is present.
    pub fn has(&self, key: &str) -> bool {
        self.axes.iter().any(|a| a.key == key)
    }

    /// Number of grid points (1 for an empty space: the defaults),
    /// `usize::MAX` when the product overflows.
    pub fn count(&self) -> usize {
        self.axes
            .iter()
            .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
            .unwrap_or(usize::MAX)
    }

    /// The grid points, the last axis varying fastest.
    pub fn candidates(&self) -> Vec<Candidate> {
        let mut out = vec![Candidate { values: Vec::new() }];
        for axis in &self.axes {
            out = out
                .into_iter()
                .flat_map(|c| {
                    axis.values.iter().map(move |v| {
                        let mut values = c.values.clone();
                        values.push((axis.key.clone(), v.clone()));
                        Candidate { values }
                    })
                })
                .collect();
        }
        out
    }
}

/// A problem's orders, priors and options with a candidate's values put in.
#[derive(Debug, Clone)]
pub struct Setup {
    /// Orders (`na`, `nb` of the candidate when it sets them).
    pub orders: RegressorSpec,
    /// Priors (`modes` of the candidate when it sets it).
    pub priors: Priors,
    /// Options: the given ones, a candidate's value replacing a given one.
    pub settings: Settings,
}

/// Why a candidate cannot be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("grid {key} = {value}: {reason}")]
pub struct CandidateError {
    /// Axis.
    pub key: String,
    /// Value as given.
    pub value: String,
    /// What is wrong: "not a count", or why the priors refuse the count.
    pub reason: String,
}

impl Setup {
    /// This set-up with `candidate`'s values: `modes` sets the prior (one
    /// the priors accept), `na` and `nb` the orders, any other key a
    /// back-end option.
    pub fn with(&self, candidate: &Candidate) -> Result<Setup, CandidateError> {
        let mut out = self.clone();
        let mut pairs: Vec<(String, String)> = self.settings.pairs().to_vec();
        for (key, value) in &candidate.values {
            let refused = |reason: String| CandidateError {
                key: key.clone(),
                value: value.clone(),
                reason,
            };
            let count = || {
                value
                    .parse::<usize>()
                    .map_err(|_| refused("not a count".into()))
            };
            match key.as_str() {
                "modes" => {
                    out.priors.modes = Some(count()?);
                    out.priors
                        .check()
                        .map_err(|problem| refused(problem.to_string()))?;
                }
                "na" => out.orders.na = count()?,
                "nb" => out.orders.nb = count()?,
                _ => {
                    pairs.retain(|(k, _)| k != key);
                    pairs.push((key.clone(), value.clone()));
                }
            }
        }
        out.settings = Settings::from_pairs(pairs);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_the_cartesian_product_in_order() {
        let s = SearchSpace::default()
            .with("c", [20, 40])
            .with("modes", [1, 2, 3]);
        let c = s.candidates();
        assert_eq!(c.len(), 6);
        assert_eq!(s.count(), 6);
        assert_eq!(
            c[4].values,
            vec![("c".into(), "40".into()), ("modes".into(), "2".into())]
        );
        assert_eq!(SearchSpace::default().candidates().len(), 1);
    }

    #[test]
    fn a_given_option_is_not_searched() {
        let s = SearchSpace::default()
            .with("delta", ["0.1", "0.2"])
            .with("c", [20])
            .without_given(&Settings::parse(&["delta=0.3"]).unwrap());
        assert!(!s.has("delta"));
        assert!(s.has("c"));
    }

    #[test]
    fn parse_grid_refuses_bad_items() {
        let s = SearchSpace::parse_grid(&["c=20, 40", "modes=2"]).unwrap();
        assert_eq!(s.axes[0].values, vec!["20", "40"]);
        assert!(matches!(
            SearchSpace::parse_grid(&["c"]),
            Err(OptionError::Syntax(_))
        ));
        assert!(matches!(
            SearchSpace::parse_grid(&["c="]),
            Err(OptionError::Syntax(_))
        ));
        // An empty value between commas is a slip, not a value.
        assert!(matches!(
            SearchSpace::parse_grid(&["c=4,,8"]),
            Err(OptionError::Syntax(_))
        ));
        assert!(matches!(
            SearchSpace::parse_grid(&["c=1", "c=2"]),
            Err(OptionError::Duplicate(_))
        ));
    }

    #[test]
    fn setup_puts_candidate_values_in_their_places() {
        let base = Setup {
            orders: RegressorSpec::new(2, 2, 1),
            priors: Priors::default(),
            settings: Settings::parse(&["c=10", "restarts=3"]).unwrap(),
        };
        let cand = Candidate {
            values: vec![
                ("c".into(), "40".into()),
                ("modes".into(), "3".into()),
                ("na".into(), "4".into()),
            ],
        };
        let s = base.with(&cand).unwrap();
        assert_eq!(s.orders.na, 4);
        assert_eq!(s.orders.nb, 2);
        assert_eq!(s.priors.modes, Some(3));
        assert_eq!(s.settings.get("c"), Some("40"));
        assert_eq!(s.settings.get("restarts"), Some("3"));
        assert_eq!(s.settings.pairs().len(), 2);
        let bad = Candidate {
            values: vec![("modes".into(), "two".into())],
        };
        assert_eq!(
            base.with(&bad).unwrap_err().to_string(),
            "grid modes = two: not a count"
        );
        let zero = Candidate {
            values: vec![("modes".into(), "0".into())],
        };
        let e = base.with(&zero).unwrap_err();
        assert_eq!((e.key.as_str(), e.value.as_str()), ("modes", "0"));
        assert_ne!(e.reason, "not a count");
    }
}
