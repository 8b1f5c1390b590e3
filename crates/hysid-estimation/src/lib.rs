//! # hysid-estimation
//!
//! The estimation pieces PWARX back-ends share: mode parameters by
//! (weighted) least squares under the gray-box priors (ties, fixed values,
//! linear equalities, bounds), dense linear algebra, and the one wrapper
//! around the conic solver. faer lives only in [`linalg`], clarabel only in
//! [`conic`].
//!
//! | module | concept |
//! |---|---|
//! | [`conic`] | LPs and QPs on clarabel: `Program`, `Settings`, `solve`, and the status policy |
//! | [`constrained`] | `Parametrisation` of the priors, mode fits under them |
//! | [`linalg`] | SVD least squares, weighted and equality-constrained (faer) |
//! | [`noise`] | the noise level of a record from local affine fits |
//! | [`parsimony`] | the one-standard-error rule: the fewest modes within one standard error of the best score |
//! | [`pwarx`] | the set-up and assembly every PWARX back-end shares |
//! | [`regions`] | region estimation from labelled regressors (MRLP, MSVM, softmax, PSVC) and the alternation of regions and assignment |
//! | [`refine`] | the multiple-shooting simulation-error refinement a PWARX back-end may end with |
//! | [`trim`] | the trimmed re-estimation of the mode parameters on their regions, before the refinement |

pub mod conic;
pub mod constrained;
#[cfg(test)]
mod fixtures;
pub mod linalg;
pub mod noise;
pub mod parsimony;
pub mod pwarx;
pub mod refine;
pub mod regions;
pub mod trim;
