//! Multiple shooting ([`segmented`]): the record cut into segments, each
//! simulated from the measured rule's state at its start. Segments are
//! independent: groups of them run in parallel, each group on a machine
//! of its own, and are joined in segment order, so the run is the same
//! for any number of threads and any grouping.

use super::sensitivity::columns;
use super::{
    CompiledInitial, GrayBoxRun, Kept, Machine, Schedule, Sensitivities, carried, free_run,
    measured_state, span, timing,
};
use crate::compile::CompiledModel;
use hysid_model::data::Dataset;
use hysid_model::simulate::{SEGMENTS_PER_TASK, SimError};
use rayon::prelude::*;
use std::ops::Range;

/// Multiple shooting: the record cut into segments of `segment` samples,
/// each simulated from the measured rule's state at its first sample `s`
/// (the position from the output, the velocity from the output's slope
/// `slope_at(s)`, the estimated states from the free run from
/// `estimates`; the mode: the first whose invariant holds). Returns the
/// outputs of every sample: the first sample's is its initial state's,
/// every other is the one its segment simulated (a boundary sample: the
/// earlier segment's). A model without the measured rule gives its free
/// run from `estimates`.
pub fn segmented(
    m: &CompiledModel,
    values: &[f64],
    estimates: &[f64],
    data: &Dataset,
    segment: usize,
    slope_at: &(dyn Fn(usize) -> f64 + Sync),
) -> Result<Vec<f64>, SimError> {
    let segments = Segments::of(segment, slope_at);
    shoot(m, values, estimates, data, segments, false).map(|r| r.y)
}

/// [`segmented`]'s outputs and their derivatives in the parameters and
/// the estimated states (as [`run_with_sensitivities`](super::run_with_sensitivities); a segment's start
/// depends on the parameters through the output map, its estimated states
/// through the free run's).
pub fn segmented_with_sensitivities(
    m: &CompiledModel,
    values: &[f64],
    estimates: &[f64],
    data: &Dataset,
    segment: usize,
    slope_at: &(dyn Fn(usize) -> f64 + Sync),
) -> Result<(Vec<f64>, Sensitivities), SimError> {
    let run = shoot(
        m,
        values,
        estimates,
        data,
        Segments::of(segment, slope_at),
        true,
    )?;
    let sensitivities = run
        .sensitivities
        .ok_or_else(|| SimError::InvalidModel("no sensitivities were carried".into()))?;
    Ok((run.y, sensitivities))
}

/// [`segmented`], with the sensitivities when `differentiate`.
fn shoot(
    m: &CompiledModel,
    values: &[f64],
    estimates: &[f64],
    data: &Dataset,
    segments: Segments<'_>,
    differentiate: bool,
) -> Result<GrayBoxRun, SimError> {
    if !matches!(m.initial, CompiledInitial::Measured { .. }) {
        return free_run(m, values, estimates, data, differentiate, Kept::Output);
    }
    let free = if m.estimates.is_empty() {
        None
    } else {
        Some(free_run(
            m,
            values,
            estimates,
            data,
            differentiate,
            Kept::Everything,
        )?)
    };
    let ts = timing(m, data)?;
    let bound = m.bind(values);
    let shooting = Shooting {
        m,
        bound: &bound,
        values,
        schedule: Schedule::new(&bound, ts),
        data,
        free: free.as_ref(),
        segments,
        differentiate,
    };
    let starts: Vec<usize> = (0..data.len().saturating_sub(1))
        .step_by(segments.length)
        .collect();
    let per_task = segments.per_task.unwrap_or_else(|| {
        // A machine forms its closed-form steps and sliding models as it
        // meets their regimes: no more tasks than threads.
        SEGMENTS_PER_TASK.max(starts.len().div_ceil(rayon::current_num_threads()))
    });
    let groups = starts
        .par_chunks(per_task)
        .map(|group| shooting.group(group))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(shooting.join(groups))
}

/// The velocity a segment starts with, by its first sample.
type SlopeAt<'a> = dyn Fn(usize) -> f64 + Sync + 'a;

/// How a record is cut: segments of `length` samples starting with the
/// velocities `slope_at`, `per_task` of them to a parallel task (`None`:
/// at least [`SEGMENTS_PER_TASK`], and one task per thread).
#[derive(Clone, Copy)]
struct Segments<'a> {
    length: usize,
    slope_at: &'a SlopeAt<'a>,
    per_task: Option<usize>,
}

impl<'a> Segments<'a> {
    /// Segments of `segment` samples (at least 1), as many to a task as
    /// the threads need.
    fn of(segment: usize, slope_at: &'a SlopeAt<'a>) -> Self {
        Segments {
            length: segment.max(1),
            slope_at,
            per_task: None,
        }
    }
}

/// What the segments of [`segmented`] share.
struct Shooting<'a> {
    m: &'a CompiledModel,
    /// `m` with its parameters bound to `values`.
    bound: &'a CompiledModel,
    values: &'a [f64],
    schedule: Schedule,
    data: &'a Dataset,
    /// The free run the estimated states are carried from.
    free: Option<&'a GrayBoxRun>,
    segments: Segments<'a>,
    differentiate: bool,
}

impl Shooting<'_> {
    /// The segments starting at `starts` (consecutive), each from the
    /// measured rule's state at its start, on a machine of their own: the
    /// run whose rows from the first start to the last segment's end are
    /// theirs.
    fn group(&self, starts: &[usize]) -> Result<(Range<usize>, GrayBoxRun), SimError> {
        let (m, data, n) = (self.m, self.data, self.data.len());
        let first = starts.first().copied().unwrap_or(0);
        let last = starts
            .last()
            .map_or(first, |&s| (s + self.segments.length).min(n - 1));
        let rows = first..last + 1;
        let mut machine = Machine::new(self.bound, self.values);
        machine.strict_resets = false;
        let mut out = GrayBoxRun::empty(data, m.states, first, Kept::Output);
        if self.differentiate {
            machine.differentiate(m);
            out.sensitivities = machine.sensitivities_for(rows.clone());
        }
        let mut u = vec![0.0; m.inputs];
        for &s in starts {
            self.schedule.inputs(data, s, 0.0, &mut u);
            let free = self.free;
            let at_s = free.map(|r| carried(m, r, s)).unwrap_or_default();
            let estimated = free
                .and_then(|r| r.sensitivities.as_ref())
                .map(|d| d.estimated_rows(m, s));
            machine.tangent_start(estimated.as_deref());
            let x = measured_state(
                self.bound,
                &mut machine,
                (data, &self.schedule),
                s,
                &at_s,
                (self.segments.slope_at)(s),
                0.0,
            )?;
            let hs = machine.state_at(x, &u, None);
            let end = (s + self.segments.length + 1).min(n);
            // The previous segment's last sample stays: this one starts there.
            let kept =
                (s > first).then(|| (out.y[s], out.sensitivities.as_ref().map(|d| d.row(s))));
            span(&mut machine, hs, data, s..end, &self.schedule, &mut out)?;
            if let Some((y, sensitivities)) = kept {
                out.y[s] = y;
                if let (Some(d), Some(before)) = (out.sensitivities.as_mut(), sensitivities) {
                    d.copy_rows(&before, s..s + 1);
                }
            }
        }
        Ok((rows, out))
    }

    /// The groups' runs joined in segment order: a group's first row is
    /// the previous group's last.
    fn join(&self, groups: Vec<(Range<usize>, GrayBoxRun)>) -> GrayBoxRun {
        let (m, n) = (self.m, self.data.len());
        let mut out = GrayBoxRun::empty(self.data, m.states, 0, Kept::Output);
        if self.differentiate {
            out.sensitivities = Some(Sensitivities::zeros(0..n, m.states, columns(m)));
        }
        for (rows, group) in groups {
            let rows = if rows.start == 0 {
                rows
            } else {
                rows.start + 1..rows.end
            };
            out.y[rows.clone()].copy_from_slice(&group.y[rows.clone()]);
            if let (Some(all), Some(part)) = (out.sensitivities.as_mut(), &group.sensitivities) {
                all.copy_rows(part, rows);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::linear::tests::{head, head_record, model_files};
    use crate::simulate::run;
    use proptest::prelude::*;

    /// `data` with its output replaced by `y` moved by a small wave, so
    /// that segments start near, not on, the model's own trajectory.
    fn measured(data: &Dataset, y: &[f64]) -> Dataset {
        let wave = y
            .iter()
            .enumerate()
            .map(|(k, v)| v + 1e-3 * (0.37 * k as f64).sin());
        Dataset::siso(data.inputs[0].values.clone(), wave.collect(), data.ts).unwrap()
    }

    /// The segmented run of `m` with sensitivities, `per_task` segments
    /// of 40 samples to a task: its outputs and sensitivities, as bits.
    fn bits(m: &CompiledModel, values: &[f64], data: &Dataset, per_task: usize) -> Vec<Vec<u64>> {
        let y = data.y().to_vec();
        let slope = move |k: usize| (y[(k + 1).min(y.len() - 1)] - y[k]) / 0.01;
        let segments = Segments {
            length: 40,
            slope_at: &slope,
            per_task: Some(per_task),
        };
        let r = shoot(m, values, &[], data, segments, true).unwrap();
        let s = r.sensitivities.unwrap();
        [&r.y, &s.dy, &s.dx]
            .iter()
            .map(|v| v.iter().map(|x| x.to_bits()).collect())
            .collect()
    }

    /// Every model file, from its own free run: the same bits whether each
    /// segment runs on a machine of its own, three to a machine or all on
    /// one.
    #[test]
    fn segments_run_the_same_in_any_grouping() {
        let files = model_files();
        for (path, g, ex) in &files {
            let m = CompiledModel::new(g).unwrap();
            let u = ex.generate(1).remove(0);
            let data = Dataset::siso(u, vec![0.0; ex.n], ex.ts).unwrap();
            let free = run(&m, &g.values(), &data).unwrap();
            let data = measured(&data, &free.y);
            let one = bits(&m, &g.values(), &data, usize::MAX);
            for per_task in [1, 3] {
                let grouped = bits(&m, &g.values(), &data, per_task);
                assert!(grouped == one, "{}, {per_task} per task", path.display());
            }
        }
        assert!(files.len() >= 30, "{} files", files.len());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]

        /// The head anywhere in its parameters' bounds: the same bits in
        /// any grouping of its segments.
        #[test]
        fn the_head_shoots_the_same_in_any_grouping(z in prop::collection::vec(0.0f64..1.0, 12), seed in 0u64..1000) {
            let g = head(&z);
            let m = CompiledModel::new(&g).unwrap();
            let record = head_record(seed);
            let free = run(&m, &g.values(), &record).unwrap();
            let data = measured(&record, &free.y);
            let one = bits(&m, &g.values(), &data, usize::MAX);
            prop_assert!(bits(&m, &g.values(), &data, 1) == one);
            prop_assert!(bits(&m, &g.values(), &data, 5) == one);
        }
    }
}
