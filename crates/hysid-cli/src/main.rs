//! `hysid`: identify hybrid systems from data.
//!
//! The command-line contract is `shared/spec/interface.md` (mirrored in
//! `docs/cli.md`). Exit codes: 0 success, 2 bad input or usage (one-line
//! message on stderr), 1 anything else. A command never leaves a partial
//! output file behind: every file is written atomically.

mod commands;
mod error;
mod progress;
mod selection;

use clap::{Parser, Subcommand};
use error::CliError;

/// Identify hybrid systems (piecewise ARX models, hybrid automata) from data.
#[derive(Parser, Debug)]
#[command(name = "hysid", version, about = "Identify hybrid systems (piecewise ARX models, hybrid automata) from data.", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// List the registered back-ends with their options and the priors they honour.
    Methods(commands::methods::Args),
    /// Identify a model from data with one back-end.
    Identify(commands::identify::Args),
    /// Score a model on data: free-run simulation and one-step prediction.
    Validate(commands::validate::Args),
    /// Simulate a model on measured inputs or on a generated excitation.
    Simulate(commands::simulate::Args),
    /// Run several back-ends on one experiment and report them side by side.
    Compare(commands::compare::Args),
    /// Sweep one back-end over a grid of option values, scored by validation simulation FIT.
    Sweep(commands::sweep::Args),
}

fn main() {
    quiet_guarded_panics();
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) if !e.use_stderr() => {
            // --help and --version.
            let _ = e.print();
            std::process::exit(0);
        }
        Err(e) => {
            // Usage errors: one line, exit code 2.
            let text = e.render().to_string();
            let first = text
                .lines()
                .next()
                .unwrap_or("usage error")
                .trim_start_matches("error: ");
            eprintln!("hysid: error: {first} (see --help)");
            std::process::exit(2);
        }
    };
    let result = match cli.command {
        Command::Methods(a) => commands::methods::run(a),
        Command::Identify(a) => commands::identify::run(a),
        Command::Validate(a) => commands::validate::run(a),
        Command::Simulate(a) => commands::simulate::run(a),
        Command::Compare(a) => commands::compare::run(a),
        Command::Sweep(a) => commands::sweep::run(a),
    };
    if let Err(e) = result {
        eprintln!("hysid: error: {}", e.one_line());
        std::process::exit(e.exit_code());
    }
}

/// The MAT reader of `hysid-core` catches panics of the third-party `matrw`
/// parser on malformed files and returns an error naming the file; the
/// default hook would still print the panic (several lines) before that
/// one-line message. Panics raised while that parser runs are therefore not
/// printed; any other panic is reported by the default hook as before.
fn quiet_guarded_panics() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !hysid_core::data::inside_guarded_parser() {
            default(info);
        }
    }));
}

/// Keeps `CliError` in use from every module.
pub(crate) type Result<T> = std::result::Result<T, CliError>;
