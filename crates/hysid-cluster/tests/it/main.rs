//! The integration tests of this crate, as one test binary.

mod priors;
mod properties;
mod reference;
mod steps;
