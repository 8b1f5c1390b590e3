//! # hysid-sign
//!
//! The worked example of `docs/architecture.md`: a complete PWARX back-end
//! in one file, on the shared layer of `hysid_estimation::pwarx`. Its
//! partition is known in advance, one mode per sign of the first input
//! `u1(k-1)`, so the whole method is: split the samples by that sign, fit
//! each mode by least squares under the priors. It is not registered in
//! `hysid::backends`; registering it would be the one line
//! `.with(hysid_sign::Sign)`.

use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::{CheckOptions, Checked, OptionError, check_float};
use hysid_core::priors::PriorKind;
use hysid_estimation::constrained::{Parametrisation, fit_modes_on};
use hysid_estimation::pwarx::{self, ModeCount, PwarxData, PwarxFit};
use hysid_model::geometry::Polyhedron;
use hysid_model::model::PwarxMode;
use serde::Serialize;

hysid_core::backend_options! {
    /// Options of the `sign` back-end.
    pub struct SignOptions {
        /// Samples with u1(k-1) at or above this threshold go to the second mode.
        threshold: f64 = 0.0,
    }
}

impl CheckOptions for SignOptions {
    fn check(&self) -> Result<(), OptionError> {
        check_float(
            "threshold",
            self.threshold,
            |_| true,
            "must be a finite number",
        )
    }
}

/// The `sign` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sign;

impl Identifier for Sign {
    type Options = SignOptions;
    const NAME: &'static str = "sign";
    const SEEDED: bool = false;
    const SUMMARY: &'static str = "one affine mode per sign of u1(k-1): the worked example";
    const HONOURS: &'static [PriorKind] = &[
        PriorKind::Modes,
        PriorKind::Saturation,
        PriorKind::Tie,
        PriorKind::Fixed,
        PriorKind::Bounds,
        PriorKind::Equality,
    ];

    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &Checked<SignOptions>,
        _ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let data = pwarx::prepare(problem, Self::NAME)?;
        Ok(pwarx::assemble(&data, fit(options, &data)?))
    }
}

/// What the `sign` back-end reports besides the common diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct SignDiagnostics {
    /// Ordinary samples in each mode.
    pub samples_per_mode: [usize; 2],
}

/// The method's steps: the regressor column of `u1(k-1)`, the split by its
/// sign, least squares per mode under the priors, the two half-spaces.
pub fn fit(
    options: &SignOptions,
    data: &PwarxData<'_>,
) -> Result<PwarxFit<SignDiagnostics>, IdentifyError> {
    let column = input_column(data)?;
    let split = split_by_sign(data, column, options.threshold);
    let thetas = least_squares(data, &split)?;
    let regions = half_spaces(data.spec.dim(), column, options.threshold);
    Ok(PwarxFit::complete(
        PwarxMode::unnamed(thetas, regions),
        SignDiagnostics {
            samples_per_mode: [split[0].len(), split[1].len()],
        },
    ))
}

/// The column of `u1(k-1)` among the regressors `[y(k-1..k-na), u1(k-1..)]`;
/// the mode count, if given, must be two.
fn input_column(data: &PwarxData<'_>) -> Result<usize, IdentifyError> {
    if data.spec.nb == 0 {
        return Err(SignError::NoInputLag.into());
    }
    match data.modes {
        ModeCount::Exact(s) if s != 2 => Err(SignError::ModeCount(s).into()),
        _ => Ok(data.spec.na),
    }
}

/// The ordinary rows below the threshold, then those at or above it.
fn split_by_sign(data: &PwarxData<'_>, column: usize, threshold: f64) -> [Vec<usize>; 2] {
    let (low, high) = data
        .ordinary
        .iter()
        .partition(|&&r| data.regressors.x[(r, column)] < threshold);
    [low, high]
}

/// One parameter vector per mode (`hysid_estimation::constrained`: ties,
/// fixed values and equalities exact, bounds by a QP).
fn least_squares(
    data: &PwarxData<'_>,
    split: &[Vec<usize>; 2],
) -> Result<Vec<Vec<f64>>, IdentifyError> {
    let par = Parametrisation::from_priors(data.priors(), &data.spec, 2)
        .map_err(|e| data.prior_error(e))?;
    fit_modes_on(&par, &data.regressors, split).map_err(|e| IdentifyError::failed(e.to_string()))
}

/// `u1(k-1) <= threshold` and `u1(k-1) >= threshold` as polyhedra.
fn half_spaces(dim: usize, column: usize, threshold: f64) -> [Polyhedron; 2] {
    let normal = |sign: f64| {
        let mut a = vec![0.0; dim];
        a[column] = sign;
        a
    };
    [
        Polyhedron::from_inequalities(vec![normal(1.0)], vec![threshold]),
        Polyhedron::from_inequalities(vec![normal(-1.0)], vec![-threshold]),
    ]
}

/// Bad input of the `sign` back-end (an [`IdentifyError::Input`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SignError {
    /// No `u1(k-1)` regressor.
    #[error("method 'sign' needs nb >= 1")]
    NoInputLag,
    /// A mode count other than two ordinary modes.
    #[error("method 'sign' identifies exactly two ordinary modes, not {0}")]
    ModeCount(usize),
}

impl From<SignError> for IdentifyError {
    fn from(e: SignError) -> Self {
        IdentifyError::input(e)
    }
}
