//! Gray-box priors in the weighted least squares of the procedure
//! (`docs/priors.md`, `docs/cluster.md`, "Priors").
//!
//! The procedure runs in working units (standardised by default), but ties,
//! fixed values and bounds are stated in data units, and a fixed or bounded
//! constant `c` is not a fixed or bounded constant after standardisation
//! (`c' = (c + sum_j a_j m_j - m_y) / s_y` mixes every parameter). So every
//! weighted least-squares step of the procedure (section 3.4 of
//! Ferrari-Trecate et al., Automatica 2003: the mode fits, the refits after
//! reattribution and the region-consistent refit) is solved here in
//! **original units** with the procedure's weights by
//! `hysid_estimation::constrained::fit_modes` (ties and fixed values exact through
//! the combinatorial null-space parametrisation, bounds through clarabel),
//! and the result is mapped to working units for the residuals the
//! procedure compares. Residuals in working units are those in original
//! units divided by `s_y`, so without constraints the minimiser is the same.

use hysid_core::priors::Priors;
use hysid_estimation::constrained::{
    self, EstimationError, ModeSamples, Parametrisation, PriorConflict,
};
use hysid_model::data::Standardization;
use hysid_model::regressors::RegressorSpec;
use nalgebra::DMatrix;

/// The weighted least squares of the procedure under gray-box priors: the
/// ordinary samples in original units, the map to working units, and the
/// priors that constrain the fit.
#[derive(Debug, Clone)]
pub struct ConstrainedFit {
    priors: Priors,
    spec: RegressorSpec,
    n: usize,
    x: Vec<f64>,
    y: Vec<f64>,
    mean: Vec<f64>,
    std: Vec<f64>,
    my: f64,
    sy: f64,
}

/// Parameters of the modes in working units and, under gray-box priors, in
/// original units (where the priors hold exactly).
#[derive(Debug, Clone)]
pub struct Thetas {
    /// Working units (used for residuals).
    pub working: Vec<Vec<f64>>,
    /// Original units, when fitted under priors.
    pub original: Option<Vec<Vec<f64>>>,
}

/// Why [`ConstrainedFit::fit`] gave no parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConstrainedFitError {
    /// Labels or weights not one per sample.
    #[error("{labels} labels and {weights} weights for {samples} samples")]
    Shape {
        /// Number of labels.
        labels: usize,
        /// Number of weights.
        weights: usize,
        /// Number of samples.
        samples: usize,
    },
    /// The priors cannot parametrise that many modes.
    #[error(transparent)]
    Prior(#[from] PriorConflict),
    /// The constrained least squares failed.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
}

impl ConstrainedFit {
    /// `x` (row-major, `spec.dim()` columns) and `y`: the ordinary samples
    /// in original units, in the order of the procedure's samples; `scale`
    /// maps original to working units. Fails with a one-line message when
    /// the priors are inconsistent for `modes` ordinary modes (a fixed value
    /// outside its bounds).
    pub fn new(
        priors: &Priors,
        spec: RegressorSpec,
        x: Vec<f64>,
        y: Vec<f64>,
        scale: &Standardization,
        modes: usize,
    ) -> Result<Self, PriorConflict> {
        Parametrisation::from_priors(priors, &spec, modes.max(1))?;
        let n = spec.dim();
        let mut mean = Vec::with_capacity(n);
        let mut std = Vec::with_capacity(n);
        for _ in 0..spec.na {
            mean.push(scale.output.mean);
            std.push(scale.output.std);
        }
        for sc in &scale.inputs {
            for _ in 0..spec.nb {
                mean.push(sc.mean);
                std.push(sc.std);
            }
        }
        Ok(Self {
            priors: priors.clone(),
            spec,
            n,
            x,
            y,
            mean,
            std,
            my: scale.output.mean,
            sy: scale.output.std,
        })
    }

    /// Minimises `sum_i sum_{j: labels_j = i} w_j (y_j - [x_j' 1] theta_i)^2`
    /// over the parameters of the `modes` modes under the priors, in
    /// original units (samples with a label `>= modes` are left out).
    /// Returns the parameters in working units and in original units.
    pub fn fit(
        &self,
        labels: &[usize],
        modes: usize,
        w: &[f64],
    ) -> Result<Thetas, ConstrainedFitError> {
        let n = self.n;
        if labels.len() != self.y.len() || w.len() != self.y.len() {
            return Err(ConstrainedFitError::Shape {
                labels: labels.len(),
                weights: w.len(),
                samples: self.y.len(),
            });
        }
        let par = Parametrisation::from_priors(&self.priors, &self.spec, modes)?;
        let mut data = Vec::with_capacity(modes);
        for i in 0..modes {
            let rows: Vec<usize> = (0..labels.len()).filter(|&j| labels[j] == i).collect();
            let phi = DMatrix::from_fn(rows.len(), n, |r, k| self.x[rows[r] * n + k]);
            let y: Vec<f64> = rows.iter().map(|&j| self.y[j]).collect();
            let wi: Vec<f64> = rows.iter().map(|&j| w[j]).collect();
            data.push((phi, y, wi));
        }
        let samples: Vec<ModeSamples<'_>> = data
            .iter()
            .map(|(phi, y, wi)| ModeSamples {
                phi,
                y,
                weights: Some(wi),
            })
            .collect();
        let original = constrained::fit_modes(&par, &samples)?;
        let working = original.iter().map(|th| self.to_working(th)).collect();
        Ok(Thetas {
            working,
            original: Some(original),
        })
    }

    /// `theta` in working units: `a'_j = a_j s_j / s_y`,
    /// `c' = (c + sum_j a_j m_j - m_y) / s_y`.
    fn to_working(&self, th: &[f64]) -> Vec<f64> {
        let n = self.n;
        let mut t = vec![0.0; n + 1];
        let mut c = th[n] - self.my;
        for j in 0..n {
            t[j] = th[j] * self.std[j] / self.sy;
            c += th[j] * self.mean[j];
        }
        t[n] = c / self.sy;
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_model::data::AffineScale;

    #[test]
    fn working_units_round_trip() {
        let spec = RegressorSpec::new(1, 1, 1);
        let scale = Standardization {
            inputs: vec![AffineScale {
                mean: 2.0,
                std: 3.0,
            }],
            output: AffineScale {
                mean: -1.0,
                std: 0.5,
            },
        };
        let con = ConstrainedFit::new(&Priors::default(), spec, vec![], vec![], &scale, 1).unwrap();
        let th = [0.4, -2.0, 1.5];
        let w = con.to_working(&th);
        // y = 0.4 y1 - 2 u1 + 1.5 at y1 = 3, u1 = 5.
        let y = 0.4 * 3.0 - 2.0 * 5.0 + 1.5;
        let (y1, u1) = ((3.0 + 1.0) / 0.5, (5.0 - 2.0) / 3.0);
        let yw = w[0] * y1 + w[1] * u1 + w[2];
        assert!((yw * 0.5 - 1.0 - y).abs() < 1e-12, "{w:?}");
    }
}
