//! Convenience constructors from hysid-core types (a [`Dataset`], a
//! [`Simulation`], [`Regressors`], a [`PwarxModel`]). The figures stay plain
//! data; these only fill them in.

use hysid_model::data::Dataset;
use hysid_model::model::PwarxModel;
use hysid_model::regressors::Regressors;
use hysid_model::simulate::Simulation;

use crate::{ModeSequence, RegionFigure, Series, SimulationFigure, time_axis};

impl SimulationFigure {
    /// The measured output and inputs of `data`, with its time axis (seconds
    /// when `data.ts` is known, else the sample index), no simulated run yet.
    /// `first_row` is the row of the record where `data` starts (e.g. 5000
    /// for the validation range), so that times match the record.
    pub fn from_dataset(
        title: impl Into<String>,
        data: &Dataset,
        first_row: usize,
        output_label: impl Into<String>,
        input_label: impl Into<String>,
    ) -> Self {
        let (time, time_label) = time_axis(data.len(), data.ts, first_row);
        Self {
            title: title.into(),
            time,
            time_label,
            output_label: output_label.into(),
            measured: Series::new(
                format!("measured {}", data.output.name),
                data.output.values.clone(),
            ),
            simulated: Vec::new(),
            input_label: input_label.into(),
            inputs: data
                .inputs
                .iter()
                .map(|s| Series::new(s.name.clone(), s.values.clone()))
                .collect(),
            warm_ups: Vec::new(),
            record_starts: data.record_ranges().iter().map(|r| r.start).collect(),
        }
    }

    /// Adds a simulated (or predicted) run. Samples before `sim.start` are
    /// copies of the measured initial outputs, not simulated, so they are
    /// left out (NaN).
    pub fn with_simulation(mut self, label: impl Into<String>, sim: &Simulation) -> Self {
        let values = sim
            .y
            .iter()
            .enumerate()
            .map(|(k, &v)| if k < sim.start { f64::NAN } else { v })
            .collect();
        self.simulated.push(Series::new(label, values));
        self
    }

    /// Marks the first `warmup` samples of each record as warm-up (not
    /// scored).
    pub fn with_warmup(mut self, warmup: usize) -> Self {
        let at = |k: usize| self.time.get(k).copied();
        let starts: &[usize] = if self.record_starts.is_empty() {
            &[0]
        } else {
            &self.record_starts
        };
        self.warm_ups = starts
            .iter()
            .filter_map(|&k| Some((at(k)?, at(k + warmup)?)))
            .collect();
        self
    }
}

impl ModeSequence {
    /// The active modes of a simulation (`None` before its start and
    /// outside every region).
    pub fn from_simulation(label: impl Into<String>, sim: &Simulation) -> Self {
        Self::new(label, sim.modes.clone())
    }
}

impl RegionFigure {
    /// Regressor rows as points, their modes as labels, the regions and mode
    /// names of `model`, and the other coordinates fixed at the mean of the
    /// regressors. Axis labels are the regressor names written with their
    /// lags (`y1` is `y(k-1)`, `u2_1` is `u2(k-1)`)
    /// followed by `unit` of each, e.g. `["mm", "mm", "-", "-"]`; an empty
    /// `units` gives `[-]`.
    pub fn from_model(
        title: impl Into<String>,
        model: &PwarxModel,
        regressors: &Regressors,
        labels: Vec<Option<usize>>,
        axes: (usize, usize),
        units: &[&str],
    ) -> Self {
        let names: Vec<String> = model
            .spec()
            .regressor_names()
            .iter()
            .map(|n| lagged_name(n))
            .collect();
        let points: Vec<Vec<f64>> = (0..regressors.x.nrows())
            .map(|r| regressors.x.row(r).iter().copied().collect())
            .collect();
        let fixed = column_means(&points, names.len());
        let label = |k: usize| {
            format!(
                "{} [{}]",
                names.get(k).map_or("x", String::as_str),
                units.get(k).copied().unwrap_or("-")
            )
        };
        Self {
            title: title.into(),
            x_label: label(axes.0),
            y_label: label(axes.1),
            axes,
            fixed,
            coordinate_names: names.clone(),
            points,
            labels,
            regions: model.modes.iter().map(|m| m.region.clone()).collect(),
            mode_names: model
                .modes
                .iter()
                .enumerate()
                .map(|(k, m)| hysid_model::model::mode_name(m.name.as_deref(), k))
                .collect(),
            bounds: None,
            notes: Vec::new(),
        }
    }
}

/// A regressor name of [`hysid_model::regressors::RegressorSpec::regressor_names`]
/// with its lag spelled out: `y2` becomes `y(k-2)`, `u1_3` becomes
/// `u1(k-3)`; any other name is returned unchanged.
pub fn lagged_name(name: &str) -> String {
    let (signal, lag) = match name.split_once('_') {
        Some((s, lag)) => (s.to_string(), lag),
        None => match name.char_indices().find(|(_, c)| c.is_ascii_digit()) {
            Some((i, _)) => (name[..i].to_string(), &name[i..]),
            None => return name.to_string(),
        },
    };
    if signal.is_empty() || lag.is_empty() || !lag.chars().all(|c| c.is_ascii_digit()) {
        return name.to_string();
    }
    format!("{signal}(k-{lag})")
}

/// Mean of each of the `dim` coordinates over the finite values of
/// `points` (0 for a coordinate with none): the usual place to slice.
pub fn column_means(points: &[Vec<f64>], dim: usize) -> Vec<f64> {
    (0..dim)
        .map(|k| {
            let (s, n) = points
                .iter()
                .filter_map(|p| p.get(k).copied().filter(|v| v.is_finite()))
                .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
            if n == 0 { 0.0 } else { s / n as f64 }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_model::geometry::Polyhedron;
    use hysid_model::model::{ModelInfo, PwarxMode};

    #[test]
    fn lags_are_spelled_out() {
        assert_eq!(lagged_name("y1"), "y(k-1)");
        assert_eq!(lagged_name("u12"), "u(k-12)");
        assert_eq!(lagged_name("u2_3"), "u2(k-3)");
        assert_eq!(lagged_name("speed"), "speed");
        assert_eq!(lagged_name("7"), "7");
    }

    #[test]
    fn means_skip_non_finite_values() {
        let p = vec![vec![1.0, f64::NAN], vec![3.0, 2.0]];
        assert_eq!(column_means(&p, 3), vec![2.0, 2.0, 0.0]);
    }

    #[test]
    fn figures_from_core_types() {
        let data = Dataset::siso(
            vec![0.0, 1.0, 0.0, 1.0],
            vec![0.0, 0.5, 0.2, 0.7],
            Some(0.01),
        )
        .unwrap();
        let sim = Simulation {
            y: vec![0.0, 0.4, 0.3, 0.6],
            modes: vec![None, Some(0), Some(1), Some(0)],
            start: 1,
            covered: vec![true; 4],
            diverged_at: None,
            diverged_to: None,
            zeno: None,
        };
        let fig = SimulationFigure::from_dataset("t", &data, 100, "y [mm]", "u [-]")
            .with_simulation("model", &sim)
            .with_warmup(2);
        assert_eq!(fig.time[0], 1.0);
        assert_eq!(fig.time_label, "time t [s]");
        assert!(fig.simulated[0].values[0].is_nan());
        assert_eq!(&fig.simulated[0].values[1..], &[0.4, 0.3, 0.6]);
        assert_eq!(fig.warm_ups, [(1.0, 1.02)]);
        assert_eq!(fig.inputs.len(), 1);
        crate::simulation_svg(&fig).unwrap();
        assert_eq!(ModeSequence::from_simulation("m", &sim).modes, sim.modes);
        // Joined records: each record's warm-up is shaded.
        let joined = Dataset::join(&[data.clone(), data.clone()]).unwrap();
        let fig =
            SimulationFigure::from_dataset("t", &joined, 100, "y [mm]", "u [-]").with_warmup(2);
        assert_eq!(fig.record_starts, [0, 4]);
        assert_eq!(fig.warm_ups, [(1.0, 1.02), (1.04, 1.06)]);
        crate::simulation_svg(&fig).unwrap();

        let model = PwarxModel {
            na: 1,
            nb: 1,
            inputs: 1,
            modes: vec![
                PwarxMode {
                    theta: vec![0.5, 1.0, 0.0],
                    region: Polyhedron::from_inequalities(vec![vec![1.0, 0.0]], vec![0.3]),
                    name: Some("low".into()),
                },
                PwarxMode {
                    theta: vec![0.2, 1.0, 0.1],
                    region: Polyhedron::from_inequalities(vec![vec![-1.0, 0.0]], vec![-0.3]),
                    name: None,
                },
            ],
            info: ModelInfo::default(),
        };
        let regs = model.spec().build(&data).unwrap();
        let labels = (0..regs.len()).map(|_| Some(0)).collect();
        let rf = RegionFigure::from_model("r", &model, &regs, labels, (0, 1), &["mm", "-"]);
        assert_eq!(rf.x_label, "y(k-1) [mm]");
        assert_eq!(rf.y_label, "u(k-1) [-]");
        assert_eq!(rf.mode_names, vec!["low".to_string(), "mode 2".to_string()]);
        assert_eq!(rf.points.len(), regs.len());
        assert_eq!(rf.points[0], vec![regs.x[(0, 0)], regs.x[(0, 1)]]);
        crate::regions_svg(&rf).unwrap();
    }
}
