//! Input signals for simulation experiments: the founding paper's random
//! piecewise-constant input `u(t) = a_k` on `[kT, (k+1)T)`, `a_k ~ U[low, high]`
//! (Juloski, Heemels, Ferrari-Trecate, IFAC ADHS 2003, section 4), seeded.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// A random piecewise-constant input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Excitation {
    /// Number of samples.
    pub n: usize,
    /// Samples each level is held (T / Ts).
    pub hold: usize,
    /// Lower end of the levels.
    pub low: f64,
    /// Upper end of the levels.
    pub high: f64,
    /// Sampling time in seconds, if known.
    #[serde(default)]
    pub ts: Option<f64>,
    /// Number of inputs (independent levels each).
    #[serde(default = "one")]
    pub inputs: usize,
}

fn one() -> usize {
    1
}

/// Most samples an excitation may have (`n`): 10 million (80 MB per input).
pub const MAX_SAMPLES: usize = 10_000_000;

/// Most inputs an excitation may have (`inputs`).
pub const MAX_INPUTS: usize = 100;

/// Most values in all (`n` times `inputs`).
pub const MAX_VALUES: usize = 10_000_000;

impl std::str::FromStr for Excitation {
    type Err = ExcitationError;

    /// Parses `n=6000,hold=120,low=-0.13,high=-0.03[,ts=0.0025][,inputs=1]`
    /// (one input unless `inputs` is given).
    fn from_str(s: &str) -> Result<Self, ExcitationError> {
        Self::parse_for(s, 1)
    }
}

impl Excitation {
    /// Parses `s` as [`str::parse`] does, with `inputs` inputs unless it
    /// gives their number (a model's input count).
    pub fn parse_for(s: &str, inputs: usize) -> Result<Self, ExcitationError> {
        let mut t = toml::Table::new();
        for item in s.split(',').map(str::trim).filter(|x| !x.is_empty()) {
            let (k, v) = item
                .split_once('=')
                .ok_or_else(|| ExcitationError::NotKeyValue(item.to_string()))?;
            let val: toml::Value = format!("v = {v}")
                .parse::<toml::Table>()
                .ok()
                .and_then(|mut x| x.remove("v"))
                .ok_or_else(|| ExcitationError::NotANumber {
                    key: k.to_string(),
                    value: v.to_string(),
                })?;
            if t.insert(k.trim().to_string(), val).is_some() {
                return Err(ExcitationError::Repeated(k.trim().to_string()));
            }
        }
        if !t.contains_key("inputs") {
            let count = i64::try_from(inputs).unwrap_or(i64::MAX);
            t.insert("inputs".into(), toml::Value::Integer(count));
        }
        // Integers are accepted where floats are expected.
        for k in ["low", "high", "ts"] {
            if let Some(toml::Value::Integer(i)) = t.get(k).cloned() {
                t.insert(k.into(), toml::Value::Float(i as f64));
            }
        }
        let e: Excitation = toml::Value::Table(t)
            .try_into()
            .map_err(|e: toml::de::Error| {
                ExcitationError::Invalid(e.to_string().trim().replace('\n', " "))
            })?;
        e.check()?;
        Ok(e)
    }
}

/// A malformed or inconsistent excitation (the messages use the
/// `--excite` syntax of `hysid simulate`, which is where excitations are
/// written as text).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExcitationError {
    /// An item without `=`.
    #[error("--excite: '{0}' is not key=value")]
    NotKeyValue(String),
    /// A key given twice.
    #[error("--excite {0}: given twice")]
    Repeated(String),
    /// A value that is not a number.
    #[error("--excite {key}: '{value}' is not a number")]
    NotANumber {
        /// The key.
        key: String,
        /// The value.
        value: String,
    },
    /// Unknown or missing keys (the parser's message).
    #[error("--excite: {0}")]
    Invalid(String),
    /// `n`, `hold` or `inputs` of zero.
    #[error("--excite: n, hold and inputs must be at least 1")]
    Zero,
    /// Too many samples.
    #[error("--excite n={0}: at most {MAX_SAMPLES} samples")]
    TooManySamples(usize),
    /// Too many inputs.
    #[error("--excite inputs={0}: at most {MAX_INPUTS} inputs")]
    TooManyInputs(usize),
    /// Too many values in all.
    #[error("--excite n={n}, inputs={inputs}: at most {MAX_VALUES} input values in all")]
    TooManyValues {
        /// Samples.
        n: usize,
        /// Inputs.
        inputs: usize,
    },
    /// Levels not finite, low above high, or a range `high - low` past
    /// the largest number.
    #[error("--excite: need finite low <= high, with high - low finite, got {low:?} and {high:?}")]
    Levels {
        /// Lower level.
        low: f64,
        /// Upper level.
        high: f64,
    },
    /// A sampling time that is not positive.
    #[error("--excite: ts must be positive, got {0}")]
    SamplingTime(f64),
}

impl Excitation {
    /// Consistency checks.
    pub fn check(&self) -> Result<(), ExcitationError> {
        if self.n == 0 || self.hold == 0 || self.inputs == 0 {
            return Err(ExcitationError::Zero);
        }
        if self.n > MAX_SAMPLES {
            return Err(ExcitationError::TooManySamples(self.n));
        }
        if self.inputs > MAX_INPUTS {
            return Err(ExcitationError::TooManyInputs(self.inputs));
        }
        if self.n.saturating_mul(self.inputs) > MAX_VALUES {
            return Err(ExcitationError::TooManyValues {
                n: self.n,
                inputs: self.inputs,
            });
        }
        if !((self.high - self.low).is_finite() && self.low <= self.high) {
            return Err(ExcitationError::Levels {
                low: self.low,
                high: self.high,
            });
        }
        if let Some(ts) = self.ts
            && !(ts.is_finite() && ts > 0.0)
        {
            return Err(ExcitationError::SamplingTime(ts));
        }
        Ok(())
    }

    /// The input signals, one vector per input; the same seed gives the same signal.
    pub fn generate(&self, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..self.inputs)
            .map(|_| {
                let mut u = Vec::with_capacity(self.n);
                let mut level = 0.0;
                for k in 0..self.n {
                    if k % self.hold == 0 {
                        level = if self.high > self.low {
                            rng.random_range(self.low..=self.high)
                        } else {
                            self.low
                        };
                    }
                    u.push(level);
                }
                u
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_generates_held_levels() {
        let e: Excitation = "n=10,hold=4,low=-1,high=1".parse().unwrap();
        let u = e.generate(7);
        assert_eq!(u.len(), 1);
        assert_eq!(u[0].len(), 10);
        assert_eq!(u[0][0], u[0][3]);
        assert!(u[0].iter().all(|v| (-1.0..=1.0).contains(v)));
        assert_eq!(u, e.generate(7));
        assert_ne!(u, e.generate(8));
        assert!("n=10,hold=0,low=0,high=1".parse::<Excitation>().is_err());
        assert!("n=10,hold=2,low=2,high=1".parse::<Excitation>().is_err());
        let twice = "n=10,hold=2,low=0,high=1,n=20".parse::<Excitation>();
        assert_eq!(twice.unwrap_err(), ExcitationError::Repeated("n".into()));
        // Finite levels whose range is not: refused, not drawn from.
        let spread = "n=10,hold=2,low=-1e308,high=1e308".parse::<Excitation>();
        assert_eq!(
            spread.unwrap_err().to_string(),
            "--excite: need finite low <= high, with high - low finite, got -1e308 and 1e308"
        );
        let wide = "n=10,hold=2,low=-1e307,high=1e307".parse::<Excitation>();
        assert!(wide.unwrap().generate(1)[0].iter().all(|v| v.is_finite()));
        assert!(
            "n=10000000,hold=2,low=0,high=1"
                .parse::<Excitation>()
                .is_ok()
        );
        let huge = "n=10000001,hold=2,low=0,high=1".parse::<Excitation>();
        assert_eq!(
            huge.unwrap_err().to_string(),
            "--excite n=10000001: at most 10000000 samples"
        );
        let wide = "n=10,hold=2,low=0,high=1,inputs=101".parse::<Excitation>();
        assert_eq!(wide.unwrap_err(), ExcitationError::TooManyInputs(101));
        let both = "n=200000,hold=2,low=0,high=1,inputs=100".parse::<Excitation>();
        assert!(
            both.unwrap_err()
                .to_string()
                .contains("at most 10000000 input values")
        );
        assert!(
            "n=10,hld=2,low=0,high=1"
                .parse::<Excitation>()
                .unwrap_err()
                .to_string()
                .contains("hld")
        );
    }
}
