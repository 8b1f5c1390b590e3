//! Choosing delta: identification over a list of bounds.
