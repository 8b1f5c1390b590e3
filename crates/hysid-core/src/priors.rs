//! Gray-box prior knowledge, one type for every back-end
//! (`docs/priors.md`; `docs/file-formats.md`, "Prior files").
//!
//! Each back-end declares the [`PriorKind`]s it honours; a prior it cannot
//! honour is refused with an error naming the entry, never dropped.

use crate::options::{first_repeated, non_empty};
use hysid_model::model::{Stop, StopBound};
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

/// `switching`, not empty: an empty one would leave the regions nothing
/// to depend on.
fn named<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
    non_empty(
        d,
        "name the regressors the regions depend on, or leave switching out",
    )
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
    #[serde(
        skip_serializing_if = "BTreeMap::is_empty",
        deserialize_with = "hysid_model::model::exact_bounds_by_name"
    )]
    pub bounds: BTreeMap<String, [f64; 2]>,
    /// Regressors the regions may depend on (given, at least one).
    #[serde(skip_serializing_if = "Vec::is_empty", deserialize_with = "named")]
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
    /// The prior file parses but its entries contradict each other.
    #[error("{path}: {problem}")]
    Inconsistent {
        /// File (or "--modes").
        path: String,
        /// The inconsistency.
        #[source]
        problem: InconsistentPrior,
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

/// The largest `max_modes`: the counts up to it are fitted one by one.
pub const MAX_MODES_BOUND: usize = 1000;

/// An inconsistency among the entries of a prior file, found by
/// [`Priors::check`]; `entry` counts the `[[...]]` tables from 1.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InconsistentPrior {
    /// `modes = 0` or `max_modes = 0`.
    #[error("modes and max_modes must be at least 1")]
    NoMode,
    /// `max_modes` above [`MAX_MODES_BOUND`].
    #[error("max_modes = {0}: at most {MAX_MODES_BOUND} (every count up to it is a candidate fit)")]
    MaxModesTooLarge(usize),
    /// `modes` above `max_modes`.
    #[error("modes = {modes} exceeds max_modes = {max}")]
    ModesExceedMax {
        /// `modes`.
        modes: usize,
        /// `max_modes`.
        max: usize,
    },
    /// A mode count that leaves no ordinary mode beside the stops.
    #[error(
        "{key} = {count} counts every mode, the {stops} saturation mode(s) included: need at least {} for one ordinary mode",
        .stops + 1
    )]
    NoOrdinaryMode {
        /// `modes` or `max_modes`.
        key: &'static str,
        /// Its value.
        count: usize,
        /// Number of `[[saturation]]` entries.
        stops: usize,
    },
    /// A stop level that is not finite.
    #[error("[[saturation]] #{entry}: level must be finite")]
    SaturationLevel {
        /// Entry number.
        entry: usize,
    },
    /// A negative or non-finite stop tolerance.
    #[error("[[saturation]] #{entry}: tol must be finite and non-negative")]
    SaturationTol {
        /// Entry number.
        entry: usize,
    },
    /// Two `[[saturation]]` entries of the same level and side.
    #[error("[[saturation]] #{entry} repeats #{first} (the same level and bound)")]
    SaturationRepeated {
        /// The repeating entry's number.
        entry: usize,
        /// The first entry's number.
        first: usize,
    },
    /// A lower stop (`bound = "min"`) at or above an upper one.
    #[error(
        "[[saturation]] #{lower} (bound = \"min\", level {low}) is at or above #{upper} (bound = \"max\", level {high}): the output would have no room between them"
    )]
    SaturationsCross {
        /// The lower stop's entry number.
        lower: usize,
        /// Its level.
        low: f64,
        /// The upper stop's entry number.
        upper: usize,
        /// Its level.
        high: f64,
    },
    /// A name listed twice in one entry.
    #[error("{entry}: '{}' is listed twice", .name.escape_debug())]
    Repeated {
        /// The entry (`switching`, `[[tie]] #2`).
        entry: String,
        /// The name.
        name: String,
    },
    /// A tie of no parameter.
    #[error("[[tie]] #{entry}: params is empty")]
    EmptyTie {
        /// Entry number.
        entry: usize,
    },
    /// An equality of no parameter.
    #[error("[[equality]] #{entry}: coefficients is empty")]
    EmptyEquality {
        /// Entry number.
        entry: usize,
    },
    /// A non-finite equality coefficient.
    #[error("[[equality]] #{entry}: coefficient of {param} must be finite, got {value}")]
    EqualityCoefficient {
        /// Entry number.
        entry: usize,
        /// Parameter name.
        param: String,
        /// The coefficient.
        value: f64,
    },
    /// An equality whose coefficients are all zero.
    #[error("[[equality]] #{entry}: every coefficient is zero")]
    ZeroEquality {
        /// Entry number.
        entry: usize,
    },
    /// A non-finite equality right-hand side.
    #[error("[[equality]] #{entry}: value must be finite")]
    EqualityValue {
        /// Entry number.
        entry: usize,
    },
    /// A non-finite fixed value.
    #[error("[fixed] {param}: value must be finite")]
    FixedValue {
        /// Parameter name.
        param: String,
    },
    /// Bounds with low above high (or NaN).
    #[error("[bounds] {param}: need low <= high, got [{low}, {high}]")]
    Bounds {
        /// Parameter name.
        param: String,
        /// Lower bound.
        low: f64,
        /// Upper bound.
        high: f64,
    },
}

/// What a back-end's fit needs of the priors' number of modes
/// ([`crate::backend::Identifier::mode_count_need`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeCountNeed {
    /// Nothing: the back-end chooses the count, or has a fixed one.
    Nothing,
    /// `modes`, or `max_modes` to choose the count under.
    CountOrBound,
    /// `modes` itself.
    Count,
}

impl ModeCountNeed {
    /// Whether `priors` give what is needed.
    pub fn met_by(self, priors: &Priors) -> bool {
        match self {
            ModeCountNeed::Nothing => true,
            ModeCountNeed::CountOrBound => priors.modes.is_some() || priors.max_modes.is_some(),
            ModeCountNeed::Count => priors.modes.is_some(),
        }
    }
}

impl Priors {
    /// Parses a prior file's text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, PriorError> {
        Self::checked(
            toml::from_str(text).map_err(|e| e.to_string().trim().replace('\n', " ")),
            origin,
        )
    }

    /// Parses priors given as JSON in the prior file's shape (the Python
    /// package's `priors` dictionary); `origin` names them in errors.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, PriorError> {
        Self::checked(
            serde_json::from_str(text).map_err(|e| e.to_string()),
            origin,
        )
    }

    /// Parsed priors (or the parser's message) after their consistency
    /// [`Priors::check`].
    fn checked(parsed: Result<Self, String>, origin: &str) -> Result<Self, PriorError> {
        let p = parsed.map_err(|message| PriorError::Invalid {
            path: origin.to_string(),
            message,
        })?;
        p.check().map_err(|problem| PriorError::Inconsistent {
            path: origin.to_string(),
            problem,
        })?;
        Ok(p)
    }

    /// Reads a prior file: TOML, or JSON of the same shape where its name
    /// ends in `.json`.
    pub fn load(path: &Path) -> Result<Self, PriorError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| PriorError::Io {
            path: origin.clone(),
            source,
        })?;
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
        {
            Self::from_json(&text, &origin)
        } else {
            Self::from_toml(&text, &origin)
        }
    }

    /// Internal consistency (independent of the model structure).
    pub fn check(&self) -> Result<(), InconsistentPrior> {
        use InconsistentPrior as E;
        if self.modes == Some(0) || self.max_modes == Some(0) {
            return Err(E::NoMode);
        }
        if let Some(max) = self.max_modes.filter(|&m| m > MAX_MODES_BOUND) {
            return Err(E::MaxModesTooLarge(max));
        }
        if let (Some(modes), Some(max)) = (self.modes, self.max_modes)
            && modes > max
        {
            return Err(E::ModesExceedMax { modes, max });
        }
        let stops = self.saturation.len();
        for (key, v) in [("modes", self.modes), ("max_modes", self.max_modes)] {
            if let Some(count) = v
                && count <= stops
            {
                return Err(E::NoOrdinaryMode { key, count, stops });
            }
        }
        for (i, s) in self.saturation.iter().enumerate() {
            let entry = i + 1;
            if !s.level.is_finite() {
                return Err(E::SaturationLevel { entry });
            }
            if s.tol.is_some_and(|t| !(t.is_finite() && t >= 0.0)) {
                return Err(E::SaturationTol { entry });
            }
            if let Some(j) = self.saturation[..i]
                .iter()
                .position(|o| o.level == s.level && o.bound == s.bound)
            {
                return Err(E::SaturationRepeated {
                    entry,
                    first: j + 1,
                });
            }
        }
        // A stop the output never goes below at or above one it never
        // exceeds leaves no room between them.
        let level_of = |bound: StopBound| {
            self.saturation
                .iter()
                .enumerate()
                .filter(move |(_, s)| s.bound == bound)
                .map(|(i, s)| (i + 1, s.level))
        };
        for (lower, low) in level_of(StopBound::Min) {
            if let Some((upper, high)) = level_of(StopBound::Max).find(|&(_, high)| low >= high) {
                return Err(E::SaturationsCross {
                    lower,
                    low,
                    upper,
                    high,
                });
            }
        }
        for (i, t) in self.tie.iter().enumerate() {
            if t.params.is_empty() {
                return Err(E::EmptyTie { entry: i + 1 });
            }
            if let Some(name) = first_repeated(&t.params).cloned() {
                return Err(E::Repeated {
                    entry: format!("[[tie]] #{}", i + 1),
                    name,
                });
            }
        }
        if let Some(name) = first_repeated(&self.switching).cloned() {
            return Err(E::Repeated {
                entry: "switching".into(),
                name,
            });
        }
        for (i, e) in self.equality.iter().enumerate() {
            let entry = i + 1;
            if e.coefficients.is_empty() {
                return Err(E::EmptyEquality { entry });
            }
            if let Some((k, c)) = e.coefficients.iter().find(|(_, c)| !c.is_finite()) {
                return Err(E::EqualityCoefficient {
                    entry,
                    param: k.clone(),
                    value: *c,
                });
            }
            if e.coefficients.values().all(|c| *c == 0.0) {
                return Err(E::ZeroEquality { entry });
            }
            if !e.value.is_finite() {
                return Err(E::EqualityValue { entry });
            }
        }
        for (k, v) in &self.fixed {
            if !v.is_finite() {
                return Err(E::FixedValue { param: k.clone() });
            }
        }
        for (k, &[low, high]) in &self.bounds {
            if low.is_nan() || high.is_nan() || low > high {
                return Err(E::Bounds {
                    param: k.clone(),
                    low,
                    high,
                });
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_model::model::StopBound;

    /// A stop given twice, and a lower stop at or above an upper one, are
    /// refused; two stops with room between them are not.
    #[test]
    fn repeated_and_crossing_stops_are_refused() {
        let stops = |pairs: &[(f64, StopBound)]| {
            Priors {
                saturation: pairs
                    .iter()
                    .map(|&(level, bound)| Stop {
                        level,
                        bound,
                        tol: None,
                    })
                    .collect(),
                ..Priors::default()
            }
            .check()
        };
        use StopBound::{Max, Min};
        assert!(stops(&[(25.0, Max), (0.0, Min)]).is_ok());
        assert_eq!(
            stops(&[(25.0, Max), (25.0, Max)]),
            Err(InconsistentPrior::SaturationRepeated { entry: 2, first: 1 })
        );
        assert!(matches!(
            stops(&[(0.0, Max), (0.0, Min)]),
            Err(InconsistentPrior::SaturationsCross {
                lower: 2,
                upper: 1,
                ..
            })
        ));
        assert!(matches!(
            stops(&[(10.0, Min), (5.0, Max)]),
            Err(InconsistentPrior::SaturationsCross {
                lower: 1,
                upper: 2,
                ..
            })
        ));
    }

    /// The example file of docs/priors.md reads as it is shown, every key
    /// in the table its comment puts it in.
    #[test]
    fn the_documented_example_file_reads() {
        let doc = include_str!("../../../docs/priors.md");
        let start = doc.find("```toml\n").expect("a TOML block") + "```toml\n".len();
        let end = start + doc[start..].find("```").unwrap();
        let p = Priors::from_toml(&doc[start..end], "priors.md").unwrap();
        assert_eq!(p.modes, Some(4));
        assert_eq!(p.switching, ["y1"]);
        assert_eq!(p.saturation.len(), 2);
        assert_eq!(p.bounds.keys().collect::<Vec<_>>(), ["b1"]);
        p.check().unwrap();
    }

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
    fn spec_example_parses() {
        let p =
            Priors::from_toml(&format!("switching = [\"y1\"]\n{SPEC_EXAMPLE}"), "p.toml").unwrap();
        assert_eq!(p.modes, Some(4));
        assert_eq!(p.saturation.len(), 2);
        assert_eq!(p.saturation[0].bound, StopBound::Max);
        assert_eq!(p.kinds().len(), 7 - 1);
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
        let refused = |text: &str| Priors::from_toml(text, "p.toml").unwrap_err().to_string();
        let e = refused("switching = []");
        assert!(e.contains("p.toml") && e.contains("an empty list"), "{e}");
        let e = refused("switching = [\"y1\", \"u1\", \"y1\"]");
        assert!(e.ends_with("switching: 'y1' is listed twice"), "{e}");
        let e = refused("[[tie]]\nparams = [\"a1\"]\n[[tie]]\nparams = [\"b1\", \"b1\"]");
        assert!(e.ends_with("[[tie]] #2: 'b1' is listed twice"), "{e}");
        assert!(Priors::from_toml("switching = [\"y1\", \"u1\"]", "p").is_ok());
    }

    #[test]
    fn equality_parses_and_is_checked() {
        let p = Priors::from_toml(
            "[[equality]]\ncoefficients = { a1 = 1.0, a2 = 1.0 }\nvalue = 1.0\n[[equality]]\ncoefficients = { b1 = 1.0, b2 = -2.0 }\n",
            "p.toml",
        )
        .unwrap();
        assert_eq!(p.kinds(), vec![PriorKind::Equality]);
        assert_eq!(p.equality[1].value, 0.0);
        assert_eq!(p.equality[0].describe(), "a1 + a2 = 1");
        assert_eq!(p.equality[1].describe(), "b1 - 2 b2 = 0");
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
    fn saturation_tolerance_is_checked() {
        let e = Priors::from_toml(
            "[[saturation]]\nlevel = 1.0\nbound = \"max\"\ntol = -1.0\n",
            "p",
        )
        .unwrap_err();
        assert!(matches!(
            e,
            PriorError::Inconsistent {
                problem: InconsistentPrior::SaturationTol { entry: 1 },
                ..
            }
        ));
        assert_eq!(
            e.to_string(),
            "p: [[saturation]] #1: tol must be finite and non-negative"
        );
    }
}
