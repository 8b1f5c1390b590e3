//! The integration tests of this crate, as one test binary.

mod ball;
mod delay;
mod examples;
mod head;
mod initial;
mod limits;
mod real_systems;
mod sensitivities;
