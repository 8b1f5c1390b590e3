//! Deterministic signals and random priors shared by the tests of the
//! stages after a PWARX fit ([`crate::trim`], [`crate::refine`]).

use hysid_core::priors::Priors;

/// A deterministic sequence in [-1, 1] (a linear congruential one).
pub fn uniform(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        })
        .collect()
}

/// Priors with every kind of parameter constraint: `b1` bounded to
/// `[lo, lo + width]`, the equality `terms + eq_c c = value` (`terms`
/// such as `"a1 = 1.0, b1 = 1.0"`), optionally `tied` in every mode and
/// `c` fixed.
pub fn constraint_priors(
    terms: &str,
    eq_c: f64,
    value: f64,
    (lo, width): (f64, f64),
    tied: Option<&str>,
    fixed_c: Option<f64>,
) -> Priors {
    let mut text = format!(
        "[bounds]\nb1 = [{lo:?}, {:?}]\n[[equality]]\ncoefficients = {{ {terms}, c = {eq_c:?} }}\nvalue = {value:?}\n",
        lo + width
    );
    if let Some(p) = tied {
        text += &format!("[[tie]]\nparams = [\"{p}\"]\n");
    }
    if let Some(c) = fixed_c {
        text += &format!("[fixed]\nc = {c:?}\n");
    }
    Priors::from_toml(&text, "p.toml").expect("the fixture's priors parse")
}
