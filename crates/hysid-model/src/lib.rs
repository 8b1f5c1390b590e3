//! # hysid-model
//!
//! The model layer of hysid, shared by every other crate: what a record is,
//! what a PWARX model and a hybrid automaton are, how they simulate, and how
//! they are scored. It knows no back-end, no file reader and no solver.
//!
//! | module | concept |
//! |---|---|
//! | [`data`] | measured records, selection rules, standardisation |
//! | [`regressors`] | PWARX regressors and parameter order |
//! | [`geometry`] | polyhedra: regions, invariants, guard sets |
//! | [`model`] | PWARX models, hybrid automata, stops, provenance |
//! | [`simulate`] | free-run simulation and one-step prediction of those kinds |
//! | [`metrics`] | FIT, RMSE, mode matching |
//! | [`statistics`] | medians and the robust scale of a sample |
//! | [`excitation`] | the founding paper's random step input |

pub mod data;
pub mod excitation;
pub mod geometry;
pub mod metrics;
pub mod model;
pub mod regressors;
pub mod simulate;
pub mod statistics;
