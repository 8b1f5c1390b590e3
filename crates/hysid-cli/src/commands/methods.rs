//! `hysid methods [NAME]`: the registered back-ends, each with its summary,
//! option keys and the priors it honours; with a name, that back-end's
//! options in full (type, default, meaning), what `--auto` tries and what
//! the seed does. Lines are wrapped at [`WIDTH`] characters.

use crate::error::{CliError, Result};
use hysid_core::backend::{Backend, MethodDescription};

/// The longest line printed.
const WIDTH: usize = 120;

/// Arguments of `hysid methods`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// One back-end in full: its options with their types, defaults and
    /// meanings, what --auto tries, what the seed does.
    pub name: Option<String>,
    /// Print as JSON (name, summary, options, priors honoured, what --auto
    /// tries, whether the seed can change the model): the list, or NAME's
    /// object.
    #[arg(long)]
    pub json: bool,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let registry = hysid::registry();
    let one = match &args.name {
        Some(name) => Some(registry.get(name).ok_or_else(|| {
            CliError::input(format!(
                "methods {name}: unknown method (methods: {})",
                registry.names().join(", ")
            ))
        })?),
        None => None,
    };
    if args.json {
        let text = match one {
            Some(b) => serde_json::to_string_pretty(&MethodDescription::of(b)),
            None => serde_json::to_string_pretty(&registry.describe()),
        };
        println!("{}", text.expect("json"));
        return Ok(());
    }
    if let Some(b) = one {
        print!("{}", in_full(b));
        return Ok(());
    }
    for b in registry.iter() {
        print!("{}", in_brief(b));
    }
    println!("details of one: hysid methods NAME");
    println!(
        "model files: gray_box format {} (docs/gray-box-models.md)",
        hysid_graybox::FORMAT_VERSION
    );
    Ok(())
}

/// The name and summary, the option keys with their defaults, the priors.
fn in_brief(b: &dyn Backend) -> String {
    let options: Vec<String> = b
        .options()
        .iter()
        .map(|o| format!("{}={}", o.key, o.default))
        .collect();
    let mut s = wrapped(&format!("{:<10} ", b.name()), b.summary(), 11);
    s += &wrapped("    options: ", &list_or_none(&options), 13);
    s += &wrapped("    priors honoured: ", &priors(b), 21);
    s
}

/// Every option with its type, default and meaning, what `--auto` tries,
/// what the seed does, the priors.
fn in_full(b: &dyn Backend) -> String {
    let mut s = wrapped(&format!("{} ", b.name()), b.summary(), 4);
    for o in b.options() {
        s += &wrapped(
            "    ",
            &format!("{} ({}, default {})", o.key, o.ty, o.default),
            8,
        );
        s += &wrapped("        ", &o.doc, 8);
    }
    let auto = if b.search_doc().is_empty() {
        "its defaults only (no option to choose)"
    } else {
        b.search_doc()
    };
    s += &wrapped("    --auto tries: ", auto, 18);
    let seed = match (b.seeded(), b.seed_use()) {
        (false, _) => "does not change the model".to_string(),
        (true, "") => {
            "can change the model (--auto refits the choice from --refit-starts seeds)".to_string()
        }
        (true, when) => format!(
            "can change the model {when} (--auto then refits the choice from --refit-starts seeds)"
        ),
    };
    s += &wrapped("    seed: ", &seed, 10);
    s += &wrapped("    priors honoured: ", &priors(b), 21);
    s
}

fn priors(b: &dyn Backend) -> String {
    let names: Vec<String> = b.honours().iter().map(ToString::to_string).collect();
    list_or_none(&names)
}

fn list_or_none(items: &[String]) -> String {
    if items.is_empty() {
        "none".into()
    } else {
        items.join(", ")
    }
}

/// `lead` then `text` broken at spaces into lines of at most [`WIDTH`]
/// characters (a longer word stands alone), continuation lines indented by
/// `indent`; each line ends with a newline.
fn wrapped(lead: &str, text: &str, indent: usize) -> String {
    let mut out = String::new();
    let mut line = lead.to_string();
    let mut empty = true;
    for word in text.split(' ').filter(|w| !w.is_empty()) {
        if !empty && line.chars().count() + 1 + word.chars().count() > WIDTH {
            out += &line;
            out.push('\n');
            line = " ".repeat(indent);
            empty = true;
        }
        if !empty {
            line.push(' ');
        }
        line += word;
        empty = false;
    }
    out += &line;
    out.push('\n');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapping_keeps_words_and_the_width() {
        let s = wrapped("    ", &"word ".repeat(60), 8);
        assert!(s.lines().all(|l| l.chars().count() <= WIDTH), "{s}");
        assert!(
            s.lines().skip(1).all(|l| l.starts_with("        word")),
            "{s}"
        );
        assert_eq!(s.split_whitespace().count(), 60);
        let long = "x".repeat(WIDTH + 5);
        assert_eq!(
            wrapped("", &format!("a {long} b"), 2),
            format!("a\n  {long}\n  b\n")
        );
        // The lead is kept as it is; the first word follows it.
        assert_eq!(wrapped("arx   ", "one model", 6), "arx   one model\n");
    }
}
