//! The integration tests of this crate, as one test binary.

mod regions_alternation;
mod regions_methods;
mod regions_properties;
