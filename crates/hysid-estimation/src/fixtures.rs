//! Random priors shared by the tests of the stages after a PWARX fit
//! ([`crate::pwarx::trim`], [`crate::pwarx::refine`]).

use hysid_core::priors::Priors;

/// Priors with every kind of parameter constraint, and the check that a
/// fit honours them: `b1` bounded to `[lo, lo + width]`, the equality
/// `sum terms + eq_c c = value`, optionally `tied` in every mode and `c`
/// fixed.
#[derive(Debug, Clone)]
pub struct ConstraintPriors {
    /// Coefficients of the equality besides `c`'s, by parameter name.
    pub terms: &'static [(&'static str, f64)],
    /// Coefficient of `c` in the equality.
    pub eq_c: f64,
    /// Right-hand side of the equality.
    pub value: f64,
    /// Lower bound of `b1`.
    pub lo: f64,
    /// Width of `b1`'s bounds.
    pub width: f64,
    /// A parameter tied across the modes.
    pub tied: Option<&'static str>,
    /// The fixed value of `c`.
    pub fixed_c: Option<f64>,
}

impl ConstraintPriors {
    /// The priors, as a prior file writes them.
    pub fn priors(&self) -> Priors {
        let terms: Vec<String> = self
            .terms
            .iter()
            .map(|(name, coef)| format!("{name} = {coef:?}"))
            .collect();
        let mut text = format!(
            "[bounds]\nb1 = [{:?}, {:?}]\n[[equality]]\ncoefficients = {{ {}, c = {:?} }}\nvalue = {:?}\n",
            self.lo,
            self.lo + self.width,
            terms.join(", "),
            self.eq_c,
            self.value
        );
        if let Some(p) = self.tied {
            text += &format!("[[tie]]\nparams = [\"{p}\"]\n");
        }
        if let Some(c) = self.fixed_c {
            text += &format!("[fixed]\nc = {c:?}\n");
        }
        Priors::from_toml(&text, "p.toml").expect("the fixture's priors parse")
    }

    /// What `thetas` (their parameters named `names`) break of the priors:
    /// the equality beyond 1e-9 of the largest parameter (plus one), the
    /// bounds beyond 1e-9, the fixed value or the tie by a single bit.
    pub fn broken(&self, names: &[String], thetas: &[Vec<f64>]) -> Option<String> {
        let at = |name: &str| {
            names
                .iter()
                .position(|n| n == name)
                .expect("a parameter of the structure")
        };
        let (b1, c) = (at("b1"), at("c"));
        for m in thetas {
            let scale = 1.0 + m.iter().map(|x| x.abs()).fold(0.0, f64::max);
            let lhs: f64 = self
                .terms
                .iter()
                .map(|(name, coef)| coef * m[at(name)])
                .sum::<f64>()
                + self.eq_c * m[c];
            if (lhs - self.value).abs() > 1e-9 * scale {
                return Some(format!("{thetas:?}: {lhs} != {}", self.value));
            }
            if !(m[b1] >= self.lo - 1e-9 && m[b1] <= self.lo + self.width + 1e-9) {
                return Some(format!("{thetas:?}: b1 outside its bounds"));
            }
            if let Some(v) = self.fixed_c
                && m[c].to_bits() != v.to_bits()
            {
                return Some(format!("{thetas:?}: c is not the fixed {v}"));
            }
        }
        if let Some(p) = self.tied {
            let j = at(p);
            if thetas
                .iter()
                .any(|m| m[j].to_bits() != thetas[0][j].to_bits())
            {
                return Some(format!("{thetas:?}: {p} not tied"));
            }
        }
        None
    }
}
