//! Pieces shared by the figures: colours, ranges, tick labels, the legend,
//! the titled canvas every figure is drawn on.

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::PlotError;

/// A drawing area of the SVG backend.
pub type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;

/// A chart with two real axes, the kind every figure draws on.
pub type Chart<'a, 'b> =
    ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Font family of every text element (generic, so no system font is needed).
pub const FONT: &str = "sans-serif";
/// Title size (plotters units; the SVG font size is this / 1.24).
pub const TITLE_SIZE: u32 = 26;
/// Axis description size.
pub const DESC_SIZE: u32 = 19;
/// Tick label size.
pub const TICK_SIZE: u32 = 16;
/// Legend text size.
pub const LEGEND_SIZE: u32 = 17;

/// Height of the title strip in pixels.
pub const TITLE_H: u32 = 46;

/// Line colours (Okabe–Ito, colour-blind safe, without yellow).
pub const LINE_COLOURS: [RGBColor; 6] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
];

/// Input colours (dark, distinct from the line colours).
pub const INPUT_COLOURS: [RGBColor; 4] = [
    RGBColor(60, 60, 60),
    RGBColor(140, 86, 75),
    RGBColor(120, 120, 170),
    RGBColor(150, 150, 40),
];

/// Mode colours (Tableau 10).
pub const MODE_COLOURS: [RGBColor; 10] = [
    RGBColor(78, 121, 167),
    RGBColor(242, 142, 43),
    RGBColor(225, 87, 89),
    RGBColor(118, 183, 178),
    RGBColor(89, 161, 79),
    RGBColor(237, 201, 72),
    RGBColor(176, 122, 161),
    RGBColor(255, 157, 167),
    RGBColor(156, 117, 95),
    RGBColor(186, 176, 172),
];

/// Colour of "no mode" / holes.
pub const HOLE_COLOUR: RGBColor = RGBColor(200, 200, 200);

/// Line colour `k` (cycling).
pub fn line_colour(k: usize) -> RGBColor {
    LINE_COLOURS[k % LINE_COLOURS.len()]
}

/// Mode colour `k` (cycling).
pub fn mode_colour(k: usize) -> RGBColor {
    MODE_COLOURS[k % MODE_COLOURS.len()]
}

/// Name of mode `m` (0-based): `names[m]`, or `"mode m+1"`
/// ([`hysid_model::model::mode_name`]) when `names` has no entry for it.
pub fn mode_name(names: &[String], m: usize) -> String {
    hysid_model::model::mode_name(names.get(m).map(String::as_str), m)
}

/// Maps any plotters error to [`PlotError::Draw`].
pub fn draw_err<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Draw(e.to_string())
}

/// Smallest and largest finite value, or `None`.
pub fn finite_range<'a>(values: impl IntoIterator<Item = &'a f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, &v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// Widens `[lo, hi]` by `frac` of its span on both sides; a zero span
/// becomes a unit-sized (or 10 %-sized) interval around the value.
pub fn padded((lo, hi): (f64, f64), frac: f64) -> (f64, f64) {
    let span = hi - lo;
    if span > 0.0 && span.is_finite() {
        (lo - frac * span, hi + frac * span)
    } else {
        let w = if lo.abs() > 0.0 { 0.1 * lo.abs() } else { 1.0 };
        (lo - w, hi + w)
    }
}

/// A tick-label formatter with just enough decimals for a range of `span`.
pub fn tick_formatter(span: f64) -> impl Fn(&f64) -> String {
    let step = if span > 0.0 && span.is_finite() {
        span / 8.0
    } else {
        1.0
    };
    let base = (-step.log10().floor()).clamp(0.0, 8.0) as usize;
    let tol = 1e-6 * step;
    move |v: &f64| {
        // Up to two more decimals when a tick such as 0.25 needs them.
        let decimals = (base..=base + 2)
            .find(|&d| {
                let p = 10f64.powi(d as i32);
                ((v * p).round() / p - v).abs() <= tol
            })
            .unwrap_or(base);
        let s = format!("{:.*}", decimals, v);
        // Avoid "-0" / "-0.00".
        if s.trim_start_matches('-')
            .chars()
            .all(|c| c == '0' || c == '.')
        {
            s.trim_start_matches('-').to_string()
        } else {
            s
        }
    }
}

/// Width of the y label area for values in `range`.
pub fn y_area_width(range: (f64, f64)) -> u32 {
    let f = tick_formatter(range.1 - range.0);
    let w = text_width(&f(&range.0), TICK_SIZE).max(text_width(&f(&range.1), TICK_SIZE));
    (w + 48).max(70) as u32
}

/// Splits `(x, y)` pairs into runs of finite points (a NaN breaks a line).
pub fn finite_runs(x: &[f64], y: &[f64]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut cur = Vec::new();
    for (&a, &b) in x.iter().zip(y) {
        if a.is_finite() && b.is_finite() {
            cur.push((a, b));
        } else if !cur.is_empty() {
            runs.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        runs.push(cur);
    }
    runs
}

/// Estimated width in pixels of `text` at plotters size `size` (the SVG
/// font size is `size / 1.24`; an average sans-serif glyph is ~0.55 em).
pub fn text_width(text: &str, size: u32) -> i32 {
    (text.chars().count() as f64 * 0.56 * size as f64 / 1.24).ceil() as i32
}

/// The title's font size: [`TITLE_SIZE`], or smaller (down to
/// [`TICK_SIZE`]) so that `title` fits a figure `width` pixels wide.
pub fn title_size(title: &str, width: u32) -> u32 {
    let room = width as i32 - 40;
    (TICK_SIZE..=TITLE_SIZE)
        .rev()
        .find(|&s| text_width(title, s) <= room)
        .unwrap_or(TICK_SIZE)
}

/// `text` broken at spaces into lines of at most `width` pixels at `size`
/// (a word longer than a line stands alone on its line).
pub fn wrap(text: &str, size: u32, width: u32) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split(' ') {
        let candidate = if line.is_empty() {
            word.to_string()
        } else {
            format!("{line} {word}")
        };
        if !line.is_empty() && text_width(&candidate, size) > width as i32 {
            lines.push(std::mem::replace(&mut line, word.to_string()));
        } else {
            line = candidate;
        }
    }
    lines.push(line);
    lines
}

/// What a legend entry shows beside its label.
#[derive(Debug, Clone, Copy)]
pub enum Swatch {
    /// A line, solid or dashed.
    Line(RGBColor, u32, bool),
    /// A filled circle.
    Marker(RGBColor),
    /// A filled square (a region or band colour), with opacity.
    Fill(RGBColor, f64),
}

/// One legend entry.
#[derive(Debug, Clone)]
pub struct LegendEntry {
    /// Swatch.
    pub swatch: Swatch,
    /// Text.
    pub label: String,
}

impl LegendEntry {
    /// A new entry.
    pub fn new(swatch: Swatch, label: impl Into<String>) -> Self {
        Self {
            swatch,
            label: label.into(),
        }
    }
}

const SWATCH_W: i32 = 30;
const ROW_H: i32 = 24;
const GAP: i32 = 22;

fn entry_width(e: &LegendEntry) -> i32 {
    SWATCH_W + 8 + text_width(&e.label, LEGEND_SIZE)
}

/// Splits the entries into rows that fit in `width` pixels.
fn legend_rows(entries: &[LegendEntry], width: i32) -> Vec<Vec<&LegendEntry>> {
    let mut rows: Vec<Vec<&LegendEntry>> = Vec::new();
    let mut used = 0;
    for e in entries {
        let w = entry_width(e);
        match rows.last_mut() {
            Some(row) if used + GAP + w <= width => {
                row.push(e);
                used += GAP + w;
            }
            _ => {
                rows.push(vec![e]);
                used = w;
            }
        }
    }
    rows
}

/// Height in pixels of the legend strip for `entries` in `width` pixels.
pub fn legend_height(entries: &[LegendEntry], width: u32) -> u32 {
    if entries.is_empty() {
        return 0;
    }
    (legend_rows(entries, width as i32 - 20).len() as i32 * ROW_H + 8) as u32
}

/// Draws the legend as centred rows across `area` (from
/// [`legend_height`]), with a light frame.
pub fn draw_legend(area: &Area<'_>, entries: &[LegendEntry]) -> Result<(), PlotError> {
    if entries.is_empty() {
        return Ok(());
    }
    let (w, _) = area.dim_in_pixel();
    let rows = legend_rows(entries, w as i32 - 20);
    let font = (FONT, LEGEND_SIZE)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (r, row) in rows.iter().enumerate() {
        let total: i32 =
            row.iter().map(|e| entry_width(e)).sum::<i32>() + GAP * (row.len() as i32 - 1);
        let mut x = (w as i32 - total) / 2;
        let y = 4 + r as i32 * ROW_H + ROW_H / 2;
        for e in row {
            match e.swatch {
                Swatch::Line(c, width, dashed) => {
                    let style = ShapeStyle::from(&c).stroke_width(width);
                    if dashed {
                        area.draw(&plotters::element::DashedPathElement::new(
                            vec![(x, y), (x + SWATCH_W, y)],
                            7,
                            4,
                            style,
                        ))
                        .map_err(draw_err)?;
                    } else {
                        area.draw(&PathElement::new(vec![(x, y), (x + SWATCH_W, y)], style))
                            .map_err(draw_err)?;
                    }
                }
                Swatch::Marker(c) => {
                    area.draw(&Circle::new((x + SWATCH_W / 2, y), 5, c.filled()))
                        .map_err(draw_err)?;
                }
                Swatch::Fill(c, alpha) => {
                    area.draw(&Rectangle::new(
                        [(x + 4, y - 8), (x + SWATCH_W - 4, y + 8)],
                        c.mix(alpha).filled(),
                    ))
                    .map_err(draw_err)?;
                    area.draw(&Rectangle::new(
                        [(x + 4, y - 8), (x + SWATCH_W - 4, y + 8)],
                        ShapeStyle::from(&c).stroke_width(1),
                    ))
                    .map_err(draw_err)?;
                }
            }
            area.draw(&Text::new(
                e.label.clone(),
                (x + SWATCH_W + 8, y),
                font.clone(),
            ))
            .map_err(draw_err)?;
            x += entry_width(e) + GAP;
        }
    }
    Ok(())
}

/// Renders a figure `width` pixels wide to an SVG string: a white canvas
/// with `title` on top, the legend of `entries` below it and `body_h` pixels
/// under the legend, which `draw_body` fills. `draw_body` gets the whole
/// canvas (for drawing in pixel coordinates) and the area under the legend.
pub fn render_figure(
    width: u32,
    title: &str,
    entries: &[LegendEntry],
    body_h: u32,
    draw_body: impl FnOnce(&Area<'_>, Area<'_>) -> Result<(), PlotError>,
) -> Result<String, PlotError> {
    let legend_h = legend_height(entries, width);
    let height = TITLE_H + legend_h + body_h;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let body = root
            .titled(title, (FONT, title_size(title, width)))
            .map_err(draw_err)?;
        let (legend_area, rest) = body.split_vertically(legend_h);
        draw_legend(&legend_area, entries)?;
        draw_body(&root, rest)?;
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// Checks that a title and the labels are not empty.
pub fn require_text(what: &str, text: &str) -> Result<(), PlotError> {
    if text.trim().is_empty() {
        Err(PlotError::Invalid(format!("{what} is empty")))
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_have_just_enough_decimals() {
        assert_eq!(tick_formatter(100.0)(&25.0), "25");
        assert_eq!(tick_formatter(1.0)(&0.25), "0.25");
        assert_eq!(tick_formatter(0.1)(&-1e-17), "0.00");
        assert_eq!(tick_formatter(1.0)(&(0.1 + 0.2)), "0.3");
    }

    #[test]
    fn nan_breaks_runs_and_ranges_skip_it() {
        let x = [0.0, 1.0, 2.0, 3.0, 4.0];
        let y = [1.0, f64::NAN, 2.0, 3.0, f64::INFINITY];
        assert_eq!(
            finite_runs(&x, &y),
            vec![vec![(0.0, 1.0)], vec![(2.0, 2.0), (3.0, 3.0)]]
        );
        assert_eq!(finite_range(&y), Some((1.0, 3.0)));
        assert_eq!(finite_range(&[f64::NAN]), None);
        assert_eq!(padded((2.0, 2.0), 0.05), (1.8, 2.2));
    }

    #[test]
    fn long_titles_shrink_and_notes_wrap() {
        assert_eq!(title_size("short", 900), TITLE_SIZE);
        let long = "cluster(4 modes, c=40), saturation priors: validation regressors by mode, regions and stops sliced";
        let size = title_size(long, 900);
        assert!(size < TITLE_SIZE && text_width(long, size) <= 860);
        let note = "Stops at y(k-1) = 0 and y(k-1) = 25: beyond a stop no ordinary mode applies (its region ends there), so the grey band past it is the far side of the stop, not a hole.";
        let lines = wrap(note, TICK_SIZE, 860);
        assert!(lines.len() > 1);
        assert!(lines.iter().all(|l| text_width(l, TICK_SIZE) <= 860));
        assert_eq!(lines.join(" "), note);
    }

    #[test]
    fn legend_wraps_into_rows() {
        let e: Vec<LegendEntry> = (0..6)
            .map(|k| {
                LegendEntry::new(
                    Swatch::Marker(mode_colour(k)),
                    format!("a long label number {k}"),
                )
            })
            .collect();
        assert_eq!(legend_height(&e[..1], 1000), ROW_H as u32 + 8);
        assert!(legend_height(&e, 400) > legend_height(&e, 2000));
        assert_eq!(legend_height(&[], 1000), 0);
    }
}
