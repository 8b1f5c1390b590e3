//! The program's end-to-end tests, as one test binary: every module
//! runs the `hysid` binary or reads the repository.

mod architecture;
mod bad_input;
mod cli;
mod common;
mod compare;
mod determinism;
mod docs_commands;
mod edge_cases;
mod initial_states;
mod pick_and_place;
mod records;
mod results_table;
mod stops;
