//! One module per subcommand.

pub mod compare;
pub mod identify;
pub mod methods;
pub mod simulate;
pub mod validate;
