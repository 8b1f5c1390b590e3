//! Classified data points in a plane of two regressor coordinates, with the
//! 2-D slices of the mode regions and the holes between them: the founding
//! paper's Figs. 6 and 11.

use std::path::Path;

use hysid_model::geometry::Polyhedron;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::PlotError;
use crate::common::{
    Area, Chart, DESC_SIZE, FONT, HOLE_COLOUR, LegendEntry, Swatch, TICK_SIZE, draw_err,
    finite_range, mode_colour, mode_name, padded, render_figure, require_text, tick_formatter,
    wrap, y_area_width,
};
use crate::slice::{Bounds, Slice2, slice_polyhedron};

/// Classified regressors and the mode regions, sliced by a plane.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RegionFigure {
    /// Title above the figure.
    pub title: String,
    /// Label of the horizontal axis with its unit, e.g. `"y(k-1) [mm]"`.
    pub x_label: String,
    /// Label of the vertical axis with its unit.
    pub y_label: String,
    /// The two regressor coordinates shown (horizontal, vertical), 0-based.
    pub axes: (usize, usize),
    /// A full regressor vector giving the value of every other coordinate in
    /// the slice (for example the means of the data); its entries at `axes`
    /// are ignored.
    pub fixed: Vec<f64>,
    /// Names of the regressor coordinates, used in the note that says where
    /// the slice is taken; empty gives `"x1"`, `"x2"`, ...
    pub coordinate_names: Vec<String>,
    /// The data points: full regressor vectors (same length as `fixed`),
    /// drawn at their two `axes` coordinates (a projection of all points).
    /// Points with a non-finite coordinate are skipped.
    pub points: Vec<Vec<f64>>,
    /// Mode of each point (`None`: unclassified), same length as `points`.
    pub labels: Vec<Option<usize>>,
    /// Region of each mode, `{x : a x <= b}` in regressor coordinates.
    pub regions: Vec<Polyhedron>,
    /// Names of the modes; missing names are `"mode k"` (1-based).
    pub mode_names: Vec<String>,
    /// Plotting window; `None` uses the range of the points plus 5 %.
    pub bounds: Option<Bounds>,
    /// Extra lines printed under the plot after the generated notes, e.g.
    /// how the window relates to a figure quoted elsewhere.
    pub notes: Vec<String>,
}

const WIDTH: u32 = 900;
const PLOT_H: u32 = 680;
/// Opacity of the region fill.
const REGION_ALPHA: f64 = 0.28;
/// Grid resolution of the hole/overlap estimate.
const GRID: usize = 200;
/// Colour of unclassified points.
const UNCLASSIFIED: RGBColor = RGBColor(90, 90, 90);

fn coord_name(fig: &RegionFigure, k: usize) -> String {
    fig.coordinate_names
        .get(k)
        .cloned()
        .unwrap_or_else(|| format!("x{}", k + 1))
}

/// True when `p` lies in the counter-clockwise convex polygon `v`.
fn in_convex(v: &[[f64; 2]], p: [f64; 2]) -> bool {
    let n = v.len();
    (0..n).all(|k| {
        let a = v[k];
        let b = v[(k + 1) % n];
        (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) >= 0.0
    })
}

/// Fractions of the window in no polygon and in two or more, on a grid of
/// cell centres.
fn coverage(polys: &[&Vec<[f64; 2]>], b: Bounds) -> (f64, f64) {
    let (mut none, mut many) = (0usize, 0usize);
    for r in 0..GRID {
        for c in 0..GRID {
            let p = [
                b.x_min + (c as f64 + 0.5) / GRID as f64 * (b.x_max - b.x_min),
                b.y_min + (r as f64 + 0.5) / GRID as f64 * (b.y_max - b.y_min),
            ];
            let k = polys.iter().filter(|v| in_convex(v, p)).count();
            if k == 0 {
                none += 1;
            } else if k > 1 {
                many += 1;
            }
        }
    }
    let total = (GRID * GRID) as f64;
    (none as f64 / total, many as f64 / total)
}

fn fmt_value(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    }
}

/// A share of the window in per cent, with enough digits that a non-zero
/// share never reads as `0.0 %` (the grid resolves 1 / GRID^2 = 0.0025 %).
fn fmt_share(f: f64) -> String {
    let p = 100.0 * f;
    if p == 0.0 {
        "0 %".into()
    } else if p < 0.1 {
        format!("{p:.4} %")
    } else {
        format!("{p:.1} %")
    }
}

/// A data point at its two plotted coordinates, with its mode.
type PlanePoint = ([f64; 2], Option<usize>);

/// Checks the texts, the axes and the lengths of the points and labels.
fn check_figure(fig: &RegionFigure) -> Result<(), PlotError> {
    require_text("the title", &fig.title)?;
    require_text("the horizontal axis label", &fig.x_label)?;
    require_text("the vertical axis label", &fig.y_label)?;
    let dim = fig.fixed.len();
    let (i, j) = fig.axes;
    if i == j || i >= dim || j >= dim {
        return Err(PlotError::Invalid(format!(
            "axes ({i}, {j}) must be two distinct coordinates below the dimension {dim} of `fixed`"
        )));
    }
    if fig.labels.len() != fig.points.len() {
        return Err(PlotError::LengthMismatch {
            what: "labels".into(),
            got: fig.labels.len(),
            expected: fig.points.len(),
        });
    }
    if let Some((k, p)) = fig.points.iter().enumerate().find(|(_, p)| p.len() != dim) {
        return Err(PlotError::LengthMismatch {
            what: format!("point {}", k + 1),
            got: p.len(),
            expected: dim,
        });
    }
    Ok(())
}

/// The points projected on the plane of `fig.axes`, without those with a
/// non-finite coordinate there.
fn projected_points(fig: &RegionFigure) -> Vec<PlanePoint> {
    let (i, j) = fig.axes;
    fig.points
        .iter()
        .zip(&fig.labels)
        .map(|(p, &l)| ([p[i], p[j]], l))
        .filter(|(p, _)| p[0].is_finite() && p[1].is_finite())
        .collect()
}

/// The plotting window: the given one, or the range of the points plus 5 %.
fn window(fig: &RegionFigure, pts: &[PlanePoint]) -> Result<Bounds, PlotError> {
    if let Some(b) = fig.bounds {
        if !b.is_valid() {
            return Err(PlotError::Invalid(
                "the plotting window is not a finite box of positive size".into(),
            ));
        }
        return Ok(b);
    }
    let xr = finite_range(pts.iter().map(|(p, _)| &p[0]))
        .ok_or_else(|| PlotError::NoData("no finite data point and no window given".into()))?;
    let yr = finite_range(pts.iter().map(|(p, _)| &p[1])).expect("same points");
    let (x_min, x_max) = padded(xr, 0.05);
    let (y_min, y_max) = padded(yr, 0.05);
    Ok(Bounds {
        x_min,
        x_max,
        y_min,
        y_max,
    })
}

/// The 2-D slice of every region in the window.
fn slice_regions(fig: &RegionFigure, bounds: Bounds) -> Result<Vec<Slice2>, PlotError> {
    fig.regions
        .iter()
        .enumerate()
        .map(|(m, r)| {
            slice_polyhedron(r, &fig.fixed, fig.axes, bounds)
                .map_err(|source| PlotError::Slice { mode: m, source })
        })
        .collect()
}

/// The slices that are polygons (those with an area in the plane).
fn polygons(slices: &[Slice2]) -> Vec<&Vec<[f64; 2]>> {
    slices
        .iter()
        .filter_map(|s| match s {
            Slice2::Polygon(v) => Some(v),
            _ => None,
        })
        .collect()
}

/// Legend: modes (regions or points), holes, unclassified points.
fn legend_entries(
    fig: &RegionFigure,
    pts: &[PlanePoint],
    slices: &[Slice2],
    hole: f64,
) -> Vec<LegendEntry> {
    let n_modes = fig.regions.len().max(
        pts.iter()
            .filter_map(|(_, l)| l.map(|m| m + 1))
            .max()
            .unwrap_or(0),
    );
    // A mode whose slice is a segment or a point (a guard set such as a
    // stop `y(k-1) = level`) is drawn as a thick line or a circle, and its
    // legend entry says so.
    let name = |m| mode_name(&fig.mode_names, m);
    let mut entries: Vec<LegendEntry> = (0..n_modes)
        .map(|m| match slices.get(m) {
            Some(Slice2::Segment(..)) => LegendEntry::new(
                Swatch::Line(mode_colour(m), 4, false),
                format!("{} (a line in this plane)", name(m)),
            ),
            Some(Slice2::Point(..)) => LegendEntry::new(
                Swatch::Marker(mode_colour(m)),
                format!("{} (a point in this plane)", name(m)),
            ),
            _ => LegendEntry::new(Swatch::Fill(mode_colour(m), 0.6), name(m)),
        })
        .collect();
    if !fig.regions.is_empty() && hole > 0.0 {
        entries.push(LegendEntry::new(
            Swatch::Fill(HOLE_COLOUR, 1.0),
            "in no region (hole)",
        ));
    }
    if pts.iter().any(|(_, l)| l.is_none()) {
        entries.push(LegendEntry::new(
            Swatch::Marker(UNCLASSIFIED),
            "unclassified point",
        ));
    }
    entries
}

/// Notes under the plot: where the slice is, what is not drawn, then the
/// figure's own notes; wrapped to the width of the figure.
fn notes(
    fig: &RegionFigure,
    n_points: usize,
    slices: &[Slice2],
    (hole, overlap): (f64, f64),
) -> Vec<String> {
    let (i, j) = fig.axes;
    let name = |m| mode_name(&fig.mode_names, m);
    let mut notes = Vec::new();
    let others: Vec<String> = (0..fig.fixed.len())
        .filter(|&k| k != i && k != j)
        .map(|k| format!("{} = {}", coord_name(fig, k), fmt_value(fig.fixed[k])))
        .collect();
    if !others.is_empty() {
        notes.push(format!(
            "Regions: slice at {}. Points: all {} data points, projected.",
            others.join(", "),
            n_points
        ));
    }
    if !fig.regions.is_empty() {
        notes.push(format!(
            "In this window of the plane: {} in no region, {} in two or more ({GRID} x {GRID} grid estimate).",
            fmt_share(hole),
            fmt_share(overlap)
        ));
    }
    let empty: Vec<String> = slices
        .iter()
        .enumerate()
        .filter(|(_, s)| s.is_empty())
        .map(|(m, _)| name(m))
        .collect();
    if !empty.is_empty() {
        notes.push(format!(
            "Not in this slice or window: {}.",
            empty.join(", ")
        ));
    }
    let flat: Vec<String> = slices
        .iter()
        .enumerate()
        .filter_map(|(m, s)| match s {
            Slice2::Segment(..) => Some(format!("{} (a line)", name(m))),
            Slice2::Point(..) => Some(format!("{} (a point)", name(m))),
            _ => None,
        })
        .collect();
    if !flat.is_empty() {
        notes.push(format!("Without area in this slice: {}.", flat.join(", ")));
    }
    notes.extend(fig.notes.iter().cloned());
    notes
        .iter()
        .flat_map(|n| wrap(n, TICK_SIZE, WIDTH - 40))
        .collect()
}

/// The chart over the window, before anything is drawn on it.
fn plane_chart<'a, 'b>(area: &'a Area<'b>, bounds: Bounds) -> Result<Chart<'a, 'b>, PlotError> {
    ChartBuilder::on(area)
        .margin_right(30)
        .margin_left(16)
        .margin_top(8)
        .x_label_area_size(62)
        .y_label_area_size(y_area_width((bounds.y_min, bounds.y_max)))
        .build_cartesian_2d(bounds.x_min..bounds.x_max, bounds.y_min..bounds.y_max)
        .map_err(draw_err)
}

fn to_pts(v: &[[f64; 2]]) -> Vec<(f64, f64)> {
    v.iter().map(|p| (p[0], p[1])).collect()
}

/// The partition as background: the window in grey, every region cleared
/// to white, then filled in its mode colour; what stays grey is a hole.
fn draw_partition(
    chart: &mut Chart<'_, '_>,
    bounds: Bounds,
    slices: &[Slice2],
) -> Result<(), PlotError> {
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(bounds.x_min, bounds.y_min), (bounds.x_max, bounds.y_max)],
            HOLE_COLOUR.filled(),
        )))
        .map_err(draw_err)?;
    chart
        .draw_series(
            polygons(slices)
                .iter()
                .map(|v| Polygon::new(to_pts(v), WHITE.filled())),
        )
        .map_err(draw_err)?;
    for (m, s) in slices.iter().enumerate() {
        if let Slice2::Polygon(v) = s {
            chart
                .draw_series(std::iter::once(Polygon::new(
                    to_pts(v),
                    mode_colour(m).mix(REGION_ALPHA).filled(),
                )))
                .map_err(draw_err)?;
        }
    }
    Ok(())
}

/// Axes, ticks, a faint grid and the axis labels.
fn draw_mesh(
    chart: &mut Chart<'_, '_>,
    fig: &RegionFigure,
    bounds: Bounds,
) -> Result<(), PlotError> {
    let xf = tick_formatter(bounds.x_max - bounds.x_min);
    let yf = tick_formatter(bounds.y_max - bounds.y_min);
    chart
        .configure_mesh()
        .x_label_formatter(&xf)
        .y_label_formatter(&yf)
        .x_labels(8)
        .y_labels(8)
        .label_style((FONT, TICK_SIZE))
        .axis_desc_style((FONT, DESC_SIZE))
        .light_line_style(TRANSPARENT)
        .bold_line_style(BLACK.mix(0.08))
        .x_desc(fig.x_label.as_str())
        .y_desc(fig.y_label.as_str())
        .draw()
        .map_err(draw_err)
}

/// Region boundaries, lines and points of lower-dimensional slices.
fn draw_outlines(chart: &mut Chart<'_, '_>, slices: &[Slice2]) -> Result<(), PlotError> {
    for (m, s) in slices.iter().enumerate() {
        let style = ShapeStyle::from(&mode_colour(m)).stroke_width(2);
        match s {
            Slice2::Empty => {}
            Slice2::Polygon(v) => {
                let mut path = to_pts(v);
                path.push(path[0]);
                chart
                    .draw_series(std::iter::once(PathElement::new(path, style)))
                    .map_err(draw_err)?;
            }
            Slice2::Segment(a, b) => {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(a[0], a[1]), (b[0], b[1])],
                        style.stroke_width(4),
                    )))
                    .map_err(draw_err)?;
            }
            Slice2::Point(p) => {
                chart
                    .draw_series(std::iter::once(Circle::new(
                        (p[0], p[1]),
                        8,
                        style.stroke_width(3),
                    )))
                    .map_err(draw_err)?;
            }
        }
    }
    Ok(())
}

/// The data points in their mode colours, clipped to the window.
fn draw_points(
    chart: &mut Chart<'_, '_>,
    pts: &[PlanePoint],
    bounds: Bounds,
) -> Result<(), PlotError> {
    let inside = |p: &[f64; 2]| {
        p[0] >= bounds.x_min && p[0] <= bounds.x_max && p[1] >= bounds.y_min && p[1] <= bounds.y_max
    };
    chart
        .draw_series(pts.iter().filter(|(p, _)| inside(p)).map(|(p, l)| {
            let style = match l {
                Some(m) => mode_colour(*m).filled(),
                None => ShapeStyle::from(&UNCLASSIFIED).stroke_width(1),
            };
            Circle::new((p[0], p[1]), 3, style)
        }))
        .map_err(draw_err)?;
    Ok(())
}

/// The notes, one line each, from the top left of `area`.
fn draw_notes(area: &Area<'_>, notes: &[String]) -> Result<(), PlotError> {
    let font = (FONT, TICK_SIZE)
        .into_font()
        .color(&RGBColor(50, 50, 50))
        .pos(Pos::new(HPos::Left, VPos::Top));
    for (k, note) in notes.iter().enumerate() {
        area.draw(&Text::new(
            note.clone(),
            (20, 4 + 24 * k as i32),
            font.clone(),
        ))
        .map_err(draw_err)?;
    }
    Ok(())
}

/// Renders a [`RegionFigure`] to an SVG string.
pub fn regions_svg(fig: &RegionFigure) -> Result<String, PlotError> {
    check_figure(fig)?;
    let pts = projected_points(fig);
    let bounds = window(fig, &pts)?;
    let slices = slice_regions(fig, bounds)?;
    let shares = if fig.regions.is_empty() {
        (0.0, 0.0)
    } else {
        coverage(&polygons(&slices), bounds)
    };
    let entries = legend_entries(fig, &pts, &slices, shares.0);
    let notes = notes(fig, pts.len(), &slices, shares);
    let notes_h = 10 + 24 * notes.len() as u32;
    render_figure(WIDTH, &fig.title, &entries, PLOT_H + notes_h, |_, rest| {
        let (plot_area, notes_area) = rest.split_vertically(PLOT_H);
        let mut chart = plane_chart(&plot_area, bounds)?;
        if !fig.regions.is_empty() {
            draw_partition(&mut chart, bounds, &slices)?;
        }
        draw_mesh(&mut chart, fig, bounds)?;
        draw_outlines(&mut chart, &slices)?;
        draw_points(&mut chart, &pts, bounds)?;
        draw_notes(&notes_area, &notes)
    })
}

/// Draws classified points and region slices in a regressor plane into the
/// file `path` (`.svg` or `.png`), written atomically.
pub fn regions_plot(path: &Path, fig: &RegionFigure) -> Result<(), PlotError> {
    let svg = regions_svg(fig)?;
    crate::write_figure(path, &svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_counts_holes_and_overlaps() {
        let b = Bounds {
            x_min: 0.0,
            x_max: 1.0,
            y_min: 0.0,
            y_max: 1.0,
        };
        let left = vec![[0.0, 0.0], [0.5, 0.0], [0.5, 1.0], [0.0, 1.0]];
        let (hole, overlap) = coverage(&[&left], b);
        assert!((hole - 0.5).abs() < 1e-12 && overlap == 0.0);
        let all = b.corners();
        let (hole, overlap) = coverage(&[&left, &all], b);
        assert!(hole == 0.0 && (overlap - 0.5).abs() < 1e-12);
        assert_eq!(fmt_value(0.5), "0.5");
        assert_eq!(fmt_value(12.0), "12");
        assert_eq!(fmt_share(0.0), "0 %");
        assert_eq!(fmt_share(1.0 / 40_000.0), "0.0025 %");
        assert_eq!(fmt_share(0.25), "25.0 %");
    }
}
