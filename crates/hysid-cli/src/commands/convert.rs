//! `hysid convert`: a mechanical model written as the gray-box model of
//! the same physics ([`hysid_core::model::to_gray_box`]).

use crate::error::{CliError, Result};
use hysid_core::model::Model;
use std::path::PathBuf;

/// Arguments of `hysid convert`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Mechanical model file (.toml or .json).
    pub model: PathBuf,
    /// The gray-box model file to write: TOML for a .toml name, else JSON.
    #[arg(short = 'o', long = "out", value_name = "OUT.toml")]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    super::not_an_input("-o", &args.out, [args.model.as_path()])?;
    let gray = super::load_model(&args.model)?
        .to_gray_box()
        .map_err(|e| CliError::input(format!("{}: {e}", args.model.display())))?;
    hysid_io::save_model(&Model::GrayBox(gray), &args.out)?;
    eprintln!(
        "hysid: the gray-box form of {} -> {}",
        args.model.display(),
        args.out.display()
    );
    Ok(())
}
