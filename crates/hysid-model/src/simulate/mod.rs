//! Free-run simulation and one-step prediction of every model kind.
//!
//! Policies, the same for every model (documented in `docs/simulation.md`):
//!
//! - **Outside every region/invariant**: the mode of least violation
//!   (smallest Euclidean distance) is used, never NaN; the step is counted
//!   in [`Simulation::covered`].
//! - **Divergence**: when the output leaves `[-bound, bound]` or is not
//!   finite, the simulation stops there, the output is held at the clamped
//!   value (at 0 after an undefined one) and [`Simulation::diverged_at`]
//!   reports the sample, [`Simulation::diverged_to`] how.
//! - **Initial conditions**: PWARX models start from the first `max(na, nb)`
//!   measured outputs; automata from their [`InitialState`](crate::model::InitialState) rule.

pub mod automaton;
pub mod pwarx;

use crate::data::Dataset;

/// Segments of a segmented (multiple-shooting) run given to one parallel
/// task: enough work (8 segments of 100 samples by default) to outweigh
/// the task's cost. Groups of segments are joined in order, so the run is
/// the same for any number of threads.
pub const SEGMENTS_PER_TASK: usize = 8;

/// Options of a simulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulationOptions {
    /// Output magnitude beyond which the simulation counts as diverged.
    pub bound: f64,
}

impl Default for SimulationOptions {
    fn default() -> Self {
        Self { bound: 1e9 }
    }
}

impl SimulationOptions {
    /// A bound of 1000 times the measured output's scale (max |y| plus its range).
    pub fn for_data(data: &Dataset) -> Self {
        let y = data.y();
        let (lo, hi) = y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let scale = if y.is_empty() {
            1.0
        } else {
            hi.abs().max(lo.abs()) + (hi - lo)
        };
        Self {
            bound: 1e3 * scale.max(1.0),
        }
    }
}

/// Result of a simulation or prediction over a record of N samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Simulation {
    /// Output, N samples; entries before `start` are the measured initial
    /// outputs (or the output of the initial state).
    pub y: Vec<f64>,
    /// Active mode per sample (`None` before `start`).
    pub modes: Vec<Option<usize>>,
    /// First simulated sample.
    pub start: usize,
    /// Per sample: false when the step that produced it used the
    /// least-violation policy (outside every region/invariant).
    pub covered: Vec<bool>,
    /// Sample at which the output diverged, if it did.
    pub diverged_at: Option<usize>,
    /// How it diverged, where it did.
    pub diverged_to: Option<DivergedTo>,
    /// The integration sub-steps that reached the Zeno bound, if any did.
    pub zeno: Option<ZenoSteps>,
}

/// How a simulated output diverged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DivergedTo {
    /// Its magnitude passed the bound ([`SimulationOptions::bound`]), or
    /// infinity.
    Bound,
    /// It became undefined (NaN): a flow, a reset or the output map gave an
    /// undefined value (the square root or logarithm of a negative number,
    /// `0/0`, ...).
    Undefined,
}

/// Integration sub-steps of a hybrid model's run that reached the bound of
/// events per sub-step (a Zeno point: a transition firing again and
/// again): the rest of each ran without events, so a guard may have been
/// passed through.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ZenoSteps {
    /// The first sample in which one did.
    pub first: usize,
    /// How many did.
    pub steps: usize,
}

impl ZenoSteps {
    /// One more such sub-step in sample `k` of `zeno` (`None`: none yet).
    pub fn add(zeno: &mut Option<ZenoSteps>, k: usize) {
        let z = zeno.get_or_insert(ZenoSteps { first: k, steps: 0 });
        z.steps += 1;
    }

    /// The two counts of consecutive parts, `later`'s samples from `at`.
    fn joined(earlier: Option<Self>, later: Option<Self>, at: usize) -> Option<Self> {
        match (earlier, later) {
            (Some(a), Some(b)) => Some(ZenoSteps {
                first: a.first,
                steps: a.steps + b.steps,
            }),
            (a, b) => a.or(b.map(|b| ZenoSteps {
                first: b.first + at,
                ..b
            })),
        }
    }
}

impl std::fmt::Display for ZenoSteps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} integration sub-step(s), the first in sample {}, reached the bound of events \
             per sub-step (a Zeno point: a transition firing again and again); the rest of each ran without \
             events, so a guard may have been passed through (a contact that comes to rest is a \
             `stop` element, or a resting mode)",
            self.steps, self.first
        )
    }
}

/// What the user of a run should be told about it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimulationWarning {
    /// The output diverged at this sample, as said, and is held from there
    /// on.
    Diverged(usize, DivergedTo),
    /// Sub-steps reached the Zeno bound.
    Zeno(ZenoSteps),
}

impl SimulationWarning {
    /// The warnings of a run that diverged at `diverged_at` (to
    /// `diverged_to`) and reached the Zeno bound in `zeno`.
    pub fn of(
        diverged_at: Option<usize>,
        diverged_to: Option<DivergedTo>,
        zeno: Option<ZenoSteps>,
    ) -> Vec<Self> {
        let to = diverged_to.unwrap_or(DivergedTo::Bound);
        let zeno = zeno.map(SimulationWarning::Zeno);
        (diverged_at
            .map(|k| SimulationWarning::Diverged(k, to))
            .into_iter())
        .chain(zeno)
        .collect()
    }
}

impl DivergedTo {
    /// How the output value `v`, not finite or past the bound, diverged.
    pub fn of(v: f64) -> Self {
        if v.is_nan() {
            DivergedTo::Undefined
        } else {
            DivergedTo::Bound
        }
    }
}

/// Where and how a simulated output diverged, said as its cause (without
/// what the simulator then does).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Divergence {
    /// The sample.
    pub at: usize,
    /// How.
    pub to: DivergedTo,
}

impl std::fmt::Display for Divergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let k = self.at;
        match self.to {
            DivergedTo::Bound => write!(f, "the simulation diverged at sample {k}"),
            DivergedTo::Undefined => write!(
                f,
                "the simulated output became undefined (NaN) at sample {k}: a flow, a reset or \
                 the output map gave an undefined value (the square root or logarithm of a \
                 negative number, 0/0, ...)"
            ),
        }
    }
}

impl std::fmt::Display for SimulationWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            SimulationWarning::Diverged(at, to) => {
                let held = match to {
                    DivergedTo::Bound => "held",
                    DivergedTo::Undefined => "held at 0",
                };
                write!(
                    f,
                    "{}; the output is {held} from there on",
                    Divergence { at, to }
                )
            }
            SimulationWarning::Zeno(z) => z.fmt(f),
        }
    }
}

impl Simulation {
    /// What the user of this run should be told ([`SimulationWarning`]).
    pub fn warnings(&self) -> Vec<SimulationWarning> {
        SimulationWarning::of(self.diverged_at, self.diverged_to, self.zeno)
    }

    /// Records a new output sample, detecting divergence. Returns false when
    /// the simulation must stop.
    pub fn push_checked(&mut self, k: usize, v: f64, bound: f64) -> bool {
        if v.is_finite() && v.abs() <= bound {
            self.y[k] = v;
            true
        } else {
            let held = if v.is_nan() {
                0.0
            } else {
                v.clamp(-bound, bound)
            };
            if self.diverged_at.is_none() {
                self.diverged_at = Some(k);
                self.diverged_to = Some(DivergedTo::of(v));
            }
            for yk in &mut self.y[k..] {
                *yk = held;
            }
            false
        }
    }
}

/// Simulates every record of `data` on its own with `run` (each from its
/// own initial state) and joins the simulations in the dataset's order:
/// `start` is the first record's, and a later record's samples before its
/// own start keep its initial outputs with no mode. One record: `run(data)`.
pub fn per_record(
    data: &Dataset,
    mut run: impl FnMut(&Dataset) -> Result<Simulation, SimError>,
) -> Result<Simulation, SimError> {
    if data.record_count() == 1 {
        return run(data);
    }
    let parts = data
        .records()
        .iter()
        .enumerate()
        .map(|(i, r)| {
            run(r).map_err(|e| SimError::InRecord {
                record: i + 1,
                source: Box::new(e),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Simulation::join(parts, &data.record_ranges()))
}

impl Simulation {
    /// The simulations of consecutive records joined, part `i` of the
    /// samples `ranges[i]` ([`per_record`]).
    pub fn join(parts: Vec<Simulation>, ranges: &[std::ops::Range<usize>]) -> Simulation {
        let mut parts = parts.into_iter();
        let mut joined = parts.next().unwrap_or(Simulation {
            y: Vec::new(),
            modes: Vec::new(),
            start: 0,
            covered: Vec::new(),
            diverged_at: None,
            diverged_to: None,
            zeno: None,
        });
        for (part, at) in parts.zip(ranges.iter().skip(1).map(|r| r.start)) {
            joined.modes.extend(
                part.modes
                    .iter()
                    .enumerate()
                    .map(|(k, q)| if k < part.start { None } else { *q }),
            );
            joined.y.extend(part.y);
            joined.covered.extend(part.covered);
            if joined.diverged_at.is_none() {
                joined.diverged_at = part.diverged_at.map(|k| k + at);
                joined.diverged_to = part.diverged_to;
            }
            joined.zeno = ZenoSteps::joined(joined.zeno, part.zeno, at);
        }
        joined
    }
}

/// Errors of simulation set-up (bad data for this model).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// Wrong number of inputs.
    #[error("the model has {expected} input(s), the data {found}")]
    Inputs {
        /// Model's.
        expected: usize,
        /// Data's.
        found: usize,
    },
    /// Too few samples for the initial condition.
    #[error("the record has {samples} samples; the model needs more than {needed}")]
    TooShort {
        /// Samples.
        samples: usize,
        /// Needed for the initial condition.
        needed: usize,
    },
    /// A record of a dataset that joins several (counted from 1).
    #[error("record {record}: {source}")]
    InRecord {
        /// The record, counted from 1.
        record: usize,
        /// What went wrong in it.
        source: Box<SimError>,
    },
    /// A continuous-time model needs the sampling time.
    #[error(
        "a continuous-time model needs the sampling time: give a 't' signal, or the sampling time (the program's --ts, or ts= in its --excite; Python's ts=)"
    )]
    NoSamplingTime,
    /// A model that does not pass its own checks (one built in code
    /// without them; model files are checked when read).
    #[error("invalid model: {0}")]
    InvalidModel(String),
    /// The model's initial-state rule could not be met on this record (no
    /// rest state, a sensor map of zero gain).
    #[error("initial state: {0}")]
    InitialState(String),
    /// A transition put the state outside its target mode's invariant (a
    /// modelling error: its reset, or its guard where it has none, and the
    /// invariant disagree).
    #[error(
        "transition {transition} {how} outside the invariant of its target mode (sample {sample})",
        how = if *reset { "resets the state to a point" } else { "fires at a state (it has no reset)" }
    )]
    OutsideTargetInvariant {
        /// `from -> to`.
        transition: String,
        /// Whether the transition has a reset map.
        reset: bool,
        /// The sample in which it happened.
        sample: usize,
    },
    /// The model's `internal_step` is so small against the sampling time
    /// that a sample would take more than [`MAX_SUBSTEPS_PER_SAMPLE`]
    /// integration steps.
    #[error(
        "internal_step = {internal_step} s with a sampling time of {ts} s needs more than {max} integration sub-steps per sample: raise internal_step (or use a shorter sampling time)",
        max = MAX_SUBSTEPS_PER_SAMPLE
    )]
    TooManySubsteps {
        /// Sampling time of the data, seconds.
        ts: f64,
        /// The model's internal step, seconds.
        internal_step: f64,
    },
}

/// Most integration sub-steps a continuous-time model (hybrid automaton,
/// mechanical model) takes per sample: `ceil(ts / internal_step)` above it
/// is refused with [`SimError::TooManySubsteps`] instead of running for
/// hours (or forever: `1e-300` gives `usize::MAX`). 100 000 sub-steps per
/// sample is far beyond any sensible model (the pick-and-place head takes 10).
pub const MAX_SUBSTEPS_PER_SAMPLE: usize = 100_000;

/// Checks a sub-step count `n = ceil(ts / internal_step)` (as computed by
/// the model kind's simulator) against [`MAX_SUBSTEPS_PER_SAMPLE`]:
/// [`SimError::TooManySubsteps`] above it or when it is not finite.
pub fn check_substeps(n: f64, ts: f64, internal_step: f64) -> Result<usize, SimError> {
    // `!(n <= max)` also refuses NaN.
    if n <= MAX_SUBSTEPS_PER_SAMPLE as f64 {
        Ok(n.max(1.0) as usize)
    } else {
        Err(SimError::TooManySubsteps { ts, internal_step })
    }
}

/// Sub-steps per sample: the smallest count whose step is at most
/// `internal_step`, at most [`MAX_SUBSTEPS_PER_SAMPLE`] (the rule of the
/// continuous-time kinds declared by their physics).
pub fn substeps(ts: f64, internal_step: f64) -> Result<usize, SimError> {
    check_substeps(((ts / internal_step) - 1e-9).ceil(), ts, internal_step)
}

/// Estimates the state at sample `s` from measured outputs `y[..=s]`:
/// position `y[s]` and the slope at `s` of a least-squares quadratic through
/// the last (up to 5) samples (a line through 2).
pub fn estimate_velocity(y: &[f64], s: usize, ts: f64) -> f64 {
    let m = (s + 1).min(5);
    match m {
        0 | 1 => 0.0,
        2 => (y[s] - y[s - 1]) / ts,
        _ => {
            // Fit y = a + b t + c t^2 with t = 0 at sample s (t = -j ts).
            let (mut s0, mut s1, mut s2, mut s3, mut s4) = (0.0, 0.0, 0.0, 0.0, 0.0);
            let (mut r0, mut r1, mut r2) = (0.0, 0.0, 0.0);
            for j in 0..m {
                let t = -(j as f64);
                let yy = y[s - j];
                s0 += 1.0;
                s1 += t;
                s2 += t * t;
                s3 += t * t * t;
                s4 += t * t * t * t;
                r0 += yy;
                r1 += t * yy;
                r2 += t * t * yy;
            }
            // Solve the 3x3 normal equations by Cramer's rule for b.
            let det =
                s0 * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s3 * s2) + s2 * (s1 * s3 - s2 * s2);
            let db = s0 * (r1 * s4 - s3 * r2) - r0 * (s1 * s4 - s3 * s2) + s2 * (s1 * r2 - r1 * s2);
            if det.abs() < 1e-300 {
                0.0
            } else {
                db / det / ts
            }
        }
    }
}
