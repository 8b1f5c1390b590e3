//! The integration tests of this crate, as one test binary.

/// The `--set` that fits the mounting head (the crate's copy of
/// models/pick-and-place/head.toml).
const HEAD_MODEL_SET: &str = concat!("model=", env!("CARGO_MANIFEST_DIR"), "/models/head.toml");

mod backend;
mod graybox;
mod initial;
mod jacobian;
mod recovery;
