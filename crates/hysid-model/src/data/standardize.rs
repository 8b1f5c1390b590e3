//! Standardisation (zero mean, unit standard deviation) of a record. The
//! statistics are kept so that identified models are reported in original
//! units (see `PwarxModel::to_original_units`).

use super::{Dataset, Signal};
use serde::{Deserialize, Serialize};

/// `scaled = (original - mean) / std`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AffineScale {
    /// Mean of the original signal.
    pub mean: f64,
    /// Standard deviation of the original signal (1 for a constant signal).
    pub std: f64,
}

impl AffineScale {
    /// The identity scale.
    pub const IDENTITY: Self = Self {
        mean: 0.0,
        std: 1.0,
    };

    /// Statistics of `v`; a constant signal gets `std = 1`. Constant means
    /// a spread below 1e-12 of the signal's magnitude, whatever its units (a
    /// record in 1e-12 units still varies).
    pub fn of(v: &[f64]) -> Self {
        let n = v.len().max(1) as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        let std = var.sqrt();
        let magnitude = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let std = if std > 1e-12 * magnitude && std.is_finite() {
            std
        } else {
            1.0
        };
        Self { mean, std }
    }

    /// Original to scaled.
    pub fn apply(&self, x: f64) -> f64 {
        (x - self.mean) / self.std
    }

    /// Scaled to original.
    pub fn invert(&self, x: f64) -> f64 {
        x * self.std + self.mean
    }
}

/// Per-signal scales of a MISO record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Standardization {
    /// Scale of each input, in order.
    pub inputs: Vec<AffineScale>,
    /// Scale of the output.
    pub output: AffineScale,
}

impl Standardization {
    /// Statistics of `data`.
    pub fn of(data: &Dataset) -> Self {
        Self {
            inputs: data
                .inputs
                .iter()
                .map(|s| AffineScale::of(&s.values))
                .collect(),
            output: AffineScale::of(&data.output.values),
        }
    }

    /// No scaling, for `m` inputs.
    pub fn identity(m: usize) -> Self {
        Self {
            inputs: vec![AffineScale::IDENTITY; m],
            output: AffineScale::IDENTITY,
        }
    }

    /// The record in scaled units.
    pub fn apply(&self, data: &Dataset) -> Dataset {
        let map = |s: &Signal, a: &AffineScale| Signal {
            name: s.name.clone(),
            values: s.values.iter().map(|&x| a.apply(x)).collect(),
        };
        Dataset {
            inputs: data
                .inputs
                .iter()
                .zip(&self.inputs)
                .map(|(s, a)| map(s, a))
                .collect(),
            output: map(&data.output, &self.output),
            ts: data.ts,
            boundaries: data.boundaries.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_record_has_zero_mean_unit_std() {
        let d =
            Dataset::siso(vec![1.0, 2.0, 3.0, 4.0], vec![10.0, 10.0, 30.0, 50.0], None).unwrap();
        let s = Standardization::of(&d);
        let z = s.apply(&d);
        let st = AffineScale::of(z.y());
        assert!(st.mean.abs() < 1e-12 && (st.std - 1.0).abs() < 1e-12);
        assert!((s.output.invert(z.y()[2]) - 30.0).abs() < 1e-12);
        assert_eq!(AffineScale::of(&[5.0, 5.0]).std, 1.0);
    }
}
