//! # hysid-mechanical
//!
//! Mass-spring-friction hybrid automata declared by their physical
//! parameters, contacts and stops (the mounting head of Juloski, Heemels,
//! Ferrari-Trecate 2003, section 2 and figure 3), and their event-aware
//! simulator. The `physical` back-end fits such models; the model file
//! format is documented in `docs/mechanical-models.md`.

mod model;
pub mod simulate;

#[doc(no_inline)]
pub use hysid_model::model::PhysicalParameter;
pub use model::{
    Contact, Direction, ForceElement, Friction, InvalidMechanical, MAX_CONTACTS,
    MechanicalInitialState, MechanicalMode, MechanicalModeKind, MechanicalModel, Quantity,
    ResolvedContact, ResolvedForce, ResolvedMechanics, ResolvedStop, Stop,
};
