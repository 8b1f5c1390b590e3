//! `hysid methods`: the registered back-ends, one per line, with their
//! options, and the version of the gray-box model format this build reads.

use crate::error::Result;

/// Arguments of `hysid methods`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print the list as JSON (name, summary, options, priors honoured,
    /// what --auto tries, whether the seed can change the model).
    #[arg(long)]
    pub json: bool,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let registry = hysid::registry();
    if args.json {
        let list = registry.describe();
        println!("{}", serde_json::to_string_pretty(&list).expect("json"));
        return Ok(());
    }
    for b in registry.iter() {
        let opts: Vec<String> = b
            .options()
            .iter()
            .map(|o| format!("{}={}", o.key, o.default))
            .collect();
        println!(
            "{:<10} {}  [options: {}]",
            b.name(),
            b.summary(),
            if opts.is_empty() {
                "none".into()
            } else {
                opts.join(" ")
            }
        );
        for o in b.options() {
            println!(
                "    {:<14} {:<18} default {:<10} {}",
                o.key, o.ty, o.default, o.doc
            );
        }
        println!(
            "    --auto tries: {}",
            if b.search_doc().is_empty() {
                "its defaults only (no option to choose)"
            } else {
                b.search_doc()
            }
        );
        println!(
            "    seed: {}",
            if b.seeded() {
                "can change the model (--auto refits the choice from --refit-starts seeds)"
            } else {
                "does not change the model"
            }
        );
        let priors: Vec<String> = b.honours().iter().map(ToString::to_string).collect();
        println!(
            "    priors honoured: {}",
            if priors.is_empty() {
                "none".into()
            } else {
                priors.join(", ")
            }
        );
    }
    println!(
        "model files: gray_box format {} (docs/gray-box-models.md)",
        hysid_graybox::FORMAT_VERSION
    );
    Ok(())
}
