//! Piecewise ARX models: `y(k) = theta_i . [x(k); 1]` for `x(k)` in region
//! `X_i = { x : A_i x <= b_i }` (Ferrari-Trecate et al., Automatica 2003, eq. 1-2).

use super::{InvalidModel, ModelInfo};
use crate::data::Standardization;
use crate::geometry::{Polyhedron, membership_tolerance};
use crate::regressors::RegressorSpec;
use serde::{Deserialize, Serialize};

/// The name of mode `k` (0-based) whose own name is `name`: that name, or
/// `mode k+1`. Modes are numbered from 1 wherever they are shown or written
/// (model files, simulated CSVs, plots, reports).
pub fn mode_name(name: Option<&str>, k: usize) -> String {
    name.map_or_else(|| format!("mode {}", k + 1), str::to_string)
}

/// One PWARX mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PwarxMode {
    /// Parameters `[a_1 .. a_na, b_11 .. b_mnb, c]`.
    pub theta: Vec<f64>,
    /// Region in regressor space; no rows means everywhere.
    #[serde(default)]
    pub region: Polyhedron,
    /// Optional name (e.g. "free", "impact").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

impl PwarxMode {
    /// Unnamed modes from parameter vectors and their regions, in order.
    pub fn unnamed(
        thetas: impl IntoIterator<Item = Vec<f64>>,
        regions: impl IntoIterator<Item = Polyhedron>,
    ) -> Vec<PwarxMode> {
        thetas
            .into_iter()
            .zip(regions)
            .map(|(theta, region)| PwarxMode {
                theta,
                region,
                name: None,
            })
            .collect()
    }
}

/// A PWARX model in original units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PwarxModel {
    /// Past outputs in the regressor.
    pub na: usize,
    /// Past values of each input in the regressor.
    pub nb: usize,
    /// Number of inputs.
    pub inputs: usize,
    /// The modes.
    pub modes: Vec<PwarxMode>,
    /// Provenance.
    #[serde(default)]
    pub info: ModelInfo,
}

/// The mode chosen for a regressor, and whether a region contained it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RegionChoice {
    /// Mode index.
    pub mode: usize,
    /// False when the regressor lay outside every region.
    pub covered: bool,
}

/// The region of `regions` for regressor `x`, the policy of every hysid
/// simulation: the first region that contains `x` (lowest index, as HIT's
/// `hit_pwa`); outside every region, the region of least violation
/// (smallest Euclidean distance to its half-spaces, the lowest index on a
/// tie), reported as not covered. Mode 0 when `regions` is empty.
pub fn region_of<'a>(regions: impl IntoIterator<Item = &'a Polyhedron>, x: &[f64]) -> RegionChoice {
    let tolerance = membership_tolerance(x);
    let mut best = (f64::INFINITY, 0);
    for (i, region) in regions.into_iter().enumerate() {
        let v = region.violation(x);
        if v <= tolerance {
            return RegionChoice {
                mode: i,
                covered: true,
            };
        }
        if v < best.0 {
            best = (v, i);
        }
    }
    RegionChoice {
        mode: best.1,
        covered: false,
    }
}

impl PwarxModel {
    /// Regressor structure of the model.
    pub fn spec(&self) -> RegressorSpec {
        RegressorSpec::new(self.na, self.nb, self.inputs)
    }

    /// Structural checks.
    pub fn validate(&self) -> Result<(), InvalidModel> {
        if self.modes.is_empty() {
            return Err(InvalidModel::NoPwarxMode);
        }
        if self.inputs == 0 && self.nb > 0 {
            return Err(InvalidModel::NbWithoutInput);
        }
        let spec = self.spec();
        let need = (self.nb.checked_mul(self.inputs))
            .and_then(|b| b.checked_add(self.na))
            .and_then(|d| d.checked_add(1))
            .ok_or(InvalidModel::OrdersTooLarge {
                na: self.na,
                nb: self.nb,
                inputs: self.inputs,
            })?;
        for (mode, m) in self.modes.iter().enumerate() {
            if m.theta.len() != need {
                return Err(InvalidModel::ThetaLength {
                    mode,
                    len: m.theta.len(),
                    na: self.na,
                    nb: self.nb,
                    inputs: self.inputs,
                    need,
                });
            }
            if m.theta.iter().any(|v| !v.is_finite()) {
                return Err(InvalidModel::NonFiniteTheta { mode });
            }
            m.region
                .validate(spec.dim())
                .map_err(|problem| InvalidModel::Region { mode, problem })?;
        }
        self.check_names()
    }

    /// Every mode's name as shown ([`mode_name`]) differs from the others',
    /// and none given is blank: a simulated CSV's `mode` column names one
    /// mode by one label.
    fn check_names(&self) -> Result<(), InvalidModel> {
        let mut shown = std::collections::HashSet::with_capacity(self.modes.len());
        for (mode, m) in self.modes.iter().enumerate() {
            if m.name.as_deref().is_some_and(|n| n.trim().is_empty()) {
                return Err(InvalidModel::EmptyModeName { mode });
            }
            let name = mode_name(m.name.as_deref(), mode);
            if !shown.insert(name.clone()) {
                return Err(InvalidModel::DuplicateMode(name));
            }
        }
        Ok(())
    }

    /// The mode for regressor `x` (the policy of every hysid simulation):
    /// [`region_of`] on the model's regions.
    pub fn mode_of(&self, x: &[f64]) -> RegionChoice {
        region_of(self.modes.iter().map(|m| &m.region), x)
    }

    /// `theta_i . [x; 1]`.
    pub fn predict_in_mode(&self, mode: usize, x: &[f64]) -> f64 {
        let th = &self.modes[mode].theta;
        let d = x.len();
        th[..d].iter().zip(x).map(|(a, b)| a * b).sum::<f64>() + th[d]
    }

    /// One-step prediction at regressor `x`, with the mode used.
    pub fn predict(&self, x: &[f64]) -> (f64, RegionChoice) {
        let c = self.mode_of(x);
        (self.predict_in_mode(c.mode, x), c)
    }

    /// Expresses a model identified on standardised data in original units
    /// (exact: regressors and outputs are affine images of each other).
    ///
    /// With `y = s_y ys + m_y`, `u_i = s_i us_i + m_i` and
    /// `ys(k) = sum a_j ys(k-j) + sum b_ij us_i(k-j) + c`:
    /// `a_j` is unchanged, `b_ij -> b_ij s_y / s_i`, and
    /// `c -> s_y c + m_y (1 - sum a_j) - sum b_ij s_y m_i / s_i`. Regions map
    /// through `xs = (x - m) / s`.
    pub fn to_original_units(&self, scale: &Standardization) -> PwarxModel {
        let spec = self.spec();
        let d = spec.dim();
        let (sy, my) = (scale.output.std, scale.output.mean);
        // Per-regressor mean and std (y lags then input lags).
        let mut m = Vec::with_capacity(d);
        let mut s = Vec::with_capacity(d);
        for _ in 0..self.na {
            m.push(my);
            s.push(sy);
        }
        for sc in &scale.inputs {
            for _ in 0..self.nb {
                m.push(sc.mean);
                s.push(sc.std);
            }
        }
        let inv_s: Vec<f64> = s.iter().map(|v| 1.0 / v).collect();
        let neg_m_over_s: Vec<f64> = m.iter().zip(&s).map(|(a, b)| -a / b).collect();
        let modes = self
            .modes
            .iter()
            .map(|mode| {
                let th = &mode.theta;
                let mut t = vec![0.0; d + 1];
                let mut c = sy * th[d] + my;
                for j in 0..d {
                    t[j] = th[j] * sy / s[j];
                    c -= t[j] * m[j];
                }
                t[d] = c;
                PwarxMode {
                    theta: t,
                    region: mode.region.affine_preimage(&neg_m_over_s, &inv_s),
                    name: mode.name.clone(),
                }
            })
            .collect();
        PwarxModel {
            na: self.na,
            nb: self.nb,
            inputs: self.inputs,
            modes,
            info: ModelInfo {
                scaling: Some(scale.clone()),
                ..self.info.clone()
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::AffineScale;

    fn two_mode() -> PwarxModel {
        PwarxModel {
            na: 1,
            nb: 1,
            inputs: 1,
            modes: vec![
                PwarxMode {
                    theta: vec![0.5, 1.0, 0.1],
                    region: Polyhedron::from_inequalities(vec![vec![1.0, 0.0]], vec![0.0]),
                    name: None,
                },
                PwarxMode {
                    theta: vec![-0.5, 2.0, -0.1],
                    region: Polyhedron::from_inequalities(vec![vec![-1.0, 0.0]], vec![-1.0]),
                    name: None,
                },
            ],
            info: ModelInfo::default(),
        }
    }

    #[test]
    fn the_names_shown_are_unique_and_none_given_is_blank() {
        let named = |names: [Option<&str>; 2]| {
            let mut m = two_mode();
            for (mode, name) in m.modes.iter_mut().zip(names) {
                mode.name = name.map(str::to_string);
            }
            m.validate()
        };
        assert_eq!(named([None, None]), Ok(()));
        assert_eq!(named([Some("free"), Some("mode 1")]), Ok(()));
        assert_eq!(named([None, Some("mode 2")]), Ok(()));
        assert_eq!(
            named([None, Some("mode 1")]),
            Err(InvalidModel::DuplicateMode("mode 1".into()))
        );
        assert_eq!(
            named([Some("x"), Some("x")]),
            Err(InvalidModel::DuplicateMode("x".into()))
        );
        let blank = named([None, Some(" ")]).unwrap_err();
        assert_eq!(blank, InvalidModel::EmptyModeName { mode: 1 });
        assert!(
            blank.to_string().starts_with("mode 2: an empty name"),
            "{blank}"
        );
    }

    #[test]
    fn mode_policy_first_region_then_least_violation() {
        let m = two_mode();
        assert_eq!(
            m.mode_of(&[-1.0, 0.0]),
            RegionChoice {
                mode: 0,
                covered: true
            }
        );
        assert_eq!(
            m.mode_of(&[2.0, 0.0]),
            RegionChoice {
                mode: 1,
                covered: true
            }
        );
        // Hole (0, 1): nearest region wins, uncovered.
        assert_eq!(
            m.mode_of(&[0.2, 0.0]),
            RegionChoice {
                mode: 0,
                covered: false
            }
        );
        assert_eq!(
            m.mode_of(&[0.9, 0.0]),
            RegionChoice {
                mode: 1,
                covered: false
            }
        );
    }

    #[test]
    fn original_units_reproduce_scaled_predictions() {
        let m = two_mode();
        let sc = Standardization {
            inputs: vec![AffineScale {
                mean: 3.0,
                std: 0.5,
            }],
            output: AffineScale {
                mean: -2.0,
                std: 4.0,
            },
        };
        let o = m.to_original_units(&sc);
        for &(y1, u1) in &[(-5.0, 2.0), (10.0, 4.0), (-1.0, 3.1)] {
            let xs = [sc.output.apply(y1), sc.inputs[0].apply(u1)];
            let (ys, cs) = m.predict(&xs);
            let (yo, co) = o.predict(&[y1, u1]);
            assert_eq!(cs.mode, co.mode);
            assert!(
                (sc.output.invert(ys) - yo).abs() < 1e-9,
                "{} vs {yo}",
                sc.output.invert(ys)
            );
        }
    }
}
