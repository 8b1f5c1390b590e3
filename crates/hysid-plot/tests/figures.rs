//! Every figure renders to well-formed SVG that carries its title, axis
//! labels and legend; rendering is deterministic; bad data is an error, not a
//! panic.

use hysid_model::geometry::Polyhedron;
use hysid_plot::*;
use proptest::prelude::*;

/// Parses the SVG and returns the trimmed text of every `<text>` element.
fn texts(svg: &str) -> Vec<String> {
    assert!(
        svg.starts_with("<svg"),
        "starts with <svg: {}",
        &svg[..40.min(svg.len())]
    );
    assert!(svg.trim_end().ends_with("</svg>"));
    let doc = roxmltree::Document::parse(svg).expect("well-formed XML");
    assert_eq!(doc.root_element().tag_name().name(), "svg");
    doc.descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| n.text().unwrap_or("").trim().to_string())
        .collect()
}

fn has(texts: &[String], s: &str) -> bool {
    texts.iter().any(|t| t == s)
}

fn simulation_figure() -> SimulationFigure {
    let n = 200;
    let (time, time_label) = time_axis(n, Some(0.0025), 5000);
    let u: Vec<f64> = (0..n)
        .map(|k| if (k / 40) % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let y: Vec<f64> = (0..n).map(|k| (k as f64 * 0.05).sin()).collect();
    let yhat: Vec<f64> = y.iter().map(|v| 0.9 * v).collect();
    SimulationFigure {
        title: "Validation <pick & place>".into(),
        time,
        time_label,
        output_label: "position y [mm]".into(),
        measured: Series::new("measured", y),
        simulated: vec![
            Series::new("cluster (FIT 80.0 %)", yhat.clone()),
            Series::new("arx (FIT 71.0 %)", yhat.iter().map(|v| v + 0.1).collect()),
        ],
        input_label: "input u [-]".into(),
        inputs: vec![Series::new("u", u)],
        warm_ups: vec![(5000.0 * 0.0025, 5010.0 * 0.0025)],
        record_starts: Vec::new(),
    }
}

fn mode_figure() -> ModeFigure {
    let n = 100;
    let truth: Vec<Option<usize>> = (0..n).map(|k| Some(usize::from(k >= 50))).collect();
    let mut ident = truth.clone();
    ident[10] = Some(1);
    ident[60] = None;
    let (time, time_label) = time_axis(n, None, 0);
    ModeFigure {
        title: "Modes".into(),
        time,
        time_label,
        sequences: vec![
            ModeSequence::new("true", truth),
            ModeSequence::new("identified", ident),
        ],
        mode_names: vec!["free motion".into()],
        mark_mismatch: true,
    }
}

fn region_figure() -> RegionFigure {
    // Two half-spaces of R^3 with a gap 0 < x0 < 0.2, and one region that
    // misses the slice x2 = 0.
    let regions = vec![
        Polyhedron::from_inequalities(vec![vec![1.0, 0.0, 0.0]], vec![0.0]),
        Polyhedron::from_inequalities(vec![vec![-1.0, 0.0, 0.0]], vec![-0.2]),
        Polyhedron::from_inequalities(vec![vec![0.0, 0.0, -1.0]], vec![-5.0]),
    ];
    let points: Vec<Vec<f64>> = (0..50)
        .map(|k| vec![-1.0 + 0.04 * k as f64, 0.5 - 0.02 * k as f64, 0.0])
        .collect();
    let labels = points
        .iter()
        .map(|p| if p[0] <= 0.1 { Some(0) } else { Some(1) })
        .collect();
    RegionFigure {
        title: "Regions".into(),
        x_label: "y(k-1) [mm]".into(),
        y_label: "u(k-1) [-]".into(),
        axes: (0, 1),
        fixed: vec![0.0, 0.0, 0.0],
        coordinate_names: vec!["y(k-1)".into(), "u(k-1)".into(), "u(k-2)".into()],
        points,
        labels,
        regions,
        mode_names: vec![],
        bounds: None,
        notes: vec![],
    }
}

fn sweep_figure() -> SweepFigure {
    let c = vec![15.0, 25.0, 35.0, 55.0];
    SweepFigure {
        title: "FIT and modes versus delta".into(),
        x_label: "delta [mm]".into(),
        panels: vec![
            SweepPanel {
                y_label: "fit_sim [%]".into(),
                series: vec![
                    SweepSeries::new("bounded", c.clone(), vec![70.0, 75.0, f64::NAN, 80.0]),
                    SweepSeries::new("cluster", c.clone(), vec![60.0, 65.0, 70.0, 72.0]),
                ],
                integer_y: false,
            },
            SweepPanel {
                y_label: "modes [-]".into(),
                series: vec![SweepSeries::new("bounded", c, vec![5.0, 4.0, 3.0, 2.0])],
                integer_y: true,
            },
        ],
        log_x: true,
    }
}

#[test]
fn simulation_plot_has_title_labels_legend_and_writes_the_file() {
    let fig = simulation_figure();
    let svg = simulation_svg(&fig).unwrap();
    let t = texts(&svg);
    for s in [
        "Validation <pick & place>",
        "time t [s]",
        "position y [mm]",
        "input u [-]",
        "measured",
        "cluster (FIT 80.0 %)",
        "arx (FIT 71.0 %)",
        "u",
        "warm-up (not scored)",
    ] {
        assert!(has(&t, s), "missing text {s:?} in {t:?}");
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sim.svg");
    simulation_plot(&path, &fig).unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), svg);
    // Without inputs: one panel, the time label still there.
    let mut no_u = fig.clone();
    no_u.inputs.clear();
    no_u.warm_ups.clear();
    let t = texts(&simulation_svg(&no_u).unwrap());
    assert!(has(&t, "time t [s]") && !has(&t, "input u [-]") && !has(&t, "warm-up (not scored)"));
}

#[test]
fn time_axis_uses_seconds_or_sample_index() {
    let (t, l) = time_axis(3, Some(0.5), 10);
    assert_eq!((t, l.as_str()), (vec![5.0, 5.5, 6.0], "time t [s]"));
    let (t, l) = time_axis(2, None, 4);
    assert_eq!((t, l.as_str()), (vec![4.0, 5.0], "sample k [-]"));
}

#[test]
fn mode_plot_has_lanes_legend_and_counts_mismatches() {
    let svg = mode_sequence_svg(&mode_figure()).unwrap();
    let t = texts(&svg);
    for s in [
        "Modes",
        "sample k [-]",
        "true",
        "identified",
        "differs",
        "free motion",
        "mode 2",
        "no mode active",
        "mode",
    ] {
        assert!(has(&t, s), "missing text {s:?} in {t:?}");
    }
    assert!(
        has(
            &t,
            "'identified' differs from 'true' (2 of 100 samples, 2.0 %)"
        ),
        "{t:?}"
    );
}

#[test]
fn region_plot_shows_holes_and_notes_empty_slices() {
    let svg = regions_svg(&region_figure()).unwrap();
    let t = texts(&svg);
    for s in [
        "Regions",
        "y(k-1) [mm]",
        "u(k-1) [-]",
        "mode 1",
        "mode 2",
        "mode 3",
        "in no region (hole)",
    ] {
        assert!(has(&t, s), "missing text {s:?} in {t:?}");
    }
    assert!(has(&t, "Not in this slice or window: mode 3."), "{t:?}");
    assert!(
        has(
            &t,
            "Regions: slice at u(k-2) = 0. Points: all 50 data points, projected."
        ),
        "{t:?}"
    );
    // The gap 0 < x0 < 0.2 in a window of width 2.1 (points span [-1, 0.96]
    // plus 5 %): about 0.2 / 2.058 of it is in no region.
    let note = t
        .iter()
        .find(|s| s.starts_with("In this window of the plane:"))
        .unwrap();
    assert!(note.contains("9.") || note.contains("10."), "{note}");
    assert!(svg.contains("<polygon"), "regions are drawn as polygons");
}

#[test]
fn sweep_plot_has_panels_legend_and_log_ticks() {
    let svg = sweep_svg(&sweep_figure()).unwrap();
    let t = texts(&svg);
    for s in [
        "FIT and modes versus delta",
        "delta [mm]",
        "fit_sim [%]",
        "modes [-]",
        "bounded",
        "cluster",
        "20",
        "50",
    ] {
        assert!(has(&t, s), "missing text {s:?} in {t:?}");
    }
    // The legend has one entry per label, not per panel.
    assert_eq!(t.iter().filter(|s| *s == "bounded").count(), 1);
}

#[test]
fn rendering_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str| {
        let p = dir.path().join(name);
        match name {
            "sim.svg" => simulation_plot(&p, &simulation_figure()).unwrap(),
            "modes.svg" => mode_sequence_plot(&p, &mode_figure()).unwrap(),
            "regions.svg" => regions_plot(&p, &region_figure()).unwrap(),
            _ => sweep_plot(&p, &sweep_figure()).unwrap(),
        }
        std::fs::read(&p).unwrap()
    };
    for name in ["sim.svg", "modes.svg", "regions.svg", "sweep.svg"] {
        let a = render(name);
        let b = render(name);
        assert!(!a.is_empty());
        assert_eq!(a, b, "{name} differs between two renders");
    }
}

#[test]
fn bad_figures_are_errors() {
    let mut f = simulation_figure();
    f.time.clear();
    assert!(matches!(simulation_svg(&f), Err(PlotError::NoData(_))));
    let mut f = simulation_figure();
    f.simulated[1].values.pop();
    assert!(matches!(
        simulation_svg(&f),
        Err(PlotError::LengthMismatch { .. })
    ));
    let mut f = simulation_figure();
    f.measured.values.iter_mut().for_each(|v| *v = f64::NAN);
    f.simulated.clear();
    assert!(matches!(simulation_svg(&f), Err(PlotError::NoData(_))));
    let mut f = simulation_figure();
    f.title = " ".into();
    assert!(matches!(simulation_svg(&f), Err(PlotError::Invalid(_))));

    let mut m = mode_figure();
    m.time[3] = m.time[2];
    assert!(matches!(mode_sequence_svg(&m), Err(PlotError::Invalid(_))));
    let mut m = mode_figure();
    m.sequences.clear();
    assert!(matches!(mode_sequence_svg(&m), Err(PlotError::NoData(_))));

    let mut r = region_figure();
    r.axes = (1, 1);
    assert!(matches!(regions_svg(&r), Err(PlotError::Invalid(_))));
    let mut r = region_figure();
    r.regions
        .push(Polyhedron::from_inequalities(vec![vec![1.0]], vec![0.0]));
    assert!(matches!(
        regions_svg(&r),
        Err(PlotError::Slice { mode: 3, .. })
    ));
    let mut r = region_figure();
    r.points.iter_mut().for_each(|p| p[0] = f64::NAN);
    assert!(matches!(regions_svg(&r), Err(PlotError::NoData(_))));
    let mut r = region_figure();
    r.labels.pop();
    assert!(matches!(
        regions_svg(&r),
        Err(PlotError::LengthMismatch { .. })
    ));

    let mut s = sweep_figure();
    s.panels[0].series[0].x[0] = 0.0;
    assert!(matches!(sweep_svg(&s), Err(PlotError::Invalid(_))));
    let mut s = sweep_figure();
    s.panels[1].series[0].y = vec![f64::NAN; 4];
    assert!(matches!(sweep_svg(&s), Err(PlotError::NoData(_))));

    let err = simulation_plot(
        std::path::Path::new("/nonexistent-dir-hysid/x.svg"),
        &simulation_figure(),
    );
    assert!(matches!(err, Err(PlotError::Io { .. })));
}

#[test]
fn regions_with_an_explicit_window_and_no_points_render() {
    let mut r = region_figure();
    r.points.clear();
    r.labels.clear();
    r.bounds = Some(Bounds {
        x_min: -1.0,
        x_max: 1.0,
        y_min: -1.0,
        y_max: 1.0,
    });
    let t = texts(&regions_svg(&r).unwrap());
    assert!(has(&t, "Regions"));
    // A lower-dimensional region is reported as a line.
    let mut stop = Polyhedron::everything();
    stop.a_eq = vec![vec![1.0, 0.0, 0.0]];
    stop.b_eq = vec![0.5];
    r.regions = vec![stop];
    let t = texts(&regions_svg(&r).unwrap());
    assert!(
        has(&t, "Without area in this slice: mode 1 (a line)."),
        "{t:?}"
    );
    // Its legend entry says it is a line, and the extra notes are printed.
    r.notes = vec!["The window is not the data box.".into()];
    let t = texts(&regions_svg(&r).unwrap());
    assert!(has(&t, "mode 1 (a line in this plane)"), "{t:?}");
    assert!(has(&t, "The window is not the data box."), "{t:?}");
}

fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -1e3f64..1e3,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(0.0),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Arbitrary values with NaN and infinities never panic: either an error
    /// or a well-formed SVG.
    #[test]
    fn arbitrary_data_never_panics(
        y in proptest::collection::vec(value(), 1..40),
        shift in value(),
        ts in prop_oneof![Just(None), Just(Some(0.01))],
    ) {
        let n = y.len();
        let (time, time_label) = time_axis(n, ts, 0);
        let fig = SimulationFigure {
            title: "t".into(),
            time: time.clone(),
            time_label: time_label.clone(),
            output_label: "y [-]".into(),
            measured: Series::new("m", y.clone()),
            simulated: vec![Series::new("s", y.iter().map(|v| v + shift).collect())],
            input_label: "u [-]".into(),
            inputs: vec![Series::new("u", y.clone())],
            warm_ups: vec![(f64::NEG_INFINITY, shift)],
            record_starts: Vec::new(),
        };
        if let Ok(svg) = simulation_svg(&fig) { texts(&svg); }
        let sweep = SweepFigure {
            title: "t".into(),
            x_label: "x [-]".into(),
            panels: vec![SweepPanel { y_label: "y [-]".into(), series: vec![SweepSeries::new("a", y.clone(), y.clone())], integer_y: shift > 0.0 }],
            log_x: shift < 0.0,
        };
        if let Ok(svg) = sweep_svg(&sweep) { texts(&svg); }
        let modes = ModeFigure {
            title: "t".into(),
            time,
            time_label,
            sequences: vec![ModeSequence::new("a", y.iter().map(|v| (v.is_finite() && *v > 0.0).then_some((*v as usize) % 12)).collect())],
            mode_names: vec![],
            mark_mismatch: true,
        };
        if let Ok(svg) = mode_sequence_svg(&modes) { texts(&svg); }
        let pts: Vec<Vec<f64>> = y.chunks(2).filter(|c| c.len() == 2).map(|c| c.to_vec()).collect();
        let regions = RegionFigure {
            title: "t".into(),
            x_label: "a".into(),
            y_label: "b".into(),
            axes: (0, 1),
            fixed: vec![0.0, 0.0],
            labels: vec![Some(0); pts.len()],
            points: pts,
            regions: vec![Polyhedron::from_inequalities(vec![vec![1.0, shift]], vec![shift])],
            ..RegionFigure::default()
        };
        if let Ok(svg) = regions_svg(&regions) { texts(&svg); }
    }
}

/// Non-white pixels of `png` in rows `rows` (pixel rows of the image).
#[cfg(feature = "png")]
fn inked(png: &[u8], rows: std::ops::Range<u32>) -> (u32, u32, usize) {
    let img = resvg::tiny_skia::Pixmap::decode_png(png).expect("a readable PNG");
    let (w, h) = (img.width(), img.height());
    let ink = rows
        .filter(|&r| r < h)
        .flat_map(|r| (0..w).map(move |c| (r, c)))
        .filter(|&(r, c)| {
            let p = img.pixel(c, r).unwrap();
            p.red() < 200 || p.green() < 200 || p.blue() < 200
        })
        .count();
    (w, h, ink)
}

/// A `.png` path gives the SVG rasterised at twice its size, text drawn
/// with the embedded font (a long title inks its band, a one-dot title
/// hardly); any other extension is refused, and nothing is written.
#[cfg(feature = "png")]
#[test]
fn png_figures_are_the_svg_rasterised_with_their_text() {
    let dir = tempfile::tempdir().unwrap();
    let fig = simulation_figure();
    let svg = simulation_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let size = |a: &str| -> u32 { doc.root_element().attribute(a).unwrap().parse().unwrap() };
    let (svg_w, svg_h) = (size("width"), size("height"));
    let path = dir.path().join("sim.png");
    simulation_plot(&path, &fig).unwrap();
    let png = std::fs::read(&path).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let band = 0..(PNG_SCALE as u32 * 30);
    let (w, h, titled) = inked(&png, band.clone());
    assert_eq!((w, h), (2 * svg_w, 2 * svg_h));
    let untitled_path = dir.path().join("untitled.png");
    let untitled = SimulationFigure {
        title: ".".into(),
        ..fig.clone()
    };
    simulation_plot(&untitled_path, &untitled).unwrap();
    let (_, _, blank) = inked(&std::fs::read(&untitled_path).unwrap(), band);
    assert!(
        titled > 200 && titled > 10 * blank.max(1),
        "title band: {titled} inked pixels, {blank} with a dot for title"
    );
    let (_, _, body) = inked(&png, 0..h);
    assert!(body > 10_000, "{body} inked pixels");
    let gif = dir.path().join("sim.gif");
    assert!(matches!(
        simulation_plot(&gif, &fig),
        Err(PlotError::Format { .. })
    ));
    assert!(!gif.exists());
}

/// Without the `png` feature a `.png` path is refused with the error that
/// says how to build it, and nothing is written; any other extension than
/// `.svg` and `.png` is refused too.
#[cfg(not(feature = "png"))]
#[test]
fn png_figures_need_the_png_feature() {
    let dir = tempfile::tempdir().unwrap();
    let fig = simulation_figure();
    for (name, png) in [("sim.png", true), ("sim.gif", false)] {
        let path = dir.path().join(name);
        let e = simulation_plot(&path, &fig).unwrap_err();
        assert_eq!(matches!(e, PlotError::PngNotBuilt), png, "{e}");
        assert!(!path.exists());
    }
    assert!(
        PlotError::PngNotBuilt
            .to_string()
            .contains("--features png")
    );
}
