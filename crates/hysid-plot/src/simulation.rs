//! Measured versus simulated output over time, with the input below: the
//! founding paper's Figs. 7, 8, 9, 12 and 14.

use std::path::Path;

use plotters::prelude::*;

use crate::PlotError;
use crate::common::{
    Area, Chart, DESC_SIZE, FONT, INPUT_COLOURS, LegendEntry, Swatch, TICK_SIZE, draw_err,
    finite_range, finite_runs, line_colour, padded, render_figure, require_text, tick_formatter,
    y_area_width,
};

/// A named series of values, one per time sample.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Series {
    /// Legend text (for example `"measured"`, `"cluster, c = 55 (FIT 80.1 %)"`).
    pub label: String,
    /// One value per sample; NaN or infinite values leave a gap.
    pub values: Vec<f64>,
}

impl Series {
    /// A series from a label and values.
    pub fn new(label: impl Into<String>, values: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            values,
        }
    }
}

/// Measured versus simulated output, with the input in a panel below.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SimulationFigure {
    /// Title above the figure.
    pub title: String,
    /// Time of each sample: seconds, or the sample index when the data has
    /// no sampling time (see [`time_axis`]).
    pub time: Vec<f64>,
    /// Label of the time axis with its unit, e.g. `"time t [s]"`.
    pub time_label: String,
    /// Label of the output axis with its unit, e.g. `"position y [mm]"`.
    pub output_label: String,
    /// The measured output (drawn in black).
    pub measured: Series,
    /// One or more simulated (or predicted) outputs, side by side.
    pub simulated: Vec<Series>,
    /// Label of the input axis with its unit, e.g. `"input u [-]"`.
    pub input_label: String,
    /// The inputs; empty draws no input panel.
    pub inputs: Vec<Series>,
    /// The warm-ups (not scored), shaded: `(from, to)` times, `to` where
    /// scoring starts; one per record of a dataset that joins several.
    pub warm_ups: Vec<(f64, f64)>,
    /// The sample at which each record begins, for data that join several
    /// records (empty, or `[0]`, for one).
    pub record_starts: Vec<usize>,
}

/// The time vector and axis label for `n` samples starting at row `first`:
/// seconds `(first + k) ts` when the sampling time `ts` is known, the sample
/// index otherwise.
pub fn time_axis(n: usize, ts: Option<f64>, first: usize) -> (Vec<f64>, String) {
    match ts {
        Some(ts) if ts.is_finite() && ts > 0.0 => (
            (0..n).map(|k| (first + k) as f64 * ts).collect(),
            "time t [s]".to_string(),
        ),
        _ => (
            (0..n).map(|k| (first + k) as f64).collect(),
            "sample k [-]".to_string(),
        ),
    }
}

const WIDTH: u32 = 1100;
const PANEL_OUTPUT_H: u32 = 440;
const PANEL_INPUT_H: u32 = 250;
const WARMUP_ALPHA: f64 = 0.18;
const WARMUP_COLOUR: RGBColor = RGBColor(120, 120, 120);

fn check_len(what: &str, got: usize, expected: usize) -> Result<(), PlotError> {
    if got != expected {
        return Err(PlotError::LengthMismatch {
            what: what.to_string(),
            got,
            expected,
        });
    }
    Ok(())
}

struct Panel<'a> {
    y_desc: &'a str,
    x_desc: Option<&'a str>,
    y_range: (f64, f64),
    lines: Vec<(&'a [f64], RGBColor, u32)>,
}

/// The warm-up shaded from `x0` to `w`, with a dashed line where scoring
/// starts.
fn draw_warm_up(
    chart: &mut Chart<'_, '_>,
    (x0, w): (f64, f64),
    (y0, y1): (f64, f64),
) -> Result<(), PlotError> {
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(x0, y0), (w, y1)],
            WARMUP_COLOUR.mix(WARMUP_ALPHA).filled(),
        )))
        .map_err(draw_err)?;
    chart
        .draw_series(std::iter::once(plotters::element::DashedPathElement::new(
            vec![(w, y0), (w, y1)],
            6,
            4,
            ShapeStyle::from(&WARMUP_COLOUR).stroke_width(2),
        )))
        .map_err(draw_err)?;
    Ok(())
}

/// One panel: axes, the warm-up shading, then the lines over time.
fn draw_panel(
    area: &Area<'_>,
    time: &[f64],
    x_range: (f64, f64),
    y_area: u32,
    warm_ups: &[(f64, f64)],
    panel: Panel<'_>,
) -> Result<(), PlotError> {
    let (y0, y1) = panel.y_range;
    let mut chart = ChartBuilder::on(area)
        .margin_right(25)
        .margin_left(16)
        .margin_top(8)
        .x_label_area_size(if panel.x_desc.is_some() { 58 } else { 30 })
        .y_label_area_size(y_area)
        .build_cartesian_2d(x_range.0..x_range.1, y0..y1)
        .map_err(draw_err)?;
    let xf = tick_formatter(x_range.1 - x_range.0);
    let yf = tick_formatter(y1 - y0);
    let mut mesh = chart.configure_mesh();
    mesh.x_label_formatter(&xf)
        .y_label_formatter(&yf)
        .x_labels(10)
        .y_labels(6)
        .label_style((FONT, TICK_SIZE))
        .axis_desc_style((FONT, DESC_SIZE))
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215))
        .y_desc(panel.y_desc);
    if let Some(d) = panel.x_desc {
        mesh.x_desc(d);
    }
    mesh.draw().map_err(draw_err)?;
    for &(from, to) in warm_ups {
        let from = from.max(x_range.0);
        if from.is_finite() && to.is_finite() && to > from {
            draw_warm_up(&mut chart, (from, to.min(x_range.1)), (y0, y1))?;
        }
    }
    for (values, colour, width) in panel.lines {
        for run in finite_runs(time, values) {
            chart
                .draw_series(LineSeries::new(
                    run,
                    ShapeStyle::from(&colour).stroke_width(width),
                ))
                .map_err(draw_err)?;
        }
    }
    Ok(())
}

/// Checks the texts and that every series has one value per time sample.
fn check_figure(fig: &SimulationFigure) -> Result<(), PlotError> {
    require_text("the title", &fig.title)?;
    require_text("the time label", &fig.time_label)?;
    require_text("the output label", &fig.output_label)?;
    let n = fig.time.len();
    if n == 0 {
        return Err(PlotError::NoData("the time vector is empty".into()));
    }
    check_len(
        &format!("measured output '{}'", fig.measured.label),
        fig.measured.values.len(),
        n,
    )?;
    for s in &fig.simulated {
        check_len(
            &format!("simulated output '{}'", s.label),
            s.values.len(),
            n,
        )?;
    }
    for s in &fig.inputs {
        check_len(&format!("input '{}'", s.label), s.values.len(), n)?;
    }
    if !fig.inputs.is_empty() {
        require_text("the input label", &fig.input_label)?;
    }
    Ok(())
}

/// The ranges of the axes: time, output and (with inputs) input.
struct Ranges {
    x: (f64, f64),
    y: (f64, f64),
    u: Option<(f64, f64)>,
}

/// The time range, and the output and input ranges padded by 5 % and 8 %.
fn ranges(fig: &SimulationFigure) -> Result<Ranges, PlotError> {
    let x = finite_range(&fig.time)
        .map(|r| if r.1 > r.0 { r } else { padded(r, 0.0) })
        .ok_or_else(|| PlotError::NoData("no finite time value".into()))?;
    let y = finite_range(
        fig.measured
            .values
            .iter()
            .chain(fig.simulated.iter().flat_map(|s| &s.values)),
    )
    .map(|r| padded(r, 0.05))
    .ok_or_else(|| PlotError::NoData("no finite output value".into()))?;
    let u = if fig.inputs.is_empty() {
        None
    } else {
        Some(
            finite_range(fig.inputs.iter().flat_map(|s| &s.values))
                .map(|r| padded(r, 0.08))
                .ok_or_else(|| PlotError::NoData("no finite input value".into()))?,
        )
    };
    Ok(Ranges { x, y, u })
}

fn input_colour(k: usize) -> RGBColor {
    INPUT_COLOURS[k % INPUT_COLOURS.len()]
}

/// Legend: the measured output, the simulated ones, the inputs, the warm-up.
fn legend_entries(fig: &SimulationFigure) -> Vec<LegendEntry> {
    let mut entries = vec![LegendEntry::new(
        Swatch::Line(BLACK, 3, false),
        fig.measured.label.clone(),
    )];
    for (k, s) in fig.simulated.iter().enumerate() {
        entries.push(LegendEntry::new(
            Swatch::Line(line_colour(k), 2, false),
            s.label.clone(),
        ));
    }
    for (k, s) in fig.inputs.iter().enumerate() {
        entries.push(LegendEntry::new(
            Swatch::Line(input_colour(k), 2, false),
            s.label.clone(),
        ));
    }
    if !fig.warm_ups.is_empty() {
        entries.push(LegendEntry::new(
            Swatch::Fill(WARMUP_COLOUR, WARMUP_ALPHA),
            "warm-up (not scored)",
        ));
    }
    entries
}

/// The output panel on `area`, with the time label under it when it is the
/// only panel.
fn draw_output_panel(
    area: &Area<'_>,
    fig: &SimulationFigure,
    r: &Ranges,
    y_area: u32,
    x_desc: Option<&str>,
) -> Result<(), PlotError> {
    let mut lines: Vec<(&[f64], RGBColor, u32)> = vec![(&fig.measured.values, BLACK, 3)];
    for (k, s) in fig.simulated.iter().enumerate() {
        lines.push((&s.values, line_colour(k), 2));
    }
    let panel = Panel {
        y_desc: &fig.output_label,
        x_desc,
        y_range: r.y,
        lines,
    };
    draw_panel(area, &fig.time, r.x, y_area, &fig.warm_ups, panel)
}

/// The input panel on `area`, with the time label under it.
fn draw_input_panel(
    area: &Area<'_>,
    fig: &SimulationFigure,
    r: &Ranges,
    u_range: (f64, f64),
    y_area: u32,
) -> Result<(), PlotError> {
    let lines = fig
        .inputs
        .iter()
        .enumerate()
        .map(|(k, s)| (s.values.as_slice(), input_colour(k), 2))
        .collect();
    let panel = Panel {
        y_desc: &fig.input_label,
        x_desc: Some(&fig.time_label),
        y_range: u_range,
        lines,
    };
    draw_panel(area, &fig.time, r.x, y_area, &fig.warm_ups, panel)
}

/// Renders a [`SimulationFigure`] to an SVG string.
pub fn simulation_svg(fig: &SimulationFigure) -> Result<String, PlotError> {
    check_figure(fig)?;
    let r = ranges(fig)?;
    let entries = legend_entries(fig);
    let panels_h = PANEL_OUTPUT_H + if r.u.is_some() { PANEL_INPUT_H } else { 0 };
    let y_area = y_area_width(r.y).max(r.u.map_or(0, y_area_width));
    render_figure(WIDTH, &fig.title, &entries, panels_h, |_, panels| {
        match r.u {
            None => draw_output_panel(&panels, fig, &r, y_area, Some(&fig.time_label)),
            Some(u_range) => {
                let (top, bottom) = panels.split_vertically(PANEL_OUTPUT_H);
                draw_output_panel(&top, fig, &r, y_area, None)?;
                draw_input_panel(&bottom, fig, &r, u_range, y_area)
            }
        }
    })
}

/// Draws measured versus simulated output over time (and the input below)
/// into the file `path` (`.svg` or `.png`), written atomically.
pub fn simulation_plot(path: &Path, fig: &SimulationFigure) -> Result<(), PlotError> {
    let svg = simulation_svg(fig)?;
    crate::write_figure(path, &svg)
}
