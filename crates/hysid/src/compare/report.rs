//! Writing a comparison: `report.md`, `report.json`, `models/*.json` and
//! the figures under `plots/` (SVG, `hysid-plot`).

use crate::compare::experiment::slug;
use crate::compare::{Comparison, Drawn, DrawnRun, RunResult};
use hysid_core::model::Model;
use hysid_core::simulate::ValidationReport;
use hysid_model::data::Dataset;
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{HybridAutomaton, InitialState, PwarxMode, PwarxModel, TimeDomain};
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::DivergedTo;
use hysid_model::statistics::median;
use hysid_plot::{
    ModeFigure, ModeSequence, RegionFigure, SimulationFigure, SweepFigure, SweepPanel, SweepSeries,
};
use std::fmt::Write as _;
use std::path::Path;

/// Why a folder cannot take a report ([`check_report_folder`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReportFolderError {
    /// The folder is a file.
    #[error("is a file; the report goes into a folder")]
    IsAFile,
    /// Its `models` or `plots` is a file.
    #[error("{} is a file; the report writes into a folder of that name", .0.display())]
    InnerIsAFile(std::path::PathBuf),
    /// A file the run reads is one the report may replace or remove.
    #[error(
        "holds {}, which the run reads and its report may replace or remove; give another folder",
        .0.display()
    )]
    HoldsAnInput(std::path::PathBuf),
}

/// Whether `dir` can take a report: it, its `models` and its `plots` are
/// folders or not there yet, and none of `inputs` (the files the run
/// reads) is a file the report writes or removes ([`REPORT_FILES`]).
/// Checked before anything runs, since writing comes after every fit.
pub fn check_report_folder(dir: &Path, inputs: &[&Path]) -> Result<(), ReportFolderError> {
    let a_file = |p: &Path| p.exists() && !p.is_dir();
    if a_file(dir) {
        return Err(ReportFolderError::IsAFile);
    }
    if let Some(inner) = ["models", "plots"]
        .map(|f| dir.join(f))
        .into_iter()
        .find(|p| a_file(p))
    {
        return Err(ReportFolderError::InnerIsAFile(inner));
    }
    match inputs.iter().find(|p| a_report_file(dir, p)) {
        Some(input) => Err(ReportFolderError::HoldsAnInput(input.to_path_buf())),
        None => Ok(()),
    }
}

/// The files of a report folder that writing a report may replace or
/// remove: in its folder, `report.md` and `report.json`; in `models/` and
/// `plots/`, files of these extensions.
pub const REPORT_FILES: [(&str, &[&str]); 3] = [
    ("", &["report.md", "report.json"]),
    ("models", &["json"]),
    ("plots", &["svg", "png"]),
];

/// Whether `file` is one of the files of [`REPORT_FILES`] in `dir` (both
/// resolved, so links and `..` name the same file).
fn a_report_file(dir: &Path, file: &Path) -> bool {
    let (Ok(dir), Ok(file)) = (std::fs::canonicalize(dir), std::fs::canonicalize(file)) else {
        return false;
    };
    let (Some(folder), Some(name)) = (file.parent(), file.file_name().and_then(|n| n.to_str()))
    else {
        return false;
    };
    let extension = file.extension().and_then(|x| x.to_str()).unwrap_or("");
    REPORT_FILES.iter().any(|(inner, kinds)| {
        folder == dir.join(inner)
            && kinds.iter().any(|k| {
                if inner.is_empty() {
                    name == *k
                } else {
                    extension == *k
                }
            })
    })
}

/// Writes the report and the models into `dir` (created if needed); every
/// file is written atomically, and in a folder that held an earlier
/// report, its models and figures that this one does not write are
/// removed. Returns the paths written.
pub fn write_report(c: &mut Comparison, dir: &Path) -> std::io::Result<Vec<std::path::PathBuf>> {
    let earlier = dir.join("report.json").is_file();
    std::fs::create_dir_all(dir.join("models"))?;
    let mut written = Vec::new();
    for r in &mut c.results {
        if let Some(m) = &r.model {
            let rel = format!("models/{}.json", slug(&r.name));
            let path = dir.join(&rel);
            hysid_io::write(&path, m.to_json().as_bytes())?;
            written.push(path);
            r.model_file = Some(rel);
        }
    }
    let (files, drawn) = figures(c, dir)?;
    written.extend(files);
    c.drawn = drawn;
    let json = serde_json::to_string_pretty(&*c).expect("report serialises") + "\n";
    let p = dir.join("report.json");
    hysid_io::write(&p, json.as_bytes())?;
    written.push(p);
    let p = dir.join("report.md");
    hysid_io::write(&p, markdown(c).as_bytes())?;
    written.push(p);
    if earlier {
        remove_stale(dir, &written)?;
    }
    Ok(written)
}

/// Removes the models and figures of an earlier report in `dir` (a folder
/// that held a `report.json`) that this one did not write (`written`): a
/// report folder holds one report, so no model sits beside a report that
/// does not list it. Only files of the kinds a report writes, in `models/`
/// and `plots/`, are touched.
fn remove_stale(dir: &Path, written: &[std::path::PathBuf]) -> std::io::Result<()> {
    for (folder, kinds) in REPORT_FILES.iter().filter(|(inner, _)| !inner.is_empty()) {
        let Ok(entries) = std::fs::read_dir(dir.join(folder)) else {
            continue;
        };
        for entry in entries {
            let path = entry?.path();
            let ours =
                (path.extension().and_then(|e| e.to_str())).is_some_and(|e| kinds.contains(&e));
            if ours && path.is_file() && !written.contains(&path) {
                std::fs::remove_file(&path)?;
            }
        }
    }
    Ok(())
}

fn plot_err(e: hysid_plot::PlotError) -> std::io::Error {
    std::io::Error::other(e.to_string())
}

/// Figures: measured vs simulated output and the mode sequence of every
/// `[[run]]` (and all runs together), and one figure per sweep (fit_sim and
/// mode count against the first varied key). Returns the files and what
/// they show.
fn figures(c: &Comparison, dir: &Path) -> std::io::Result<(Vec<std::path::PathBuf>, Drawn)> {
    let mut drawn = Drawn::default();
    let Some(valid) = &c.validation else {
        return Ok((vec![], drawn));
    };
    std::fs::create_dir_all(dir.join("plots"))?;
    let mut written = Vec::new();
    let ext = c.figures.extension();
    // A figure's path under the report's directory, and the file.
    let file = |name: String| {
        let rel = format!("plots/{name}.{ext}");
        let p = dir.join(&rel);
        (rel, p)
    };
    let y_label = c.output_label.clone();
    let u_label = c.input_label.clone();
    let base = |title: String| {
        SimulationFigure::from_dataset(
            title,
            valid,
            c.validation_first_row,
            y_label.clone(),
            u_label.clone(),
        )
        .with_warmup(c.warmup)
    };
    let mut all = base("Validation: free-run simulation of every run".to_string());
    for r in c
        .results
        .iter()
        .filter(|r| r.simulation.is_some() && r.sweep.is_none())
    {
        let sim = r.simulation.as_ref().expect("filtered");
        let fit = r
            .report
            .as_ref()
            .map_or(String::new(), |v| format!(" (fit_sim {:.1} %)", v.fit_sim));
        let slug = slug(&r.name);
        let (simulation, p) = file(format!("{slug}-simulation"));
        hysid_plot::simulation_plot(
            &p,
            &base(format!("{}{fit}", r.name)).with_simulation(&r.name, sim),
        )
        .map_err(plot_err)?;
        written.push(p);
        let (time, time_label) =
            hysid_plot::time_axis(valid.len(), valid.ts, c.validation_first_row);
        let modes = ModeFigure {
            title: format!("{}: active mode in simulation", r.name),
            time,
            time_label,
            sequences: vec![ModeSequence::from_simulation(&r.name, sim)],
            mode_names: r.model.as_ref().map(display_mode_names).unwrap_or_default(),
            mark_mismatch: false,
        };
        let (modes_file, p) = file(format!("{slug}-modes"));
        hysid_plot::mode_sequence_plot(&p, &modes).map_err(plot_err)?;
        written.push(p);
        all = all.with_simulation(format!("{}{fit}", r.name), sim);
        // Classified validation regressors with the region boundaries (the
        // founding paper's Figs. 6 and 11), in the plane y(k-1), u(k-1).
        let mut regions = None;
        if let Some(fig) = region_figure(c, r, valid) {
            let (rel, p) = file(format!("{slug}-regions"));
            hysid_plot::regions_plot(&p, &fig).map_err(plot_err)?;
            written.push(p);
            regions = Some(rel);
        }
        drawn.runs.push(DrawnRun {
            name: r.name.clone(),
            simulation,
            modes: modes_file,
            regions,
        });
    }
    if !all.simulated.is_empty() {
        let (rel, p) = file("runs-simulation".into());
        hysid_plot::simulation_plot(&p, &all).map_err(plot_err)?;
        written.push(p);
        drawn.all = Some(rel);
    }
    let mut sweeps: Vec<&str> = Vec::new();
    for r in &c.results {
        if let Some(s) = &r.sweep
            && !sweeps.contains(&s.sweep.as_str())
        {
            sweeps.push(&s.sweep);
        }
    }
    for name in sweeps {
        let Some(fig) = sweep_figure(c, name, &sweep_points(c, name)) else {
            continue;
        };
        let (rel, p) = file(format!("{}-sweep", slug(name)));
        hysid_plot::sweep_plot(&p, &fig).map_err(plot_err)?;
        written.push(p);
        drawn.sweeps.push((name.to_string(), rel));
    }
    Ok((written, drawn))
}

/// The unit in the last `[...]` of an axis label (`"head position y [mm]"`
/// gives `"mm"`), or `"-"` when there is none.
pub fn unit_of(label: &str) -> String {
    label
        .rfind('[')
        .and_then(|a| {
            let rest = &label[a + 1..];
            rest.find(']').map(|b| rest[..b].trim().to_string())
        })
        .filter(|u| !u.is_empty())
        .unwrap_or_else(|| "-".into())
}

/// The unit of every regressor of `spec`: output lags in the unit of the
/// experiment's output label, input lags in that of its input label.
fn regressor_units(c: &Comparison, spec: &RegressorSpec) -> Vec<String> {
    let (y, u) = (unit_of(&c.output_label), unit_of(&c.input_label));
    (0..spec.dim())
        .map(|k| if k < spec.na { y.clone() } else { u.clone() })
        .collect()
}

/// The unit of a swept key: `delta` (the bounded error bound) is in output
/// units; the other keys (`c`, `modes`, orders, ...) are numbers.
fn sweep_key_unit(c_output_label: &str, key: &str) -> String {
    match key {
        "delta" => unit_of(c_output_label),
        _ => "-".into(),
    }
}

/// The level of a stop mode: an invariant that is the single equality
/// `y = level` on the first coordinate (as built by
/// `HybridAutomaton::from_pwarx_with_stops`).
fn stop_level(p: &Polyhedron) -> Option<f64> {
    if p.a_eq.len() != 1 || !p.a.is_empty() {
        return None;
    }
    let row = &p.a_eq[0];
    let c = *row.first()?;
    (c != 0.0 && row[1..].iter().all(|&v| v == 0.0)).then(|| p.b_eq[0] / c)
}

/// Mode names as the figures show them, the same in the mode-sequence and
/// the region plots: the model's names (unnamed PWARX modes are `mode 1`,
/// `mode 2`, ...: `hysid_model::model::mode_name`); a stop of an automaton
/// also says its level.
fn display_mode_names(m: &Model) -> Vec<String> {
    match m {
        Model::HybridAutomaton(a) => a
            .modes
            .iter()
            .map(|q| match stop_level(&q.invariant) {
                Some(level) => format!("{}: stop y = {level}", q.name),
                None => q.name.clone(),
            })
            .collect(),
        Model::Pwarx(_) | Model::Mechanical(_) | Model::GrayBox(_) => m.mode_names(),
    }
}

/// A discrete-time automaton in ARX form (as built from a PWARX model,
/// with or without stops) read back in PWARX regressor coordinates: the
/// invariants of its modes as regions (a stop becomes the guard set
/// `y(k-1) = level`), its orders and input count. `None` for any other
/// automaton.
fn automaton_regions(a: &HybridAutomaton) -> Option<(RegressorSpec, Vec<Polyhedron>)> {
    let InitialState::ArxHistory { na, nb } = a.initial_state else {
        return None;
    };
    let m = a.inputs.len();
    let nu = nb.saturating_sub(1);
    if a.time != TimeDomain::Discrete || na == 0 || a.states.len() != na + nu * m {
        return None;
    }
    let n = na + nu * m;
    // Position in z = [x(k-1); u(k-1)] of each regressor entry of y(k)
    // (the inverse of the map in `HybridAutomaton::from_pwarx`).
    let mut pos: Vec<usize> = (0..na).collect();
    for i in 0..m {
        for j in 1..=nb {
            pos.push(if j == 1 { n + i } else { na + i * nu + (j - 2) });
        }
    }
    let back = |rows: &[Vec<f64>]| -> Option<Vec<Vec<f64>>> {
        rows.iter()
            .map(|r| (r.len() == n + m).then(|| pos.iter().map(|&zi| r[zi]).collect::<Vec<f64>>()))
            .collect()
    };
    let regions = a
        .modes
        .iter()
        .map(|q| {
            Some(Polyhedron {
                a: back(&q.invariant.a)?,
                b: q.invariant.b.clone(),
                a_eq: back(&q.invariant.a_eq)?,
                b_eq: q.invariant.b_eq.clone(),
            })
        })
        .collect::<Option<Vec<_>>>()?;
    Some((RegressorSpec::new(na, nb, m), regions))
}

/// The region figure of a `[[run]]`: the validation regressors coloured by
/// mode and the regions sliced in the plane `y(k-1)`, `u(k-1)` (the other
/// coordinates at their means), for a PWARX model with two or more modes
/// and for an automaton in ARX form (ordinary modes as regions, stops as
/// the lines `y(k-1) = level`). `None` when there is nothing to draw.
fn region_figure(c: &Comparison, r: &RunResult, valid: &Dataset) -> Option<RegionFigure> {
    if r.sweep.is_some() || r.simulation.is_none() {
        return None;
    }
    let model = r.model.as_ref()?;
    let names = display_mode_names(model);
    // The model's regions as a PWARX model (theta unused by the figure).
    let (spec, regions) = match model {
        Model::Pwarx(m) if m.modes.len() > 1 => (
            m.spec(),
            m.modes.iter().map(|q| q.region.clone()).collect::<Vec<_>>(),
        ),
        Model::HybridAutomaton(a) if a.modes.len() > 1 => automaton_regions(a)?,
        _ => return None,
    };
    if spec.dim() < 2 {
        return None;
    }
    let shape = PwarxModel {
        na: spec.na,
        nb: spec.nb,
        inputs: spec.inputs,
        modes: regions
            .iter()
            .zip(&names)
            .map(|(region, name)| PwarxMode {
                theta: vec![0.0; spec.dim() + 1],
                region: region.clone(),
                name: Some(name.clone()),
            })
            .collect(),
        info: Default::default(),
    };
    let reg = spec.build(valid).ok()?;
    let labels = (0..reg.len())
        .map(|i| {
            let x: Vec<f64> = reg.x.row(i).iter().copied().collect();
            match model {
                Model::Pwarx(m) => Some(m.mode_of(&x).mode),
                // The first full-dimensional region holding the point, else
                // the mode it violates least (a point at or past a stop).
                _ => regions
                    .iter()
                    .position(|p| p.a_eq.is_empty() && p.contains(&x))
                    .or_else(|| {
                        regions
                            .iter()
                            .map(|p| p.violation(&x))
                            .enumerate()
                            .min_by(|a, b| a.1.total_cmp(&b.1))
                            .map(|(k, _)| k)
                    }),
            }
        })
        .collect();
    let axes = if spec.nb >= 1 && spec.inputs >= 1 {
        (0, spec.na)
    } else {
        (0, 1)
    };
    let units = regressor_units(c, &spec);
    let units: Vec<&str> = units.iter().map(String::as_str).collect();
    let what = if matches!(model, Model::HybridAutomaton(_)) {
        "validation regressors by mode, regions and stops sliced at the mean"
    } else {
        "validation regressors by mode, regions sliced at the mean"
    };
    let mut fig = RegionFigure::from_model(
        format!("{}: {what}", r.name),
        &shape,
        &reg,
        labels,
        axes,
        &units,
    );
    let stops: Vec<f64> = regions.iter().filter_map(stop_level).collect();
    if !stops.is_empty() {
        let levels: Vec<String> = stops.iter().map(|l| format!("y(k-1) = {l}")).collect();
        fig.notes.push(format!(
            "Stops at {}: beyond a stop no ordinary mode applies (its region ends there), so the grey band past it is the far side of the stop, not a hole.",
            levels.join(" and ")
        ));
    }
    if let Some(f) = model.info().diagnostics.uncovered_fraction_of_data_box {
        fig.notes.push(format!(
            "The report's {:.2} % in no region is over the box of the identification regressors in all {} coordinates, not this plane.",
            100.0 * f,
            spec.dim()
        ));
    }
    Some(fig)
}

/// The results of the points of sweep `name`, in order.
fn sweep_points<'c>(c: &'c Comparison, name: &str) -> Vec<&'c RunResult> {
    c.results
        .iter()
        .filter(|r| r.sweep.as_ref().is_some_and(|s| s.sweep == name))
        .collect()
}

/// fit_sim and modes against the first varied key (numeric values only),
/// one series per combination of the other keys; `None` when no point was
/// scored.
fn sweep_figure(c: &Comparison, name: &str, points: &[&RunResult]) -> Option<SweepFigure> {
    let first = points.first()?.sweep.as_ref()?;
    let x_key = first.values.first()?.0.clone();
    let mut fit: Vec<SweepSeries> = Vec::new();
    let mut modes: Vec<SweepSeries> = Vec::new();
    for r in points {
        let s = r.sweep.as_ref()?;
        let x: f64 = s.values.first()?.1.parse().ok()?;
        let label = s.values[1..]
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(", ");
        let label = if label.is_empty() {
            name.to_string()
        } else {
            label
        };
        let idx = match fit.iter().position(|f| f.label == label) {
            Some(i) => i,
            None => {
                fit.push(SweepSeries::new(label.clone(), vec![], vec![]));
                modes.push(SweepSeries::new(label, vec![], vec![]));
                fit.len() - 1
            }
        };
        fit[idx].x.push(x);
        fit[idx]
            .y
            .push(r.report.as_ref().map_or(f64::NAN, |v| v.fit_sim));
        modes[idx].x.push(x);
        modes[idx].y.push(r.modes.map_or(f64::NAN, |m| m as f64));
    }
    // A sweep none of whose points was scored has nothing to draw.
    let empty = |panel: &[SweepSeries]| panel.iter().flat_map(|s| &s.y).all(|v| !v.is_finite());
    if empty(&fit) || empty(&modes) {
        return None;
    }
    Some(SweepFigure {
        title: format!(
            "{name}: {} simulation FIT and modes against {x_key}",
            c.scored_rows.word()
        ),
        x_label: format!("{x_key} [{}]", sweep_key_unit(&c.output_label, &x_key)),
        panels: vec![
            SweepPanel {
                y_label: "fit_sim [%]".into(),
                series: fit,
                integer_y: false,
            },
            SweepPanel {
                y_label: "modes [-]".into(),
                series: modes,
                integer_y: true,
            },
        ],
        log_x: false,
    })
}

/// Whether a run's model has regressor orders: not one declared by its
/// physics (mechanical or gray-box), nor, where the run failed, the model
/// of a model file.
fn has_orders(model: Option<&Model>, options: &[(String, String)]) -> bool {
    match model {
        Some(Model::Mechanical(_) | Model::GrayBox(_)) => false,
        Some(_) => true,
        None => !(options.iter()).any(|(k, _)| k == super::experiment::MODEL_FILE_OPTION),
    }
}

/// An error in the output's unit: four decimals, or four significant
/// digits where four decimals would show none (an axis in metres).
fn error_text(x: f64) -> String {
    if x != 0.0 && x.abs() < 1e-3 {
        format!("{x:.3e}")
    } else {
        format!("{x:.4}")
    }
}

/// The report as Markdown, with the links to the figures
/// [`write_report`] drew (none before it runs).
pub fn markdown(c: &Comparison) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# {}\n", c.title);
    if !c.description.trim().is_empty() {
        let _ = writeln!(s, "{}\n", c.description.trim());
    }
    let _ = write!(
        s,
        "Data: {}. {} scores leave out the first {} samples",
        c.data,
        capitalised(c.scored_rows.word()),
        c.warmup
    );
    match &c.warmup_raised {
        None => s.push_str(".\n\n"),
        Some(raised) => {
            let _ = writeln!(
                s,
                ": the warm-up of {} asked for, lengthened so that every run is scored on the \
                 same samples (the simulation of {} starts at sample {}).\n",
                raised.asked, raised.run, c.warmup
            );
        }
    }
    for w in &c.warnings {
        let _ = writeln!(s, "**Warning:** {w}.\n");
    }
    seeds_table(&mut s, c);
    let _ = writeln!(
        s,
        "| run | provenance | method | na | nb | modes | fit_sim [%] | rmse_sim | fit_pred [%] | coverage | time [s] | note |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &c.results {
        let (fs, rs, fp, cov) = match &r.report {
            Some(v) => (
                format!("{:.2}", v.fit_sim),
                error_text(v.rmse_sim),
                format!("{:.2}", v.fit_pred),
                format!("{:.3}", v.coverage),
            ),
            None => ("-".into(), "-".into(), "-".into(), "-".into()),
        };
        let mut note = r.error.clone().unwrap_or_default();
        if let Some(v) = &r.report
            && let Some(k) = v.diverged_at
        {
            note = match v.diverged_to {
                Some(DivergedTo::Undefined) => {
                    format!("simulated output undefined (NaN) at sample {k}")
                }
                _ => format!("simulation diverged at sample {k}"),
            };
        }
        let model_notes = r.model.as_ref().map(|m| {
            [selection_note(m), holes_note(m), status_note(m)]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>()
        });
        for extra in model_notes.into_iter().flatten() {
            note = if note.is_empty() {
                extra
            } else {
                format!("{note}; {extra}")
            };
        }
        let order = |v: usize| {
            if has_orders(r.model.as_ref(), &r.options) {
                v.to_string()
            } else {
                "-".to_string()
            }
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {} |",
            r.name.replace('|', "/"),
            r.origin.label(c.scored_rows),
            r.method,
            order(r.na),
            order(r.nb),
            r.modes.map_or("-".into(), |m| m.to_string()),
            fs,
            rs,
            fp,
            cov,
            r.seconds,
            note.replace('|', "/")
        );
    }
    records_table(&mut s, c);
    mode_recovery_table(&mut s, c);
    figure_links(&mut s, c);
    s
}

/// The list of the figures [`write_report`] drew, as links, into `s`.
fn figure_links(s: &mut String, c: &Comparison) {
    let mut figs: Vec<String> = Vec::new();
    if let Some(f) = &c.drawn.all {
        figs.push(format!("- all runs: [{f}]({f})"));
    }
    for (sweep, f) in &c.drawn.sweeps {
        figs.push(format!("- sweep {sweep}: [{f}]({f})"));
    }
    let mut with_regions = 0;
    for run in &c.drawn.runs {
        let (f, m) = (&run.simulation, &run.modes);
        let mut line = format!("- {}: [{f}]({f}), [{m}]({m})", run.name);
        if let Some(g) = &run.regions {
            let _ = write!(line, ", [{g}]({g})");
            with_regions += 1;
        }
        figs.push(line);
    }
    if !figs.is_empty() {
        let runs = c.results.iter().filter(|r| r.sweep.is_none()).count();
        let drawn = c.drawn.runs.len();
        let points = c.results.len() - runs;
        let mut parts = Vec::new();
        if runs > 0 {
            let mut part = format!(
                "the simulation and the mode sequence of each of the {drawn} of {runs} `[[run]]` entries that produced a validation simulation"
            );
            if with_regions > 0 {
                let _ = write!(
                    part,
                    ", and the regions of the {with_regions} with a region partition to draw (PWARX with two or more modes, automata with stops)"
                );
            }
            parts.push(part);
        }
        if points > 0 {
            parts.push(format!(
                "the {points} sweep points have no figures of their own, only one FIT and mode-count figure per sweep"
            ));
        }
        let what = format!("\nFigures (under plots/): {}", parts.join("; "));
        let _ = writeln!(s, "{what}:\n");
        for f in figs {
            let _ = writeln!(s, "{f}");
        }
    }
}

/// What the back-end said about its run (cut short, warnings), as
/// `hysid identify` prints it.
/// `word` with its first letter in upper case.
fn capitalised(word: &str) -> String {
    let mut chars = word.chars();
    chars
        .next()
        .map(|f| f.to_uppercase().chain(chars).collect())
        .unwrap_or_default()
}

/// What automatic selection chose, with its selection-row FIT.
fn selection_note(m: &Model) -> Option<String> {
    let s = m.info().selection.as_ref()?;
    let c = s.candidates.get(s.chosen)?;
    let values: Vec<String> = s
        .chosen_values()
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    let what = if values.is_empty() {
        format!("the {} model", c.method)
    } else {
        format!("{} {}", c.method, values.join(" "))
    };
    Some(format!(
        "auto chose {what} (selection FIT {:.2} %)",
        c.fit_sim.unwrap_or(f64::NAN)
    ))
}

fn status_note(m: &Model) -> Option<String> {
    m.info().diagnostics.note()
}

/// "regions leave holes" when the back-end reported an incomplete partition
/// (`regions_complete = false`, e.g. HIT's pairwise `psvc` regions), with
/// the uncovered fraction of the data box when known.
fn holes_note(m: &hysid_core::model::Model) -> Option<String> {
    let d = &m.info().diagnostics;
    if d.regions_complete? {
        return None;
    }
    Some(match d.uncovered_fraction_of_data_box {
        Some(f) => format!(
            "regions leave holes: {:.2} % of the data box in no region",
            100.0 * f
        ),
        None => "regions leave holes".into(),
    })
}

/// The table of `[data] truth` scores: accuracy, and per true mode the
/// fraction of its samples simulated in the matched identified mode.
/// Median and range over the seeds of each `[[run]]` with `seeds`: the
/// figure to quote for a stochastic back-end, not its best seed. A run
/// whose fit does not depend on the seed ran once for all its seeds.
fn seeds_table(s: &mut String, c: &Comparison) {
    let mut groups: Vec<&str> = Vec::new();
    for g in c.results.iter().filter_map(|r| r.seed_group.as_deref()) {
        if !groups.contains(&g) {
            groups.push(g);
        }
    }
    if groups.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "Over seeds (each `[[run]]` with `seeds`, {} fit_sim [%], and rmse_sim):\n\n| run | provenance | seeds | scored | median | min | max | rmse_sim median | rmse_sim min | rmse_sim max |\n|---|---|---|---|---|---|---|---|---|---|",
        c.scored_rows.word()
    );
    for g in groups {
        let runs: Vec<&RunResult> = c
            .results
            .iter()
            .filter(|r| r.seed_group.as_deref() == Some(g))
            .collect();
        let scores = |score: fn(&ValidationReport) -> f64| {
            let mut v: Vec<f64> = (runs.iter())
                .filter_map(|r| r.report.as_ref().map(score))
                .collect();
            v.sort_by(f64::total_cmp);
            v
        };
        let mut fits = scores(|v| v.fit_sim);
        let mut errors = scores(|v| v.rmse_sim);
        let (lowest, highest) = (fits.first().copied(), fits.last().copied());
        let (least, most) = (errors.first().copied(), errors.last().copied());
        let show = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2}"));
        let error = |v: Option<f64>| v.map_or("-".into(), error_text);
        let standing: usize = runs.iter().map(|r| r.same_for_seeds.len()).sum();
        let seeds = if standing == 0 {
            runs.len().to_string()
        } else {
            format!(
                "{} (one run: the fit does not depend on the seed)",
                runs.len() + standing
            )
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            g.replace('|', "/"),
            runs[0].origin.label(c.scored_rows),
            seeds,
            fits.len(),
            show(median(&mut fits)),
            show(lowest),
            show(highest),
            error(median(&mut errors)),
            error(least),
            error(most),
        );
    }
    s.push('\n');
}

/// When the scored rows join several records: each run's `fit_sim` on each
/// record (the table above pools them).
fn records_table(s: &mut String, c: &Comparison) {
    let count = c
        .results
        .iter()
        .filter_map(|r| r.report.as_ref())
        .map(|v| v.records.len())
        .max()
        .unwrap_or(0);
    if count == 0 {
        return;
    }
    let _ = writeln!(
        s,
        "
Per record ({} fit_sim [%], each record from its own initial state and warm-up; the table above pools their scored samples):
",
        c.scored_rows.word()
    );
    let heads: Vec<String> = (0..count)
        .map(|i| match c.scored_records.get(i) {
            Some(label) => label.replace('|', "/"),
            None => format!("record {}", i + 1),
        })
        .collect();
    let _ = writeln!(s, "| run | {} |", heads.join(" | "));
    let _ = writeln!(s, "|---|{}", "---|".repeat(count));
    for r in &c.results {
        let Some(v) = &r.report else { continue };
        let cells: Vec<String> = v
            .records
            .iter()
            .map(|p| format!("{:.2}", p.fit_sim))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} |",
            r.name.replace('|', "/"),
            cells.join(" | ")
        );
    }
}

fn mode_recovery_table(s: &mut String, c: &Comparison) {
    let mut names: Vec<&str> = Vec::new();
    for r in c.results.iter().filter_map(|r| r.mode_recovery.as_ref()) {
        for (n, _, _) in &r.recall {
            if !names.contains(&n.as_str()) {
                names.push(n);
            }
        }
    }
    if names.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\nMode recovery against the true modes of the record (`[data] truth`): the validation simulation's modes after the warm-up, up to a divergence, matched to the true modes by the Hungarian method; per true mode, the fraction of its samples simulated in the matched mode:\n"
    );
    let _ = writeln!(
        s,
        "| run | samples scored | mode accuracy | {} |",
        names.join(" | ")
    );
    let _ = writeln!(s, "|---|---|---|{}", "---|".repeat(names.len()));
    for r in &c.results {
        let Some(m) = &r.mode_recovery else { continue };
        let cells: Vec<String> = names
            .iter()
            .map(|n| {
                m.recall
                    .iter()
                    .find(|(x, _, _)| x == n)
                    .map_or("-".into(), |(_, _, v)| format!("{v:.3}"))
            })
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {} |",
            r.name.replace('|', "/"),
            m.samples,
            m.accuracy,
            cells.join(" | ")
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_model::model::{Stop, StopBound};

    /// Errors too small for four decimals keep four significant digits.
    #[test]
    fn small_errors_keep_their_digits() {
        assert_eq!(error_text(1.54236), "1.5424");
        assert_eq!(error_text(0.005027), "0.0050");
        assert_eq!(error_text(3.2549e-5), "3.255e-5");
        assert_eq!(error_text(0.0), "0.0000");
    }

    /// A run cut short or with warnings gets its status in the report's
    /// note; a completed run without messages gets none.
    #[test]
    fn status_notes_come_from_the_typed_diagnostics() {
        use hysid_model::model::{ModelInfo, RunStatus};
        let mut m = PwarxModel {
            na: 1,
            nb: 1,
            inputs: 1,
            modes: vec![],
            info: ModelInfo::default(),
        };
        assert_eq!(status_note(&Model::Pwarx(m.clone())), None);
        m.info.diagnostics.run_status = RunStatus::IterationLimit;
        m.info.diagnostics.status = vec!["iteration limit reached".into()];
        assert_eq!(
            status_note(&Model::Pwarx(m)).as_deref(),
            Some("iteration limit reached")
        );
    }

    #[test]
    fn a_physical_model_has_no_regressor_orders() {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../models/pick-and-place/head-fitted.json");
        let head = Model::load(&file).unwrap();
        assert!(!has_orders(Some(&head), &[]));
        // A run that failed has no model: one of a model file has no
        // orders either.
        assert!(has_orders(None, &[]));
        let file = vec![("model".to_string(), "head.toml".to_string())];
        assert!(!has_orders(None, &file));
    }

    #[test]
    fn units_come_from_the_labels() {
        assert_eq!(unit_of("head position y [mm]"), "mm");
        assert_eq!(unit_of("motor input u [-]"), "-");
        assert_eq!(unit_of("output y"), "-");
        assert_eq!(unit_of("a [b] c [ V ]"), "V");
        assert_eq!(sweep_key_unit("y [mm]", "delta"), "mm");
        assert_eq!(sweep_key_unit("y [mm]", "c"), "-");
    }

    #[test]
    fn automaton_stops_read_back_as_guard_lines_in_regressor_space() {
        // na = nb = 2, one input: regressor [y(k-1), y(k-2), u(k-1), u(k-2)].
        let region =
            |sign: f64| Polyhedron::from_inequalities(vec![vec![0.0, 0.0, sign, 0.0]], vec![0.0]);
        let pwarx = PwarxModel {
            na: 2,
            nb: 2,
            inputs: 1,
            modes: vec![
                PwarxMode {
                    theta: vec![1.5, -0.6, 0.2, 0.1, 0.0],
                    region: region(1.0),
                    name: None,
                },
                PwarxMode {
                    theta: vec![1.4, -0.5, 0.3, 0.0, 0.0],
                    region: region(-1.0),
                    name: None,
                },
            ],
            info: Default::default(),
        };
        let stop = Stop {
            level: 25.0,
            bound: StopBound::Max,
            tol: None,
        };
        let a = HybridAutomaton::from_pwarx_with_stops(&pwarx, &[stop]);
        let (spec, regions) = automaton_regions(&a).expect("ARX-form automaton");
        assert_eq!((spec.na, spec.nb, spec.inputs), (2, 2, 1));
        assert_eq!(regions.len(), 3);
        // The ordinary regions come back in regressor order, with the
        // allowed side y(k-1) <= 25 added.
        assert_eq!(regions[0].a[0], vec![0.0, 0.0, 1.0, 0.0]);
        assert_eq!(regions[0].a[1], vec![1.0, 0.0, 0.0, 0.0]);
        assert_eq!(regions[0].b, vec![0.0, 25.0]);
        assert_eq!(regions[1].a[0], vec![0.0, 0.0, -1.0, 0.0]);
        // The stop is the guard set y(k-1) = 25.
        assert_eq!(stop_level(&regions[2]), Some(25.0));
        assert_eq!(stop_level(&regions[0]), None);
        let names = display_mode_names(&Model::HybridAutomaton(a));
        assert_eq!(names, ["mode 1", "mode 2", "sat_max_25: stop y = 25"]);
    }

    #[test]
    fn slugs_are_file_names() {
        assert_eq!(super::slug("cluster [c=55]"), "cluster__c_55");
        assert_eq!(super::slug("arx(2,2)"), "arx_2_2");
    }
}
