//! The options of the `bounded` back-end, and their checks.

use hysid_core::options::{CheckOptions, OptionError, OptionType, check_count, check_float};
use hysid_estimation::regions::RegionMethod;
use serde::{Deserialize, Serialize};

/// The back-end's name.
pub const NAME: &str = "bounded";

/// The keyword `auto` of `--set delta=auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AutoKeyword {
    /// `auto`.
    #[serde(rename = "auto")]
    Auto,
}

/// The error bound: a number (output units) or `auto`
/// ([`crate::noise::auto_delta`]). Parses from `--set delta=0.1` and
/// `--set delta=auto`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Delta {
    /// A bound in output units.
    Value(f64),
    /// Estimated from the data.
    Auto(AutoKeyword),
}

impl OptionType for Delta {
    fn type_name() -> String {
        "float|auto".into()
    }
}

hysid_core::option_enum! {
    /// How each mode is re-estimated on its assigned samples.
    pub enum Refit {
        /// Chebyshev (l-infinity) LP: certifies |residual| <= delta on every assigned sample.
        Linf => "linf",
        /// Least squares (not certified).
        Ls => "ls",
    }
}

hysid_core::backend_options! {
    /// Options of the `bounded` back-end.
    pub struct BoundedOptions {
        /// Bound delta on the identification error |y - phi' theta|, in output
        /// units, or `auto`: 3 times the median noise standard deviation of local
        /// affine fits (docs/bounded.md). Larger delta, fewer modes.
        delta: Delta = Delta::Auto(AutoKeyword::Auto),
        /// Thermal relaxation cycles per MAX FS problem (each visits all remaining
        /// samples once in a random order).
        cycles: usize = 100,
        /// Initial temperature T0 as a multiple of max(median |residual of the start|,
        /// delta), per relaxed start; the temperature falls linearly to 0 over the cycles.
        t0: f64 = 2.0,
        /// Candidate starts of each MAX FS problem besides the least-squares fit of the
        /// remaining samples: least-squares fits of random local neighbourhoods (3p nearest
        /// samples in standardised regressor space); the best candidate is relaxed too.
        restarts: usize = 8,
        /// Merge two modes when |theta_i - theta_j| / min(|theta_i|, |theta_j|) <= alpha.
        alpha: f64 = 0.05,
        /// Drop modes with fewer than max(beta N, number of parameters) assigned samples.
        beta: f64 = 0.02,
        /// Re-estimation of each mode: linf (Chebyshev LP, certified) or ls.
        refit: Refit = Refit::Linf,
        /// Upper bound on the number of modes, saturation modes included (also taken
        /// from the prior max_modes); none: no bound.
        max_modes: Option<usize> = None,
        /// Region estimation from the classified samples (docs/regions.md): mrlp
        /// (multicategory robust LP, complete partition), msvm (multicategory SVM,
        /// complete partition), psvc (pairwise proximal SVM, may leave holes) or
        /// softmax (multinomial logistic regression, complete partition).
        regions: RegionMethod = RegionMethod::Mrlp,
        /// Bound on the rounds of the alternation between the modes' least squares, a
        /// softmax gate and the mode of every sample that follows the classification
        /// (docs/bounded.md, "Alternation"); 0: none, the published procedure
        /// (preset=paper).
        alternation: usize = hysid_estimation::regions::AUTO_ROUNDS,
    }
}

impl CheckOptions for BoundedOptions {
    fn check(&self) -> Result<(), OptionError> {
        match self.delta {
            Delta::Value(d) => check_float(
                "delta",
                d,
                |d| d > 0.0,
                "must be a finite number > 0 (or auto)",
            )?,
            Delta::Auto(_) => {}
        }
        if !(1..=100_000).contains(&self.cycles) {
            return Err(OptionError::invalid(
                "cycles",
                self.cycles,
                "must be in 1..=100000",
            ));
        }
        check_count("restarts", self.restarts, 0)?;
        check_float("t0", self.t0, |t| t > 0.0, "must be a finite number > 0")?;
        check_float(
            "alpha",
            self.alpha,
            |a| a >= 0.0,
            "must be a finite number >= 0",
        )?;
        check_float(
            "beta",
            self.beta,
            |b| (0.0..1.0).contains(&b),
            "must be in [0, 1)",
        )?;
        Ok(())
    }
}
