//! # hysid-core
//!
//! The core of hysid, a framework for identifying hybrid systems from data.
//! It knows no identification back-end; back-ends depend on it and plug in
//! through [`backend::Identifier`] and a [`backend::Registry`].
//!
//! | module | concept |
//! |---|---|
//! | [`data`] | measured records: CSV/MAT reading, selection, standardisation |
//! | [`regressors`] | PWARX regressors and parameter order |
//! | [`geometry`] | polyhedra: regions, invariants, guard sets |
//! | [`model`] | PWARX models and hybrid automata, model files |
//! | [`priors`] | gray-box prior knowledge |
//! | [`estimation`] | mode parameters by least squares under priors (ties, fixed values, bounds) |
//! | [`options`] | typed back-end options and `--set` |
//! | [`backend`] | the plugin contract and registry |
//! | [`simulate`] | free-run simulation and one-step prediction |
//! | [`metrics`] | FIT, RMSE, coverage, mode matching |
//! | [`excitation`] | the founding paper's random step input |
//! | [`linalg`] | dense least squares (faer, private to this module) |
//! | [`atomic`] | atomic file output |

pub mod atomic;
pub mod backend;
pub mod data;
pub mod estimation;
pub mod excitation;
pub mod geometry;
pub mod linalg;
pub mod metrics;
pub mod model;
pub mod options;
pub mod priors;
pub mod regressors;
pub mod simulate;

/// The types most programs need.
pub mod prelude {
    #[doc(no_inline)]
    pub use crate::backend::{Backend, Identifier, IdentifyError, Problem, Registry, RunContext};
    #[doc(no_inline)]
    pub use crate::data::{DataSelection, Dataset, Signal};
    #[doc(no_inline)]
    pub use crate::geometry::Polyhedron;
    #[doc(no_inline)]
    pub use crate::model::{HybridAutomaton, Model, ModelInfo, PwarxMode, PwarxModel};
    #[doc(no_inline)]
    pub use crate::priors::{PriorKind, Priors};
    #[doc(no_inline)]
    pub use crate::regressors::RegressorSpec;
}
