//! # hysid-numerics
//!
//! Numerical pieces that know no model, shared by the physics models, the
//! PWARX pipeline and the back-ends:
//!
//! | module | concept |
//! |---|---|
//! | [`affine_rk4`] | classical RK4 of affine flows in closed form, one matrix map per regime and step length |
//! | [`box_least_squares`] | linear least squares, unconstrained and in a box (the bounded steps of Levenberg-Marquardt) |
//! | [`event_location`] | the step length at which a regime ends: regula falsi on the event's margin, safeguarded by bisection |
//! | [`budget`] | a run's [`Deadline`](budget::Deadline), the iteration [`Budget`](budget::Budget) of a loop |
//! | [`least_squares`] | the one Levenberg-Marquardt, on exact or finite-difference Jacobians, under a problem's constraints |
//! | [`nelder_mead`] | argmin's Nelder-Mead, iterate for iterate, with the second point of a step guessed and evaluated beside the first |

pub mod affine_rk4;
pub mod box_least_squares;
pub mod budget;
pub mod event_location;
pub mod least_squares;
pub mod nelder_mead;
