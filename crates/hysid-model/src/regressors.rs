//! PWARX regressors and the order of parameters, exactly as in
//! `docs/cli.md` ("Regressors and parameter order"):
//!
//! `x(k) = [y(k-1) .. y(k-na), u_1(k-1) .. u_1(k-nb), .., u_m(k-1) .. u_m(k-nb)]`
//!
//! and each mode predicts `y(k) = theta . [x(k); 1]`, so `theta` is ordered
//! `[a_1 .. a_na, b_11 .. b_1nb, .., b_m1 .. b_mnb, c]`.

use crate::data::Dataset;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Model orders of a PWARX structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RegressorSpec {
    /// Number of past outputs, `na`.
    pub na: usize,
    /// Number of past values of each input, `nb`.
    pub nb: usize,
    /// Number of inputs `m`.
    pub inputs: usize,
}

/// The regression problem `y = Phi theta` built from a record.
#[derive(Debug, Clone, PartialEq)]
pub struct Regressors {
    /// Regressors `x(k)` as rows (N - lag rows, `dim` columns), without the constant.
    pub x: DMatrix<f64>,
    /// Targets `y(k)`.
    pub y: DVector<f64>,
    /// The sample `k` of each row. Within a record the rows are the
    /// samples `lag..`; a row's lags never reach into the record before.
    pub samples: Vec<usize>,
}

impl Regressors {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// True when there is no row.
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// `[x(k); 1]` rows: the regression matrix with the constant column last.
    pub fn phi(&self) -> DMatrix<f64> {
        let (n, d) = self.x.shape();
        let mut p = DMatrix::from_element(n, d + 1, 1.0);
        p.view_mut((0, 0), (n, d)).copy_from(&self.x);
        p
    }

    /// The rows whose indices are in `rows`.
    pub fn select(&self, rows: &[usize]) -> Regressors {
        Regressors {
            x: self.x.select_rows(rows),
            y: self.y.select_rows(rows),
            samples: rows.iter().map(|&r| self.samples[r]).collect(),
        }
    }
}

impl RegressorSpec {
    /// Orders `na`, `nb` for `inputs` inputs.
    pub fn new(na: usize, nb: usize, inputs: usize) -> Self {
        Self { na, nb, inputs }
    }

    /// Dimension of `x(k)` (without the constant).
    pub fn dim(&self) -> usize {
        self.na + self.nb * self.inputs
    }

    /// Number of parameters per mode, `dim + 1`.
    pub fn n_params(&self) -> usize {
        self.dim() + 1
    }

    /// Samples needed before the first regressor: `max(na, nb)`.
    pub fn lag(&self) -> usize {
        self.na.max(self.nb)
    }

    /// Parameter names in `theta` order: `a1..a<na>`, `b1..b<nb>` (one input)
    /// or `b<i>_<j>` (several), then `c`.
    pub fn param_names(&self) -> Vec<String> {
        let mut v: Vec<String> = (1..=self.na).map(|i| format!("a{i}")).collect();
        v.extend(self.input_lag_names("b"));
        v.push("c".into());
        v
    }

    /// Regressor names in `x` order: `y1..y<na>`, `u1..u<nb>` (or `u<i>_<j>`).
    pub fn regressor_names(&self) -> Vec<String> {
        let mut v: Vec<String> = (1..=self.na).map(|i| format!("y{i}")).collect();
        v.extend(self.input_lag_names("u"));
        v
    }

    fn input_lag_names(&self, p: &str) -> Vec<String> {
        let mut v = Vec::new();
        for i in 1..=self.inputs {
            for j in 1..=self.nb {
                v.push(if self.inputs == 1 {
                    format!("{p}{j}")
                } else {
                    format!("{p}{i}_{j}")
                });
            }
        }
        v
    }

    /// Writes `x(k)` into `out` from output history `y` and inputs `u`
    /// (`u[i][k]`). Requires `k >= lag()`.
    pub fn fill(&self, y: &[f64], u: &[&[f64]], k: usize, out: &mut [f64]) {
        let mut p = 0;
        for i in 1..=self.na {
            out[p] = y[k - i];
            p += 1;
        }
        for ui in u {
            for j in 1..=self.nb {
                out[p] = ui[k - j];
                p += 1;
            }
        }
    }

    /// All regressors of a dataset: `N - lag` rows per record (none from a
    /// record of `lag` samples or fewer), none whose lags cross into the
    /// record before. Errors when no record is long enough or the input
    /// count differs from the spec.
    pub fn build(&self, data: &Dataset) -> Result<Regressors, RegressorError> {
        if data.inputs.len() != self.inputs {
            return Err(RegressorError::Inputs {
                expected: self.inputs,
                found: data.inputs.len(),
            });
        }
        if self.inputs == 0 && self.nb > 0 {
            return Err(RegressorError::LagsWithoutInput { nb: self.nb });
        }
        let lag = self.lag();
        let ranges = data.record_ranges();
        let samples: Vec<usize> = (ranges.iter())
            .flat_map(|r| r.start.saturating_add(lag)..r.end)
            .collect();
        if samples.is_empty() {
            return Err(RegressorError::TooShort {
                samples: ranges.iter().map(|r| r.len()).max().unwrap_or(0),
                lag,
            });
        }
        let u: Vec<&[f64]> = (0..self.inputs).map(|i| data.u(i)).collect();
        let d = self.dim();
        let mut x = DMatrix::zeros(samples.len(), d);
        let mut buf = vec![0.0; d];
        for (r, &k) in samples.iter().enumerate() {
            self.fill(data.y(), &u, k, &mut buf);
            for c in 0..d {
                x[(r, c)] = buf[c];
            }
        }
        Ok(Regressors {
            x,
            y: samples
                .iter()
                .map(|&k| data.y()[k])
                .collect::<Vec<_>>()
                .into(),
            samples,
        })
    }
}

/// Errors building regressors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegressorError {
    /// The record has fewer samples than the orders need.
    #[error("the record has {samples} samples; orders need more than max(na, nb) = {lag}")]
    TooShort {
        /// Samples in the record.
        samples: usize,
        /// `max(na, nb)`.
        lag: usize,
    },
    /// Input lags of a record without inputs.
    #[error("nb = {nb} input lags, but the record has no input: nb must be 0")]
    LagsWithoutInput {
        /// The input order.
        nb: usize,
    },
    /// The number of inputs differs from the model's.
    #[error("the model has {expected} input(s), the data {found}")]
    Inputs {
        /// Inputs of the model.
        expected: usize,
        /// Inputs of the data.
        found: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{Dataset, Signal};
    use proptest::prelude::*;

    #[test]
    fn names_follow_the_spec() {
        let s = RegressorSpec::new(2, 2, 1);
        assert_eq!(s.param_names(), ["a1", "a2", "b1", "b2", "c"]);
        assert_eq!(s.regressor_names(), ["y1", "y2", "u1", "u2"]);
        let s = RegressorSpec::new(1, 2, 2);
        assert_eq!(s.param_names(), ["a1", "b1_1", "b1_2", "b2_1", "b2_2", "c"]);
    }

    proptest! {
        /// Shapes and lag alignment: row r holds y(k-i) and u_j(k-l) for k = r + lag.
        #[test]
        fn regressor_shapes_and_lags(na in 0usize..4, nb in 0usize..4, m in 1usize..3, n in 6usize..40) {
            prop_assume!(na + nb > 0);
            let spec = RegressorSpec::new(na, nb, m);
            let y: Vec<f64> = (0..n).map(|k| k as f64).collect();
            let inputs: Vec<Signal> = (0..m)
                .map(|i| Signal { name: format!("u{i}"), values: (0..n).map(|k| 1000.0 * (i + 1) as f64 + k as f64).collect() })
                .collect();
            let data = Dataset::new(inputs, Signal { name: "y".into(), values: y }, None).unwrap();
            let lag = na.max(nb);
            let r = spec.build(&data).unwrap();
            prop_assert_eq!(r.x.shape(), (n - lag, na + nb * m));
            for row in 0..r.len() {
                let k = row + lag;
                prop_assert_eq!(r.samples[row], k);
                prop_assert_eq!(r.y[row], k as f64);
                for i in 1..=na { prop_assert_eq!(r.x[(row, i - 1)], (k - i) as f64); }
                for j in 0..m { for l in 1..=nb {
                    prop_assert_eq!(r.x[(row, na + j * nb + l - 1)], 1000.0 * (j + 1) as f64 + (k - l) as f64);
                }}
            }
            prop_assert_eq!(r.phi().column(na + nb * m).iter().all(|&v| v == 1.0), true);
        }
    }

    proptest! {
        /// Joined records give the rows of each record, in order, and no
        /// row whose lags cross a boundary.
        #[test]
        fn joined_records_give_each_records_rows(na in 0usize..4, nb in 0usize..4, cuts in proptest::collection::vec(5usize..20, 1..4)) {
            prop_assume!(na + nb > 0);
            let spec = RegressorSpec::new(na, nb, 1);
            let mut start = 0;
            let records: Vec<Dataset> = cuts.iter().map(|&n| {
                let v: Vec<f64> = (start..start + n).map(|k| (k * k % 17) as f64).collect();
                start += n;
                Dataset::siso(v.iter().map(|x| x + 0.5).collect(), v, None).unwrap()
            }).collect();
            let joined = spec.build(&Dataset::join(&records).unwrap()).unwrap();
            let mut row = 0;
            let mut offset = 0;
            for d in &records {
                let own = spec.build(d).unwrap();
                for r in 0..own.len() {
                    prop_assert_eq!(joined.x.row(row), own.x.row(r));
                    prop_assert_eq!(joined.y[row], own.y[r]);
                    prop_assert_eq!(joined.samples[row], own.samples[r] + offset);
                    row += 1;
                }
                offset += d.len();
            }
            prop_assert_eq!(row, joined.len());
        }
    }

    #[test]
    fn too_short_and_wrong_inputs() {
        let d = Dataset::siso(vec![0.0; 2], vec![0.0; 2], None).unwrap();
        assert!(matches!(
            RegressorSpec::new(2, 2, 1).build(&d),
            Err(RegressorError::TooShort { .. })
        ));
        assert!(matches!(
            RegressorSpec::new(1, 1, 2).build(&d),
            Err(RegressorError::Inputs { .. })
        ));
        // A record of `lag` samples or fewer beside a longer one gives no row.
        let long = Dataset::siso(vec![0.0; 6], vec![0.0; 6], None).unwrap();
        let joined = Dataset::join(&[long, d.clone()]).unwrap();
        let r = RegressorSpec::new(2, 2, 1).build(&joined).unwrap();
        assert_eq!(r.samples, [2, 3, 4, 5]);
        let both_short = Dataset::join(&[d.clone(), d]).unwrap();
        assert!(matches!(
            RegressorSpec::new(2, 2, 1).build(&both_short),
            Err(RegressorError::TooShort { samples: 2, lag: 2 })
        ));
    }
}
