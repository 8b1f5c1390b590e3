//! A model's free-run FIT beside the affine ARX model's, and the warning
//! a front end prints when it is below.

use super::fit_on;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_model::data::Dataset;

/// A model's free-run FIT on a record beside the affine ARX model's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AgainstAffine {
    /// The model's free-run simulation FIT, percent.
    pub model: f64,
    /// The free-run FIT of the affine ARX model of the same orders (and the
    /// same priors, without a mode count) fitted on the same record.
    pub affine: f64,
    /// The orders `(na, nb)` of both.
    pub orders: (usize, usize),
    /// Whether the affine model carries priors (other than a mode count).
    pub with_priors: bool,
}

impl AgainstAffine {
    /// True when the model simulates the record worse than the affine one
    /// by at least [`AgainstAffine::RESOLUTION`]: FITs the warning prints
    /// alike are alike.
    pub fn below(&self) -> bool {
        self.affine - self.model >= Self::RESOLUTION
    }

    /// The smallest FIT difference, in points, [`AgainstAffine::warning`]
    /// tells apart (it prints two decimals).
    pub const RESOLUTION: f64 = 0.005;

    /// The warning every front end gives when [`AgainstAffine::below`];
    /// `rows` names the rows ("its identification rows", "these rows"). The
    /// baseline is fitted on the rows it is scored on: what a user who has
    /// only these rows could have had with one linear model.
    pub fn warning(&self, rows: &str) -> String {
        let (na, nb) = self.orders;
        let priors = if self.with_priors {
            " with the same priors"
        } else {
            ""
        };
        format!(
            "the model's free-run FIT on {rows} ({:.2} %) is below that of an affine ARX({na},{nb}){priors} fitted on these same rows ({:.2} %)",
            self.model, self.affine
        )
    }
}

/// Scores `model` and the affine model `affine` fits on `data` with
/// `orders` and `priors` by free-run simulation of `data` (first `warmup`
/// samples left out). `None` when the affine model cannot be fitted or
/// either simulation cannot be scored: the comparison is a courtesy, never
/// a reason to fail.
pub fn against_affine(
    model: &Model,
    affine: &dyn Backend,
    data: &Dataset,
    orders: hysid_model::regressors::RegressorSpec,
    priors: &hysid_core::priors::Priors,
    warmup: usize,
) -> Option<AgainstAffine> {
    let mut priors = priors.clone();
    priors.modes = None;
    priors.max_modes = None;
    let problem = Problem {
        data,
        orders,
        priors: &priors,
        priors_origin: None,
    };
    let reference = affine
        .run(&problem, &Default::default(), &RunContext::quiet(0))
        .ok()?;
    Some(AgainstAffine {
        model: fit_on(model, data, warmup)?,
        affine: fit_on(&reference, data, warmup)?,
        orders: (orders.na, orders.nb),
        with_priors: !priors.kinds().is_empty(),
    })
}
