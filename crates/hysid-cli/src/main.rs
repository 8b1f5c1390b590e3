//! `hysid`: identify hybrid systems from data.
//!
//! The command-line contract is `docs/cli.md` (with the file formats of
//! `docs/file-formats.md`). Exit codes: 0 success, 2 bad input or usage (one-line
//! message on stderr), 1 anything else. A command never leaves a partial
//! output file behind: every file is written atomically.

mod affine;
mod commands;
mod error;
mod progress;
mod selection;

use clap::{Parser, Subcommand};
use error::{CliError, Result};

/// Identify hybrid systems (piecewise ARX models, hybrid automata) from data.
#[derive(Parser, Debug)]
#[command(name = "hysid", version, about = "Identify hybrid systems (piecewise ARX models, hybrid automata) from data.", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// List the back-ends with their options and the priors they honour (one in full: NAME).
    Methods(commands::methods::Args),
    /// Identify a model from data with one back-end.
    Identify(commands::identify::Args),
    /// Score a model on data: free-run simulation and one-step prediction.
    Validate(commands::validate::Args),
    /// Simulate a model on measured inputs or on a generated excitation.
    Simulate(commands::simulate::Args),
    /// Run several back-ends on one experiment and report them side by side.
    Compare(commands::compare::Args),
    /// Sweep one back-end over a grid of option values, scored by simulation FIT on the selection rows.
    Sweep(commands::sweep::Args),
    /// Write a mechanical model as the gray-box model of the same physics.
    Convert(commands::convert::Args),
    /// Print a model: its equations, regions or parameters, and how it was identified.
    Show(commands::show::Args),
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
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            // No command: the help, with its list of commands, on standard
            // error; a usage error all the same.
            let _ = e.print();
            std::process::exit(2);
        }
        Err(e) => {
            // Usage errors: one line, exit code 2. Clap's first paragraph
            // (up to the blank line before its usage text) is the message;
            // its lines are joined, so that a list of missing arguments is
            // named too.
            let text = e.render().to_string();
            let message: Vec<&str> = text
                .lines()
                .take_while(|l| !l.trim().is_empty())
                .map(str::trim)
                .collect();
            let message = message.join(" ");
            let message = message.trim_start_matches("error: ");
            let message = if message.is_empty() {
                "usage error"
            } else {
                message
            };
            eprintln!("hysid: error: {message}{} (see --help)", suggestion(&e));
            std::process::exit(2);
        }
    };
    // A panic is a bug, never an answer: it becomes one line and exit code 1
    // (not Rust's 101). Unwinding drops the temporary file of an atomic
    // write, so no partial output file is left either.
    let result = guarded(move || dispatch(cli.command));
    if let Err(e) = result {
        eprintln!("hysid: error: {}", e.one_line());
        std::process::exit(e.exit_code());
    }
}

/// Clap's suggestion for a mistyped argument, subcommand or value
/// (`--priors`: `--prior`), which its message gives on a later line.
fn suggestion(e: &clap::Error) -> String {
    use clap::error::{ContextKind, ContextValue};
    let kinds = [
        ContextKind::SuggestedArg,
        ContextKind::SuggestedSubcommand,
        ContextKind::SuggestedValue,
    ];
    let found = kinds.iter().find_map(|&k| match e.get(k)? {
        ContextValue::String(s) => Some(s.clone()),
        ContextValue::Strings(v) => v.first().cloned(),
        _ => None,
    });
    found.map_or(String::new(), |s| format!("; a similar one exists: '{s}'"))
}

fn dispatch(command: Command) -> Result<()> {
    // Internal test hook (tests/cli.rs): a deliberate panic, to check the
    // guard below end to end. Not a user option; documented in docs/errors.md.
    if std::env::var_os("HYSID_TEST_PANIC").is_some_and(|v| v == "1") {
        panic!("HYSID_TEST_PANIC=1: deliberate panic\n(second line)");
    }
    match command {
        Command::Methods(a) => commands::methods::run(a),
        Command::Identify(a) => commands::identify::run(a),
        Command::Validate(a) => commands::validate::run(a),
        Command::Simulate(a) => commands::simulate::run(a),
        Command::Compare(a) => commands::compare::run(a),
        Command::Sweep(a) => commands::sweep::run(a),
        Command::Convert(a) => commands::convert::run(a),
        Command::Show(a) => commands::show::run(a),
    }
}

/// Runs `f`; a panic (on this thread, or on a rayon worker, which rayon
/// passes on to the caller) becomes `CliError::failure("internal error:
/// <message> at <file:line> (please report)")`, except the one `println!`
/// raises when the reader of standard output has gone (`hysid methods |
/// head`): that ends the command quietly, as it ends other Unix tools.
fn guarded(f: impl FnOnce() -> Result<()>) -> Result<()> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        let message = if let Some(s) = payload.downcast_ref::<&str>() {
            (*s).to_string()
        } else if let Some(s) = payload.downcast_ref::<String>() {
            s.clone()
        } else {
            "a panic without a message".to_string()
        };
        if is_broken_pipe(&message) {
            return Ok(());
        }
        let at = LAST_PANIC_LOCATION
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
            .map(|l| format!(" at {l}"))
            .unwrap_or_default();
        Err(CliError::failure(format!(
            "internal error: {message}{at} (please report)"
        )))
    })
}

/// The panic hook. The MAT reader of `hysid-core` catches panics of the
/// third-party `matrw` parser on malformed files and returns an error naming
/// the file; panics raised while that parser runs are not printed at all.
/// Any other panic is a bug that [`guarded`] reports on one line: the hook
/// only records where it happened. With `RUST_BACKTRACE` set (not `0`), the default report
/// (message, location, backtrace) is printed too, for debugging.
fn quiet_guarded_panics() {
    let default = std::panic::take_hook();
    let verbose = std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0");
    std::panic::set_hook(Box::new(move |info| {
        let message = (info.payload().downcast_ref::<String>().map(String::as_str))
            .or_else(|| info.payload().downcast_ref::<&str>().copied());
        if hysid_io::inside_guarded_parser() || message.is_some_and(is_broken_pipe) {
            return;
        }
        if let Some(l) = info.location() {
            let at = format!("{}:{}:{}", l.file(), l.line(), l.column());
            *LAST_PANIC_LOCATION
                .lock()
                .unwrap_or_else(|e| e.into_inner()) = Some(at);
        }
        if verbose {
            default(info);
        }
    }));
}

/// Whether a panic's message is `println!`'s when the reader of standard
/// output has gone: not a bug, the end of the command ([`guarded`]).
fn is_broken_pipe(message: &str) -> bool {
    message.starts_with("failed printing to stdout") && message.contains("Broken pipe")
}

/// The location of the last unguarded panic on any thread (a rayon worker's
/// panic is re-raised on the calling thread with the worker's payload).
static LAST_PANIC_LOCATION: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);
