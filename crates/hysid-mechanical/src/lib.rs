//! # hysid-mechanical
//!
//! Mass-spring-friction hybrid automata declared by their physical
//! parameters, contacts and stops (the mounting head of Juloski, Heemels,
//! Ferrari-Trecate 2003, section 2 and figure 3); the model file format is
//! documented in `docs/mechanical-models.md`. hysid runs such a model as
//! its gray-box form (`hysid_core::model::to_gray_box`); [`simulate`] is a
//! second, hand-written simulator of the same semantics, the reference
//! that form is tested against.

mod model;
pub mod simulate;

#[doc(no_inline)]
pub use hysid_model::model::PhysicalParameter;
pub use model::{
    Contact, Direction, ForceElement, Friction, InvalidMechanical, MAX_CONTACTS,
    MechanicalInitialState, MechanicalMode, MechanicalModeKind, MechanicalModel, Quantity,
    ResolvedContact, ResolvedForce, ResolvedMechanics, ResolvedStop, Stop,
};
