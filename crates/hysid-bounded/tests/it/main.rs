//! The integration tests of this crate, as one test binary.

mod b1;
mod common;
mod priors;
mod properties;
