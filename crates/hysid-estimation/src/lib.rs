//! # hysid-estimation
//!
//! The pieces PWARX back-ends share: the PWARX pipeline they run
//! ([`pwarx`]), mode parameters by (weighted) least squares under the
//! gray-box priors (ties, fixed values, linear equalities, bounds), region
//! estimation, dense linear algebra, and the one wrapper around the conic
//! solver. faer lives only in [`linalg`], clarabel only in [`conic`].
//!
//! | module | concept |
//! |---|---|
//! | [`conic`] | LPs and QPs on clarabel: `Program`, `Settings`, `solve`, and the status policy |
//! | [`constrained`] | `Parametrisation` of the priors, mode fits under them |
//! | [`linalg`] | SVD least squares, weighted and equality-constrained (faer) |
//! | [`noise`] | the noise level of a record from local affine fits |
//! | [`parsimony`] | the one-standard-error rule: the fewest modes within one standard error of the best score |
//! | [`pwarx`] | the PWARX pipeline every PWARX back-end runs: set-up, mode count, the method's fit, trimmed re-estimation, simulation-error refinement, assembly |
//! | [`regions`] | region estimation from labelled regressors (MRLP, MSVM, softmax, PSVC) and the alternation of regions and assignment |

pub mod conic;
pub mod constrained;
pub mod dense;
#[cfg(test)]
mod fixtures;
pub mod linalg;
pub mod noise;
pub mod parsimony;
pub mod pwarx;
pub mod regions;
