//! A metric versus a parameter: FIT versus `c` for the clustering back-end,
//! FIT and mode count versus delta for the bounded-error back-end. One panel
//! per metric, stacked on a shared horizontal axis.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::PlotError;
use crate::common::{
    Area, Chart, DESC_SIZE, FONT, LegendEntry, Swatch, TICK_SIZE, draw_err, finite_range,
    finite_runs, line_colour, padded, render_figure, require_text, tick_formatter, y_area_width,
};

/// One curve: `y` against `x`, drawn as markers joined by lines (a NaN `y`,
/// for example a failed run, leaves a gap).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepSeries {
    /// Legend text; a label used in several panels gets the same colour.
    pub label: String,
    /// Parameter values.
    pub x: Vec<f64>,
    /// Metric values, same length as `x`.
    pub y: Vec<f64>,
}

impl SweepSeries {
    /// A series from a label and its points.
    pub fn new(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
        }
    }
}

/// One panel: one metric.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepPanel {
    /// Label of the metric axis with its unit, e.g. `"fit_sim [%]"` or
    /// `"modes [-]"`.
    pub y_label: String,
    /// The curves.
    pub series: Vec<SweepSeries>,
    /// Label only whole numbers on the vertical axis (counts such as the
    /// number of modes).
    pub integer_y: bool,
}

/// A metric (or several, one panel each) versus a parameter.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepFigure {
    /// Title above the figure.
    pub title: String,
    /// Label of the parameter axis with its unit, e.g. `"c [-]"`.
    pub x_label: String,
    /// The panels, top to bottom, sharing the parameter axis.
    pub panels: Vec<SweepPanel>,
    /// Logarithmic parameter axis (all `x` must then be positive).
    pub log_x: bool,
}

const WIDTH: u32 = 1000;
const PANEL_H: u32 = 330;

/// Tick positions (log10 of the value) and labels at 1, 2, 5 per decade
/// inside `range` (given in log10 units); only powers of ten when that
/// would give more than 12 ticks.
fn log_ticks(range: (f64, f64)) -> Vec<(f64, String)> {
    let (lo, hi) = range;
    let first = lo.floor() as i32;
    let last = hi.ceil() as i32;
    let collect = |mantissas: &[f64]| {
        let mut out = Vec::new();
        for d in first..=last {
            for &m in mantissas {
                let x = m * 10f64.powi(d);
                let v = x.log10();
                if v >= lo && v <= hi {
                    out.push((v, fmt_tick(x)));
                }
            }
        }
        out
    };
    let ticks = collect(&[1.0, 2.0, 5.0]);
    if ticks.len() > 12 {
        collect(&[1.0])
    } else {
        ticks
    }
}

fn fmt_tick(x: f64) -> String {
    if (1e-4..1e6).contains(&x) {
        let s = format!("{x:.6}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{x:.0e}")
    }
}

/// Checks the texts, the lengths of the series and, on a logarithmic axis,
/// that every parameter value is positive.
fn check_figure(fig: &SweepFigure) -> Result<(), PlotError> {
    require_text("the title", &fig.title)?;
    require_text("the parameter label", &fig.x_label)?;
    if fig.panels.is_empty() {
        return Err(PlotError::NoData("no panel".into()));
    }
    for p in &fig.panels {
        require_text("a panel's metric label", &p.y_label)?;
        for s in &p.series {
            if s.x.len() != s.y.len() {
                return Err(PlotError::LengthMismatch {
                    what: format!("y of series '{}'", s.label),
                    got: s.y.len(),
                    expected: s.x.len(),
                });
            }
            if fig.log_x && s.x.iter().any(|&x| x.is_nan() || x <= 0.0) {
                return Err(PlotError::Invalid(format!(
                    "series '{}' has a parameter value <= 0 (or NaN) on a logarithmic axis",
                    s.label
                )));
            }
        }
    }
    Ok(())
}

/// A parameter value in axis units (its log10 on a logarithmic axis).
fn axis_x(fig: &SweepFigure, x: f64) -> f64 {
    if fig.log_x { x.log10() } else { x }
}

/// The parameter range in axis units, padded by 4 %.
fn x_range(fig: &SweepFigure) -> Result<(f64, f64), PlotError> {
    let all_x: Vec<f64> = fig
        .panels
        .iter()
        .flat_map(|p| &p.series)
        .flat_map(|s| s.x.iter().map(|&x| axis_x(fig, x)))
        .collect();
    finite_range(&all_x)
        .map(|r| padded(r, 0.04))
        .ok_or_else(|| PlotError::NoData("no finite parameter value".into()))
}

/// The metric range of each panel, padded by 8 %.
fn y_ranges(fig: &SweepFigure) -> Result<Vec<(f64, f64)>, PlotError> {
    fig.panels
        .iter()
        .map(|p| {
            finite_range(p.series.iter().flat_map(|s| &s.y))
                .map(|r| padded(r, 0.08))
                .ok_or_else(|| {
                    PlotError::NoData(format!("no finite value in the panel '{}'", p.y_label))
                })
        })
        .collect()
}

/// The series labels in order of first appearance; a label's colour is
/// given by its place in this list.
fn series_labels(fig: &SweepFigure) -> Vec<&str> {
    let mut labels: Vec<&str> = Vec::new();
    for s in fig.panels.iter().flat_map(|p| &p.series) {
        if !labels.contains(&s.label.as_str()) {
            labels.push(&s.label);
        }
    }
    labels
}

fn colour_of(labels: &[&str], label: &str) -> RGBColor {
    line_colour(labels.iter().position(|l| *l == label).unwrap_or(0))
}

/// What every panel shares: the parameter axis and the series colours.
struct Shared<'f> {
    fig: &'f SweepFigure,
    x_range: (f64, f64),
    /// Width of the metric label area, the same in every panel.
    y_area: u32,
    labels: Vec<&'f str>,
    /// The hand-drawn ticks of a logarithmic axis (empty on a linear one).
    log_ticks: Vec<(f64, String)>,
}

/// The chart of one panel with its axes; the parameter label goes under the
/// last panel only.
fn panel_chart<'a, 'b>(
    area: &'a Area<'b>,
    sh: &Shared<'_>,
    p: &SweepPanel,
    (y0, y1): (f64, f64),
    last: bool,
) -> Result<Chart<'a, 'b>, PlotError> {
    let (x0, x1) = sh.x_range;
    let mut chart = ChartBuilder::on(area)
        .margin_right(25)
        .margin_left(16)
        .margin_top(10)
        .x_label_area_size(if last { 62 } else { 32 })
        .y_label_area_size(sh.y_area)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(draw_err)?;
    let lin_fmt = tick_formatter(x1 - x0);
    let blank = |_: &f64| String::new();
    // On a log axis plotters' labels would sit at round exponents; ours go
    // at 1-2-5 values per decade, drawn by `draw_log_ticks`.
    let x_fmt: &dyn Fn(&f64) -> String = if sh.fig.log_x { &blank } else { &lin_fmt };
    let y_lin = tick_formatter(y1 - y0);
    let y_int = |v: &f64| {
        if (v - v.round()).abs() < 1e-9 {
            format!("{}", v.round() as i64)
        } else {
            String::new()
        }
    };
    let y_fmt: &dyn Fn(&f64) -> String = if p.integer_y { &y_int } else { &y_lin };
    let mut mesh = chart.configure_mesh();
    if sh.fig.log_x {
        mesh.disable_x_mesh()
            .set_tick_mark_size(LabelAreaPosition::Bottom, 0);
    }
    mesh.x_label_formatter(x_fmt)
        .y_label_formatter(y_fmt)
        .x_labels(10)
        .y_labels(if p.integer_y {
            ((y1 - y0).ceil() as usize + 1).clamp(2, 12)
        } else {
            6
        })
        .label_style((FONT, TICK_SIZE))
        .axis_desc_style((FONT, DESC_SIZE))
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215))
        .y_desc(p.y_label.as_str());
    if last {
        mesh.x_desc(sh.fig.x_label.as_str());
    }
    mesh.draw().map_err(draw_err)?;
    Ok(chart)
}

/// The grid lines of a logarithmic axis in the chart, and its tick marks
/// and labels on `root` in pixel coordinates.
fn draw_log_ticks(
    root: &Area<'_>,
    chart: &mut Chart<'_, '_>,
    log_ticks: &[(f64, String)],
    (y0, y1): (f64, f64),
) -> Result<(), PlotError> {
    let grid = ShapeStyle::from(&RGBColor(215, 215, 215)).stroke_width(1);
    chart
        .draw_series(
            log_ticks
                .iter()
                .map(|(v, _)| PathElement::new(vec![(*v, y0), (*v, y1)], grid)),
        )
        .map_err(draw_err)?;
    let font = (FONT, TICK_SIZE)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Top));
    for (v, label) in log_ticks {
        let (px, py) = chart.backend_coord(&(*v, y0));
        root.draw(&PathElement::new(vec![(px, py), (px, py + 5)], BLACK))
            .map_err(draw_err)?;
        root.draw(&Text::new(label.clone(), (px, py + 9), font.clone()))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// Every series of the panel as markers joined by lines, sorted by the
/// parameter; a non-finite value breaks the line.
fn draw_curves(
    chart: &mut Chart<'_, '_>,
    sh: &Shared<'_>,
    p: &SweepPanel,
) -> Result<(), PlotError> {
    for s in &p.series {
        let colour = colour_of(&sh.labels, &s.label);
        let mut pts: Vec<(f64, f64)> =
            s.x.iter()
                .zip(&s.y)
                .map(|(&x, &y)| (axis_x(sh.fig, x), y))
                .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (xs, ys): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
        for run in finite_runs(&xs, &ys) {
            chart
                .draw_series(LineSeries::new(
                    run.clone(),
                    ShapeStyle::from(&colour).stroke_width(2),
                ))
                .map_err(draw_err)?;
            chart
                .draw_series(run.into_iter().map(|q| Circle::new(q, 5, colour.filled())))
                .map_err(draw_err)?;
        }
    }
    Ok(())
}

/// The panels top to bottom, each `PANEL_H` high (the last takes the rest).
fn draw_panels(
    root: &Area<'_>,
    panels_area: Area<'_>,
    sh: &Shared<'_>,
    y_ranges: &[(f64, f64)],
) -> Result<(), PlotError> {
    let mut rest = panels_area;
    for (k, (p, &y_range)) in sh.fig.panels.iter().zip(y_ranges).enumerate() {
        let last = k + 1 == sh.fig.panels.len();
        let (area, below) = if last {
            (rest.clone(), rest.clone())
        } else {
            rest.split_vertically(PANEL_H)
        };
        let mut chart = panel_chart(&area, sh, p, y_range, last)?;
        if sh.fig.log_x {
            draw_log_ticks(root, &mut chart, &sh.log_ticks, y_range)?;
        }
        draw_curves(&mut chart, sh, p)?;
        rest = below;
    }
    Ok(())
}

/// Renders a [`SweepFigure`] to an SVG string.
pub fn sweep_svg(fig: &SweepFigure) -> Result<String, PlotError> {
    check_figure(fig)?;
    let x_range = x_range(fig)?;
    let labels = series_labels(fig);
    let entries: Vec<LegendEntry> = labels
        .iter()
        .map(|l| LegendEntry::new(Swatch::Line(colour_of(&labels, l), 2, false), *l))
        .collect();
    let y_ranges = y_ranges(fig)?;
    let y_area = y_ranges
        .iter()
        .map(|r| y_area_width(*r))
        .max()
        .unwrap_or(70);
    let shared = Shared {
        fig,
        x_range,
        y_area,
        labels,
        log_ticks: if fig.log_x {
            log_ticks(x_range)
        } else {
            Vec::new()
        },
    };
    let panels_h = fig.panels.len() as u32 * PANEL_H + 28;
    render_figure(
        WIDTH,
        &fig.title,
        &entries,
        panels_h,
        |root, panels_area| draw_panels(root, panels_area, &shared, &y_ranges),
    )
}

/// Draws a metric versus a parameter into the file `path` (`.svg` or
/// `.png`), written atomically.
pub fn sweep_plot(path: &Path, fig: &SweepFigure) -> Result<(), PlotError> {
    let svg = sweep_svg(fig)?;
    crate::write_figure(path, &svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ticks_are_one_two_five() {
        let t = log_ticks((0.01f64.log10() - 0.05, 1.0f64.log10() + 0.05));
        let labels: Vec<&str> = t.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(labels, ["0.01", "0.02", "0.05", "0.1", "0.2", "0.5", "1"]);
        let wide = log_ticks((-6.0, 6.0));
        assert_eq!(wide.len(), 13);
        assert_eq!(wide[0].1, "1e-6");
    }
}
