//! Identification on standardised data, the model written back in
//! original units (`--standardize`).

use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_model::data::Standardization;

/// Runs `backend` on standardised data (zero mean, unit standard deviation
/// per signal) and returns the model in original units, with the statistics
/// recorded in `info.scaling`. Priors holding values in data units
/// (`[[saturation]]`, `[fixed]`, `[bounds]`, `[[equality]]`) and ties on the offset `c`
/// are refused here: their meaning would change with the scaling.
pub fn run_standardized(
    backend: &dyn Backend,
    problem: &Problem<'_>,
    settings: &Settings,
    ctx: &RunContext<'_>,
) -> Result<Model, IdentifyError> {
    let p = problem.priors;
    let in_data_units = (!p.saturation.is_empty())
        .then(|| "[[saturation]] #1".to_string())
        .or_else(|| p.fixed.keys().next().map(|k| format!("[fixed] {k}")))
        .or_else(|| p.bounds.keys().next().map(|k| format!("[bounds] {k}")))
        .or_else(|| (!p.equality.is_empty()).then(|| "[[equality]] #1".to_string()));
    if let Some(entry) = in_data_units {
        return Err(IdentifyError::input(StandardizeError::PriorsInDataUnits {
            entry,
            origin: problem.priors_origin.map(str::to_string),
        }));
    }
    // Scaling multiplies a tied a_i or b_i by one factor in every mode, so
    // such ties survive; the offset c maps to a combination of all the
    // parameters of its mode, so a tie on c would not.
    if let Some(i) = p.tie.iter().position(|t| t.params.iter().any(|n| n == "c")) {
        return Err(IdentifyError::input(StandardizeError::TieOnOffset {
            tie: i + 1,
            origin: problem.priors_origin.map(str::to_string),
        }));
    }
    let scale = Standardization::of(problem.data);
    let scaled = scale.apply(problem.data);
    let inner = Problem {
        data: &scaled,
        ..*problem
    };
    let units = backend.output_units();
    let sigma = scale.output.std;
    let scaled_settings = in_output_units(settings, units, 1.0 / sigma);
    match backend.run(&inner, &scaled_settings, ctx)? {
        Model::Pwarx(m) => {
            let mut m = m.to_original_units(&scale);
            let info = &mut m.info;
            for key in units {
                if let Some(v) = info.diagnostics.method.get_mut(*key) {
                    rescale_json(v, sigma);
                }
                let given = settings.get(key).and_then(|v| v.parse::<f64>().ok());
                if let (Some(v), Some(x)) = (info.options.get_mut(*key), given) {
                    *v = serde_json::json!(x);
                }
            }
            Ok(Model::Pwarx(m))
        }
        other => Err(IdentifyError::input(StandardizeError::ModelKind {
            method: backend.name(),
            kind: other.kind(),
        })),
    }
}

/// `settings` with the numeric values of the `units` keys multiplied by
/// `factor` (other values, such as `delta=auto`, unchanged).
fn in_output_units(settings: &Settings, units: &[&str], factor: f64) -> Settings {
    let pairs = settings
        .pairs()
        .iter()
        .map(|(k, v)| match v.parse::<f64>() {
            Ok(x) if units.contains(&k.as_str()) => (k.clone(), format!("{:e}", x * factor)),
            _ => (k.clone(), v.clone()),
        })
        .collect();
    Settings::from_pairs(pairs)
}

/// Multiplies every number in `v` (a number or an array of them) by `factor`.
fn rescale_json(v: &mut serde_json::Value, factor: f64) {
    match v {
        serde_json::Value::Number(n) => {
            if let Some(x) = n
                .as_f64()
                .and_then(|x| serde_json::Number::from_f64(x * factor))
            {
                *n = x;
            }
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(|x| rescale_json(x, factor)),
        _ => {}
    }
}

impl StandardizeError {
    /// The message with `asked`, how the front end asks for a standardized
    /// run (`--standardize` on the command line).
    pub fn render(&self, asked: &str) -> String {
        match self {
            Self::PriorsInDataUnits { entry, origin } => format!(
                "{asked} cannot be combined with {entry}{}, a prior in data units ([[saturation]], [fixed], [bounds] and [[equality]] are)",
                origin
                    .as_ref()
                    .map_or(String::new(), |o| format!(" of {o}"))
            ),
            Self::TieOnOffset { tie, origin } => format!(
                "{asked} cannot be combined with [[tie]] #{tie}{}, a tie on the offset c (it does not survive the back-transform)",
                origin
                    .as_ref()
                    .map_or(String::new(), |o| format!(" of {o}"))
            ),
            Self::ModelKind { method, kind } => format!(
                "{asked}: method '{method}' returns a {kind} model, which cannot be mapped back to original units"
            ),
        }
    }
}

/// Why [`run_standardized`] refuses a run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StandardizeError {
    /// Priors holding values in data units.
    #[error("{}", self.render("standardization"))]
    PriorsInDataUnits {
        /// The first such entry (`[fixed] c`).
        entry: String,
        /// The prior file, when the priors came from one.
        origin: Option<String>,
    },
    /// A `[[tie]]` on the offset `c`.
    #[error("{}", self.render("standardization"))]
    TieOnOffset {
        /// The tie, counted from 1.
        tie: usize,
        /// The prior file, when the priors came from one.
        origin: Option<String>,
    },
    /// A back-end whose model has no original-units form.
    #[error("{}", self.render("standardization"))]
    ModelKind {
        /// Back-end name.
        method: &'static str,
        /// Kind of the model it returned.
        kind: &'static str,
    },
}
