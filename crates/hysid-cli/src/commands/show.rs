//! `hysid show`: a model in words and equations ([`hysid::describe`]).

use crate::error::Result;
use std::path::PathBuf;

/// Arguments of `hysid show`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Model file (.json, or .toml for hand-written models).
    pub model: PathBuf,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let model = super::load_model(&args.model)?;
    let text = hysid::describe::describe(&model);
    print!("{}: {text}", args.model.display());
    Ok(())
}
