//! # hysid-numerics
//!
//! Numerical pieces that know no model, shared by the physics models, the
//! PWARX pipeline and the back-ends:
//!
//! | module | concept |
//! |---|---|
//! | [`budget`] | a run's [`Deadline`](budget::Deadline), the iteration [`Budget`](budget::Budget) of a loop |
//! | [`least_squares`] | the one Levenberg-Marquardt, on exact or finite-difference Jacobians, under a problem's constraints |

pub mod budget;
pub mod least_squares;
