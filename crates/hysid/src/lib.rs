//! # hysid
//!
//! The entry point of the library: the registry of every back-end
//! ([`registry`]), automatic selection of a back-end's options on
//! selection rows ([`select`]), and experiments that run several back-ends
//! on the same data and report them side by side ([`compare`]). The
//! `hysid` program and the Python package are front ends over it.

pub mod backends;
pub mod compare;
pub mod select;

pub use backends::{affine_reference, against_affine, registry};
