//! Figures for hysid: the pictures a control engineer looks at when
//! comparing identified hybrid models.
//!
//! Every figure is plain data in, one SVG (or PNG) file out:
//!
//! | function | figure | founding paper |
//! |---|---|---|
//! | [`simulation_plot`] | measured versus simulated output over time, the input below | Figs. 7, 8, 9, 12, 14 |
//! | [`mode_sequence_plot`] | active mode over time, one lane per sequence (true, identified) | – |
//! | [`regions_plot`] | classified regressors in a plane of two regressor coordinates, with the 2-D slices of the mode regions and the holes between them | Figs. 6, 11 |
//! | [`sweep_plot`] | a metric versus a parameter (FIT versus `c`; FIT and mode count versus delta), one panel per metric | – |
//!
//! (Juloski, Heemels, Ferrari-Trecate, "Identification of an experimental
//! hybrid system", IFAC ADHS 2003.)
//!
//! Each `*_plot` function renders the SVG into a `String` first (the
//! matching `*_svg` function returns it) and then writes it atomically with
//! [`hysid_io::write`], rasterised by [`svg_to_png`] when the path ends in
//! `.png`. Text is SVG `<text>` in the generic
//! `sans-serif` family, so no system font is needed to render. The output is
//! deterministic: the same figure gives the same bytes. Empty or non-finite
//! data is an error ([`PlotError`]) or is skipped (NaN samples break a line),
//! never a panic.

mod common;
mod from_core;
mod modes;
mod png;
mod regions;
mod simulation;
pub mod slice;
mod sweep;

use std::path::{Path, PathBuf};

pub use from_core::{column_means, lagged_name};
pub use modes::{ModeFigure, ModeSequence, mode_sequence_plot, mode_sequence_svg};
pub use png::{FigureFormat, PNG_SCALE, svg_to_png};
pub use regions::{RegionFigure, regions_plot, regions_svg};
pub use simulation::{Series, SimulationFigure, simulation_plot, simulation_svg, time_axis};
pub use slice::{Bounds, Slice2, slice_polyhedron};
pub use sweep::{SweepFigure, SweepPanel, SweepSeries, sweep_plot, sweep_svg};

/// Why a figure could not be produced.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The figure has nothing finite to draw.
    #[error("nothing to plot: {0}")]
    NoData(String),
    /// Two vectors that must have the same length do not.
    #[error("{what} has {got} values but {expected} were expected")]
    LengthMismatch {
        /// Which vector.
        what: String,
        /// Its length.
        got: usize,
        /// The length it must have.
        expected: usize,
    },
    /// Any other inconsistency of the figure description.
    #[error("invalid figure: {0}")]
    Invalid(String),
    /// A region could not be sliced.
    #[error("region {mode}: {source}")]
    Slice {
        /// Index of the region.
        mode: usize,
        /// The slicing error.
        source: slice::SliceError,
    },
    /// An output file whose extension is neither `.svg` nor `.png`.
    #[error("{}: a figure is written as .svg or .png", path.display())]
    Format {
        /// The file.
        path: std::path::PathBuf,
    },
    /// The drawing library failed.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// A PNG figure from a build without the `png` feature.
    #[error(
        "PNG figures need hysid built with the png feature (cargo install --path crates/hysid-cli --features png); SVG figures need nothing"
    )]
    PngNotBuilt,
    /// The file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The target path.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Writes the figure `svg` to `path` atomically, in the format its extension
/// names: `.svg` as it is, `.png` rasterised ([`svg_to_png`]).
fn write_figure(path: &Path, svg: &str) -> Result<(), PlotError> {
    let bytes = match FigureFormat::of_path(path)? {
        FigureFormat::Svg => svg.as_bytes().to_vec(),
        FigureFormat::Png => svg_to_png(svg)?,
    };
    hysid_io::write(path, &bytes).map_err(|source| PlotError::Io {
        path: path.to_path_buf(),
        source,
    })
}
