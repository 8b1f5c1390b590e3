//! The integration tests of this crate, as one test binary.

mod backend;
mod graybox;
mod initial;
mod recovery;
