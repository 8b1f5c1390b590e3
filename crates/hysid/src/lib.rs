//! # hysid
//!
//! The entry point of the library. An [`Identify`] request names a
//! back-end, a record and what is known about the system, and returns the
//! model; automatic selection ([`select`]) chooses a back-end's options on
//! selection rows inside the identification rows; experiments
//! ([`compare`]) run several back-ends on the same data and report them
//! side by side. The [`registry`] holds every back-end hysid ships. The
//! `hysid` program and the Python package are front ends over these.
//!
//! ```
//! use hysid_testkit::{Noise, b1};
//!
//! let record = b1(300, 4.0, Noise::Uniform(0.05), 1).data;
//! let model = hysid::Identify::new("cluster", &record)
//!     .orders(1, 1)
//!     .modes(3)
//!     .run(&hysid::registry())?
//!     .model;
//! assert_eq!(model.mode_count(), 3);
//! # Ok::<(), hysid::identify::Error>(())
//! ```
//!
//! The other requests read the same way: prior knowledge
//! ([`hysid_core::priors::Priors`], as a prior file gives it), a
//! back-end's options as `--set` names them, options chosen on selection
//! rows ([`Identify::auto`]); the model is then scored by its free-run
//! simulation on rows the fit did not see.
//!
//! ```
//! use hysid_core::priors::Priors;
//! use hysid_testkit::{Noise, b1};
//!
//! let record = b1(600, 4.0, Noise::Uniform(0.05), 1).data;
//! let (fit_rows, test_rows) = (record.slice("0..450".parse()?)?, record.slice("450..".parse()?)?);
//! let priors = Priors::from_toml("max_modes = 3", "example")?;
//! let model = hysid::Identify::new("cluster", &fit_rows)
//!     .orders(1, 1)
//!     .priors(priors)
//!     .set("refine", "none")
//!     .auto()
//!     .seed(1)
//!     .run(&hysid::registry())?
//!     .model;
//! let (report, ..) = hysid_core::simulate::validate(&model, &test_rows, 10)?;
//! assert!(model.mode_count() <= 3 && report.fit_sim > 30.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod backends;
pub mod compare;
pub mod describe;
pub mod identify;
pub mod select;

pub use backends::{affine_reference, against_affine, registry};
/// The figures (`hysid-plot`), for the front ends.
pub use hysid_plot as plot;
pub use identify::{Identified, Identify};
