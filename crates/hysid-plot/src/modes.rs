//! The active mode over time: one horizontal lane per sequence (for example
//! the true and the identified mode sequence), coloured by mode.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::PlotError;
use crate::common::{
    Area, Chart, DESC_SIZE, FONT, HOLE_COLOUR, LEGEND_SIZE, LegendEntry, Swatch, TICK_SIZE,
    draw_err, mode_colour, mode_name, padded, render_figure, require_text, text_width,
    tick_formatter,
};

/// One mode sequence: the active mode of every sample, `None` where no mode
/// is active (a sample outside every region, or not classified).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModeSequence {
    /// Lane label, e.g. `"true"` or `"identified (cluster)"`.
    pub label: String,
    /// Mode index (0-based) of each sample.
    pub modes: Vec<Option<usize>>,
}

impl ModeSequence {
    /// A sequence from a label and modes.
    pub fn new(label: impl Into<String>, modes: Vec<Option<usize>>) -> Self {
        Self {
            label: label.into(),
            modes,
        }
    }
}

/// The active mode over time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModeFigure {
    /// Title above the figure.
    pub title: String,
    /// Time of each sample (finite and increasing), seconds or sample index.
    pub time: Vec<f64>,
    /// Label of the time axis with its unit.
    pub time_label: String,
    /// The sequences, drawn top to bottom.
    pub sequences: Vec<ModeSequence>,
    /// Names of the modes in the legend; missing names are `"mode k"`
    /// (1-based, as in the paper).
    pub mode_names: Vec<String>,
    /// When true and there are two or more sequences, a bottom lane marks the
    /// samples where the second sequence differs from the first (the
    /// identified from the true one, labels assumed already matched).
    pub mark_mismatch: bool,
}

const WIDTH: u32 = 1100;
const LANE_H: u32 = 56;
/// Mismatch colour: near black, unlike every mode colour.
const MISMATCH: RGBColor = RGBColor(40, 40, 40);
/// Room left of the lane labels for the vertical axis title.
const Y_TITLE_W: u32 = 34;
/// The vertical axis title: each lane is a sequence of modes.
pub const Y_TITLE: &str = "mode";

/// Runs `(start, end, value)` of equal consecutive values, `end` exclusive.
fn runs<T: PartialEq + Copy>(v: &[T]) -> Vec<(usize, usize, T)> {
    let mut out: Vec<(usize, usize, T)> = Vec::new();
    for (k, &m) in v.iter().enumerate() {
        match out.last_mut() {
            Some(r) if r.2 == m => r.1 = k + 1,
            _ => out.push((k, k + 1, m)),
        }
    }
    out
}

/// Sample `k` covers `[edge[k], edge[k + 1]]`, halfway to its neighbours.
fn sample_edges(t: &[f64]) -> Vec<f64> {
    let n = t.len();
    if n == 1 {
        return vec![t[0] - 0.5, t[0] + 0.5];
    }
    let mut e = Vec::with_capacity(n + 1);
    e.push(t[0] - 0.5 * (t[1] - t[0]));
    for k in 1..n {
        e.push(0.5 * (t[k - 1] + t[k]));
    }
    e.push(t[n - 1] + 0.5 * (t[n - 1] - t[n - 2]));
    e
}

/// Checks the texts, the time vector and the length of every sequence.
fn check_figure(fig: &ModeFigure) -> Result<(), PlotError> {
    require_text("the title", &fig.title)?;
    require_text("the time label", &fig.time_label)?;
    let n = fig.time.len();
    if n == 0 {
        return Err(PlotError::NoData("the time vector is empty".into()));
    }
    if fig.sequences.is_empty() {
        return Err(PlotError::NoData("no mode sequence".into()));
    }
    if fig.time.iter().any(|t| !t.is_finite()) || fig.time.windows(2).any(|w| w[1] <= w[0]) {
        return Err(PlotError::Invalid(
            "the time vector must be finite and strictly increasing".into(),
        ));
    }
    for s in &fig.sequences {
        if s.modes.len() != n {
            return Err(PlotError::LengthMismatch {
                what: format!("mode sequence '{}'", s.label),
                got: s.modes.len(),
                expected: n,
            });
        }
    }
    Ok(())
}

/// Where the second sequence differs from the first, when asked for and
/// there are two.
fn mismatch(fig: &ModeFigure) -> Option<Vec<bool>> {
    (fig.mark_mismatch && fig.sequences.len() >= 2).then(|| {
        fig.sequences[0]
            .modes
            .iter()
            .zip(&fig.sequences[1].modes)
            .map(|(a, b)| a != b)
            .collect()
    })
}

/// Legend: every mode that occurs, in order, then "no mode", then mismatch.
fn legend_entries(fig: &ModeFigure, mismatch: Option<&[bool]>) -> Vec<LegendEntry> {
    let mut used: Vec<usize> = fig
        .sequences
        .iter()
        .flat_map(|s| s.modes.iter().flatten().copied())
        .collect();
    used.sort_unstable();
    used.dedup();
    let mut entries: Vec<LegendEntry> = used
        .iter()
        .map(|&m| {
            LegendEntry::new(
                Swatch::Fill(mode_colour(m), 0.9),
                mode_name(&fig.mode_names, m),
            )
        })
        .collect();
    if fig
        .sequences
        .iter()
        .any(|s| s.modes.iter().any(Option::is_none))
    {
        entries.push(LegendEntry::new(
            Swatch::Fill(HOLE_COLOUR, 1.0),
            "no mode active",
        ));
    }
    if let Some(mm) = mismatch {
        let n = mm.len();
        let count = mm.iter().filter(|&&d| d).count();
        entries.push(LegendEntry::new(
            Swatch::Fill(MISMATCH, 0.9),
            format!(
                "'{}' differs from '{}' ({} of {} samples, {:.1} %)",
                fig.sequences[1].label,
                fig.sequences[0].label,
                count,
                n,
                100.0 * count as f64 / n as f64
            ),
        ));
    }
    entries
}

/// Width of the area left of the lanes: the longest lane label and the
/// vertical axis title.
fn lane_label_width(lanes: &[String]) -> u32 {
    lanes
        .iter()
        .map(|l| text_width(l, TICK_SIZE))
        .max()
        .unwrap_or(0)
        .max(40) as u32
        + 24
        + Y_TITLE_W
}

/// The vertical extent of lane `i` (from the top) of `n_lanes`: lane `i`
/// spans `[n_lanes - 1 - i, n_lanes - i]`, drawn with a gap to each side.
fn lane_span(n_lanes: usize, i: usize) -> (f64, f64) {
    let top = (n_lanes - i) as f64;
    (top - 0.85, top - 0.15)
}

/// The chart of `n_lanes` lanes over `x_range`, with the time axis and the
/// vertical axis title (the lanes have no ticks).
fn lanes_chart<'a, 'b>(
    area: &'a Area<'b>,
    fig: &ModeFigure,
    x_range: (f64, f64),
    n_lanes: usize,
    lane_label_w: u32,
) -> Result<Chart<'a, 'b>, PlotError> {
    let mut chart = ChartBuilder::on(area)
        .margin_right(25)
        .margin_left(16)
        .margin_top(8)
        .x_label_area_size(62)
        .y_label_area_size(lane_label_w)
        .build_cartesian_2d(x_range.0..x_range.1, 0.0..n_lanes as f64)
        .map_err(draw_err)?;
    let xf = tick_formatter(x_range.1 - x_range.0);
    let no_label = |_: &f64| String::new();
    chart
        .configure_mesh()
        .disable_y_mesh()
        .set_tick_mark_size(LabelAreaPosition::Left, 0)
        .x_label_formatter(&xf)
        .y_label_formatter(&no_label)
        .x_labels(10)
        .label_style((FONT, TICK_SIZE))
        .axis_desc_style((FONT, DESC_SIZE))
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215))
        .x_desc(fig.time_label.as_str())
        .y_desc(Y_TITLE)
        .draw()
        .map_err(draw_err)?;
    Ok(chart)
}

/// One lane per sequence, a rectangle per run of equal modes, then the
/// mismatch lane at the bottom.
fn draw_lanes(
    chart: &mut Chart<'_, '_>,
    fig: &ModeFigure,
    edges: &[f64],
    mismatch: Option<&[bool]>,
    n_lanes: usize,
) -> Result<(), PlotError> {
    for (i, s) in fig.sequences.iter().enumerate() {
        let (lo, hi) = lane_span(n_lanes, i);
        let rects = runs(&s.modes).into_iter().map(|(a, b, m)| {
            let colour = m.map_or(HOLE_COLOUR, mode_colour);
            Rectangle::new([(edges[a], lo), (edges[b], hi)], colour.filled())
        });
        chart.draw_series(rects).map_err(draw_err)?;
    }
    if let Some(mm) = mismatch {
        let (lo, hi) = lane_span(n_lanes, n_lanes - 1);
        let rects = runs(mm)
            .into_iter()
            .filter(|r| r.2)
            .map(|(a, b, _)| Rectangle::new([(edges[a], lo), (edges[b], hi)], MISMATCH.filled()));
        chart.draw_series(rects).map_err(draw_err)?;
    }
    Ok(())
}

/// Lane labels left of the plot, in pixel coordinates of `root`.
fn draw_lane_labels(
    root: &Area<'_>,
    chart: &Chart<'_, '_>,
    lanes: &[String],
    x_start: f64,
) -> Result<(), PlotError> {
    let font = (FONT, LEGEND_SIZE)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Right, VPos::Center));
    for (i, label) in lanes.iter().enumerate() {
        let (lo, hi) = lane_span(lanes.len(), i);
        let (px, py) = chart.backend_coord(&(x_start, 0.5 * (lo + hi)));
        root.draw(&Text::new(label.clone(), (px - 10, py), font.clone()))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// Renders a [`ModeFigure`] to an SVG string.
pub fn mode_sequence_svg(fig: &ModeFigure) -> Result<String, PlotError> {
    check_figure(fig)?;
    let mismatch = mismatch(fig);
    let entries = legend_entries(fig, mismatch.as_deref());
    let mut lanes: Vec<String> = fig.sequences.iter().map(|s| s.label.clone()).collect();
    if mismatch.is_some() {
        lanes.push("differs".to_string());
    }
    let n_lanes = lanes.len();
    let edges = sample_edges(&fig.time);
    let x_range = padded((edges[0], edges[fig.time.len()]), 0.0);
    let body_h = n_lanes as u32 * LANE_H + 90;
    render_figure(WIDTH, &fig.title, &entries, body_h, |root, plot_area| {
        let mut chart = lanes_chart(&plot_area, fig, x_range, n_lanes, lane_label_width(&lanes))?;
        draw_lanes(&mut chart, fig, &edges, mismatch.as_deref(), n_lanes)?;
        draw_lane_labels(root, &chart, &lanes, x_range.0)
    })
}

/// Draws the active mode over time into the file `path` (`.svg` or `.png`),
/// written atomically.
pub fn mode_sequence_plot(path: &Path, fig: &ModeFigure) -> Result<(), PlotError> {
    let svg = mode_sequence_svg(fig)?;
    crate::write_figure(path, &svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_merge_equal_neighbours() {
        let v = [Some(0), Some(0), None, Some(1), Some(1), Some(1)];
        assert_eq!(
            runs(&v),
            vec![(0, 2, Some(0)), (2, 3, None), (3, 6, Some(1))]
        );
        assert_eq!(sample_edges(&[0.0, 1.0, 3.0]), vec![-0.5, 0.5, 2.0, 4.0]);
    }
}
