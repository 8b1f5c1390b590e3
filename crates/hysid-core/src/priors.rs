//! Gray-box prior knowledge, one type for every back-end
//! (`docs/priors.md`; `docs/file-formats.md`, "Prior files").
//!
//! Each back-end declares the [`PriorKind`]s it honours; a prior it cannot
//! honour is refused with an error naming the entry, never dropped.

use hysid_model::model::Stop;
use hysid_model::regressors::RegressorSpec;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

/// The kinds of prior an entry of a prior file can be.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PriorKind {
    /// `modes = S`: exact number of modes.
    Modes,
    /// `max_modes = S`: an upper bound on the number of modes.
    MaxModes,
    /// `[[saturation]]`: a known stop, a mode on a lower-dimensional set.
    Saturation,
    /// `[[tie]]`: parameters sharing one value across modes.
    Tie,
    /// `[fixed]`: parameters with known values.
    Fixed,
    /// `[bounds]`: box constraints on parameters.
    Bounds,
    /// `switching = [...]`: regressors the regions may depend on.
    Switching,
    /// `[[equality]]`: a linear equality among a mode's parameters, in
    /// every ordinary mode.
    Equality,
}

impl PriorKind {
    /// Every kind: what a back-end that honours all priors declares.
    pub const ALL: &'static [PriorKind] = &[
        PriorKind::Modes,
        PriorKind::MaxModes,
        PriorKind::Saturation,
        PriorKind::Tie,
        PriorKind::Fixed,
        PriorKind::Bounds,
        PriorKind::Switching,
        PriorKind::Equality,
    ];
}

impl fmt::Display for PriorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PriorKind::Modes => "modes",
            PriorKind::MaxModes => "max_modes",
            PriorKind::Saturation => "[[saturation]]",
            PriorKind::Tie => "[[tie]]",
            PriorKind::Fixed => "[fixed]",
            PriorKind::Bounds => "[bounds]",
            PriorKind::Switching => "switching",
            PriorKind::Equality => "[[equality]]",
        })
    }
}

/// Parameters that share one value across all non-saturation modes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tie {
    /// Parameter names (`a1`, `b2`, `c`, ... for PWARX).
    pub params: Vec<String>,
}

/// A linear equality `sum_p coefficients[p] * theta[p] = value` among the
/// parameters of one mode, holding in every non-saturation mode (mode
/// identities are outputs of the identification, so an equality cannot
/// name a mode; `docs/priors.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Equality {
    /// Parameter name -> coefficient (`{ a1 = 1.0, a2 = 1.0 }`).
    pub coefficients: BTreeMap<String, f64>,
    /// Right-hand side (default 0).
    #[serde(default)]
    pub value: f64,
}

impl Equality {
    /// The equality as text, e.g. `a1 + a2 = 1`.
    pub fn describe(&self) -> String {
        let mut s = String::new();
        for (i, (name, c)) in self.coefficients.iter().enumerate() {
            let (sign, m) = if *c < 0.0 { ("-", -c) } else { ("+", *c) };
            if i == 0 {
                if sign == "-" {
                    s.push('-');
                }
            } else {
                s.push_str(&format!(" {sign} "));
            }
            if m != 1.0 {
                s.push_str(&format!("{m} "));
            }
            s.push_str(name);
        }
        format!("{s} = {}", self.value)
    }
}

/// All priors of a run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Priors {
    /// Exact number of modes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub modes: Option<usize>,
    /// Upper bound on the number of modes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_modes: Option<usize>,
    /// Known stops.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub saturation: Vec<Stop>,
    /// Parameter ties.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tie: Vec<Tie>,
    /// Fixed parameter values.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub fixed: BTreeMap<String, f64>,
    /// Box constraints `[low, high]`.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub bounds: BTreeMap<String, [f64; 2]>,
    /// Regressors the regions may depend on.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub switching: Vec<String>,
    /// Linear equalities among a mode's parameters, in every ordinary mode.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub equality: Vec<Equality>,
}

/// Errors in priors.
#[derive(Debug, thiserror::Error)]
pub enum PriorError {
    /// The prior file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// The prior file is malformed or inconsistent.
    #[error("{path}: {message}")]
    Invalid {
        /// File (or "--modes").
        path: String,
        /// What is wrong, naming the entry.
        message: String,
    },
    /// A back-end cannot honour an entry.
    #[error("method '{method}' does not honour the prior {kind}{origin}; it honours: {honoured}")]
    NotHonoured {
        /// Back-end name.
        method: String,
        /// The entry.
        kind: PriorKind,
        /// " (in FILE)" or empty.
        origin: String,
        /// What it does honour.
        honoured: String,
    },
}

impl Priors {
    /// Parses a prior file's text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, PriorError> {
        let p: Priors = toml::from_str(text).map_err(|e| PriorError::Invalid {
            path: origin.to_string(),
            message: e.to_string().trim().replace('\n', " "),
        })?;
        p.check().map_err(|message| PriorError::Invalid {
            path: origin.to_string(),
            message,
        })?;
        Ok(p)
    }

    /// Reads a prior file.
    pub fn load(path: &Path) -> Result<Self, PriorError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| PriorError::Io {
            path: origin.clone(),
            source,
        })?;
        Self::from_toml(&text, &origin)
    }

    /// Internal consistency (independent of the model structure).
    pub fn check(&self) -> Result<(), String> {
        if self.modes == Some(0) || self.max_modes == Some(0) {
            return Err("modes and max_modes must be at least 1".into());
        }
        if let (Some(s), Some(m)) = (self.modes, self.max_modes)
            && s > m
        {
            return Err(format!("modes = {s} exceeds max_modes = {m}"));
        }
        let stops = self.saturation.len();
        for (key, v) in [("modes", self.modes), ("max_modes", self.max_modes)] {
            if let Some(s) = v
                && s <= stops
            {
                return Err(format!(
                    "{key} = {s} counts every mode, the {stops} saturation mode(s) included: need at least {} for one ordinary mode",
                    stops + 1
                ));
            }
        }
        for (i, s) in self.saturation.iter().enumerate() {
            if !s.level.is_finite() {
                return Err(format!("[[saturation]] #{}: level must be finite", i + 1));
            }
            if s.tol.is_some_and(|t| !(t.is_finite() && t >= 0.0)) {
                return Err(format!(
                    "[[saturation]] #{}: tol must be finite and non-negative",
                    i + 1
                ));
            }
        }
        for (i, t) in self.tie.iter().enumerate() {
            if t.params.is_empty() {
                return Err(format!("[[tie]] #{}: params is empty", i + 1));
            }
        }
        for (i, e) in self.equality.iter().enumerate() {
            if e.coefficients.is_empty() {
                return Err(format!("[[equality]] #{}: coefficients is empty", i + 1));
            }
            if let Some((k, c)) = e.coefficients.iter().find(|(_, c)| !c.is_finite()) {
                return Err(format!(
                    "[[equality]] #{}: coefficient of {k} must be finite, got {c}",
                    i + 1
                ));
            }
            if e.coefficients.values().all(|c| *c == 0.0) {
                return Err(format!(
                    "[[equality]] #{}: every coefficient is zero",
                    i + 1
                ));
            }
            if !e.value.is_finite() {
                return Err(format!("[[equality]] #{}: value must be finite", i + 1));
            }
        }
        for (k, v) in &self.fixed {
            if !v.is_finite() {
                return Err(format!("[fixed] {k}: value must be finite"));
            }
        }
        for (k, [lo, hi]) in &self.bounds {
            if lo.is_nan() || hi.is_nan() || lo > hi {
                return Err(format!("[bounds] {k}: need low <= high, got [{lo}, {hi}]"));
            }
        }
        Ok(())
    }

    /// The kinds of entry present.
    pub fn kinds(&self) -> Vec<PriorKind> {
        let mut k = Vec::new();
        if self.modes.is_some() {
            k.push(PriorKind::Modes);
        }
        if self.max_modes.is_some() {
            k.push(PriorKind::MaxModes);
        }
        if !self.saturation.is_empty() {
            k.push(PriorKind::Saturation);
        }
        if !self.tie.is_empty() {
            k.push(PriorKind::Tie);
        }
        if !self.fixed.is_empty() {
            k.push(PriorKind::Fixed);
        }
        if !self.bounds.is_empty() {
            k.push(PriorKind::Bounds);
        }
        if !self.switching.is_empty() {
            k.push(PriorKind::Switching);
        }
        if !self.equality.is_empty() {
            k.push(PriorKind::Equality);
        }
        k
    }

    /// Refuses the run when an entry is not in `honoured`.
    pub fn ensure_honoured(
        &self,
        method: &str,
        honoured: &[PriorKind],
        origin: Option<&str>,
    ) -> Result<(), PriorError> {
        for kind in self.kinds() {
            if !honoured.contains(&kind) {
                return Err(PriorError::NotHonoured {
                    method: method.to_string(),
                    kind,
                    origin: origin.map(|o| format!(" (in {o})")).unwrap_or_default(),
                    honoured: if honoured.is_empty() {
                        "none".into()
                    } else {
                        honoured
                            .iter()
                            .map(ToString::to_string)
                            .collect::<Vec<_>>()
                            .join(", ")
                    },
                });
            }
        }
        Ok(())
    }

    /// Checks parameter and regressor names against a PWARX structure.
    pub fn check_pwarx_names(&self, spec: &RegressorSpec) -> Result<(), String> {
        let params = spec.param_names();
        let regs = spec.regressor_names();
        let known = |n: &str, list: &[String], entry: &str| -> Result<(), String> {
            if list.iter().any(|p| p == n) {
                Ok(())
            } else {
                Err(format!(
                    "{entry}: unknown name '{n}' (known: {})",
                    list.join(", ")
                ))
            }
        };
        for t in &self.tie {
            for p in &t.params {
                known(p, &params, "[[tie]] params")?;
            }
        }
        for (i, e) in self.equality.iter().enumerate() {
            for p in e.coefficients.keys() {
                known(p, &params, &format!("[[equality]] #{} coefficients", i + 1))?;
            }
        }
        for p in self.fixed.keys() {
            known(p, &params, "[fixed]")?;
        }
        for p in self.bounds.keys() {
            known(p, &params, "[bounds]")?;
        }
        for r in &self.switching {
            known(r, &regs, "switching")?;
        }
        Ok(())
    }
}

impl Priors {
    /// Whether the priors constrain the mode parameters (`[[tie]]`,
    /// `[fixed]`, `[bounds]` or `[[equality]]`).
    pub fn constrains_parameters(&self) -> bool {
        !(self.tie.is_empty()
            && self.fixed.is_empty()
            && self.bounds.is_empty()
            && self.equality.is_empty())
    }

    /// The exact number of ordinary (non-saturation) modes: `modes` minus
    /// the `[[saturation]]` entries (`modes` counts every mode).
    pub fn ordinary_modes(&self) -> Option<usize> {
        self.modes.map(|s| s - self.saturation.len())
    }

    /// The upper bound on the ordinary modes from `max_modes`.
    pub fn max_ordinary_modes(&self) -> Option<usize> {
        self.max_modes.map(|s| s - self.saturation.len())
    }

    /// The known stop the output value `y` sits at
    /// ([`Stop::holds`]), if any.
    pub fn stop_at(&self, y: f64) -> Option<usize> {
        self.saturation.iter().position(|s| s.holds(y))
    }

    /// For every regression target `y(k)`, the stop it sits at: the samples
    /// a back-end assigns to the saturation modes before clustering or
    /// bounded-error extraction (Juloski et al. 2003, section 5).
    pub fn saturated_samples(&self, targets: &[f64]) -> Vec<Option<usize>> {
        targets.iter().map(|&y| self.stop_at(y)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_model::model::StopBound;

    const SPEC_EXAMPLE: &str = r#"
modes = 4
[[saturation]]
level = 25.0
bound = "max"
[[saturation]]
level = 0.0
bound = "min"
[[tie]]
params = ["a1", "a2"]
[fixed]
c = 0.0
[bounds]
b1 = [0.0, 1.0e3]
"#;

    #[test]
    fn spec_example_parses_and_names_check() {
        let p =
            Priors::from_toml(&format!("switching = [\"y1\"]\n{SPEC_EXAMPLE}"), "p.toml").unwrap();
        assert_eq!(p.modes, Some(4));
        assert_eq!(p.saturation.len(), 2);
        assert_eq!(p.saturation[0].bound, StopBound::Max);
        assert_eq!(p.kinds().len(), 7 - 1);
        p.check_pwarx_names(&RegressorSpec::new(2, 2, 1)).unwrap();
        let e = p
            .check_pwarx_names(&RegressorSpec::new(1, 1, 1))
            .unwrap_err();
        assert!(e.contains("a2"), "{e}");
    }

    #[test]
    fn refusal_names_the_entry() {
        let p = Priors::from_toml(SPEC_EXAMPLE, "p.toml").unwrap();
        let e = p
            .ensure_honoured("arx", &[PriorKind::Fixed], Some("p.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("'arx'") && e.contains("modes") && e.contains("p.toml"),
            "{e}"
        );
    }

    #[test]
    fn typos_and_inconsistencies_are_errors() {
        let e = Priors::from_toml("mdoes = 3", "p.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.toml") && e.contains("mdoes"), "{e}");
        assert!(Priors::from_toml("modes = 5\nmax_modes = 3", "p").is_err());
        assert!(Priors::from_toml("[bounds]\nb1 = [2.0, 1.0]", "p").is_err());
        assert!(Priors::from_toml("[[saturation]]\nlevel = 1.0\nbound = \"up\"", "p").is_err());
    }

    #[test]
    fn equality_parses_and_names_are_checked() {
        let p = Priors::from_toml(
            "[[equality]]\ncoefficients = { a1 = 1.0, a2 = 1.0 }\nvalue = 1.0\n[[equality]]\ncoefficients = { b1 = 1.0, b2 = -2.0 }\n",
            "p.toml",
        )
        .unwrap();
        assert_eq!(p.kinds(), vec![PriorKind::Equality]);
        assert_eq!(p.equality[1].value, 0.0);
        assert_eq!(p.equality[0].describe(), "a1 + a2 = 1");
        assert_eq!(p.equality[1].describe(), "b1 - 2 b2 = 0");
        p.check_pwarx_names(&RegressorSpec::new(2, 2, 1)).unwrap();
        let e = p
            .check_pwarx_names(&RegressorSpec::new(1, 2, 1))
            .unwrap_err();
        assert!(e.contains("[[equality]] #1") && e.contains("'a2'"), "{e}");
        for bad in [
            "[[equality]]\ncoefficients = {}\n",
            "[[equality]]\ncoefficients = { a1 = 0.0 }\n",
            "[[equality]]\ncoefficients = { a1 = 1.0 }\nvalu = 2.0\n",
        ] {
            let e = Priors::from_toml(bad, "p.toml").unwrap_err().to_string();
            assert!(e.contains("p.toml"), "{e}");
        }
        let e = p
            .ensure_honoured(
                "physical",
                &[PriorKind::Fixed, PriorKind::Tie],
                Some("p.toml"),
            )
            .unwrap_err()
            .to_string();
        assert!(e.contains("[[equality]]") && e.contains("p.toml"), "{e}");
        p.ensure_honoured("bounded", PriorKind::ALL, None).unwrap();
    }

    #[test]
    fn saturated_samples_by_level_side_and_tolerance() {
        let sat = Priors::from_toml(
            "[[saturation]]\nlevel = 25.0\nbound = \"max\"\ntol = 0.005\n[[saturation]]\nlevel = 0.0\nbound = \"min\"\n",
            "p",
        )
        .unwrap();
        assert_eq!(sat.stop_at(24.996), Some(0));
        assert_eq!(sat.stop_at(25.3), Some(0), "beyond the stop counts");
        assert_eq!(sat.stop_at(24.9), None);
        assert_eq!(sat.stop_at(-0.1), Some(1));
        assert_eq!(sat.stop_at(1e-5), None, "default tolerance is 1e-6");
        assert_eq!(
            sat.saturated_samples(&[3.0, 25.0, 0.0]),
            vec![None, Some(0), Some(1)]
        );
        assert!(
            Priors::from_toml(
                "[[saturation]]\nlevel = 1.0\nbound = \"max\"\ntol = -1.0\n",
                "p"
            )
            .is_err()
        );
    }
}
