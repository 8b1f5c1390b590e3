//! # hysid-core
//!
//! The plugin contract of hysid, a framework for identifying hybrid systems
//! from data. It knows no identification back-end; back-ends depend on it
//! and plug in through [`backend::Identifier`] and a [`backend::Registry`].
//! The data types, PWARX models and automata it refers to live in
//! `hysid-model`, the mechanical models in `hysid-mechanical`.
//!
//! | module | concept |
//! |---|---|
//! | [`model`] | the tagged [`model::Model`] of every kind, its JSON/TOML files |
//! | [`simulate`] | simulation, prediction and validation of any model |
//! | [`priors`] | gray-box prior knowledge |
//! | [`options`] | typed back-end options and `--set` |
//! | [`backend`] | the plugin contract and registry |
//! | [`search`] | the candidate settings of automatic selection |
//! | [`stages`] | the typed options of the stages after a PWARX fit (trim, refine) |

pub mod backend;
pub mod model;
pub mod options;
pub mod priors;
pub mod search;
pub mod simulate;
pub mod stages;

/// The types most programs need.
pub mod prelude {
    #[doc(no_inline)]
    pub use crate::backend::{Backend, Identifier, IdentifyError, Problem, Registry, RunContext};
    #[doc(no_inline)]
    pub use crate::model::Model;
    #[doc(no_inline)]
    pub use crate::priors::{PriorKind, Priors};
    #[doc(no_inline)]
    pub use hysid_model::data::{DataSelection, Dataset, Signal};
    #[doc(no_inline)]
    pub use hysid_model::geometry::Polyhedron;
    #[doc(no_inline)]
    pub use hysid_model::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel};
    #[doc(no_inline)]
    pub use hysid_model::regressors::RegressorSpec;
}
