//! The free-parameter vector: how the normalised coordinates `z in [0, 1]^d`
//! of the search map onto the model's parameters under the priors
//! (`[fixed]`, `[bounds]`, `[[tie]]`), and back.

use crate::target::Target;
use hysid_core::priors::Priors;
use nalgebra::DMatrix;

/// Priors that do not fit the model's parameters (worded with the prior
/// file by the back-end).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParameterError {
    /// An entry naming a parameter the model does not have.
    #[error("{entry}: unknown parameter '{}' (known: {})", .name.escape_debug(), .known.join(", "))]
    UnknownName {
        /// `[bounds]`, `[fixed]` or `[[tie]]`.
        entry: &'static str,
        /// The name.
        name: String,
        /// The model's parameter names.
        known: Vec<String>,
    },
    /// A tie of one parameter: in a physical model a tie makes parameters
    /// equal to each other, so one ties nothing.
    #[error(
        "[[tie]] #{entry}: one parameter ('{}') ties nothing: a physical model's tie makes two or more of its parameters equal",
        .name.escape_debug()
    )]
    LoneTie {
        /// The entry, counted from 1.
        entry: usize,
        /// Its parameter.
        name: String,
    },
    /// Two tied parameters fixed to different values.
    #[error("[[tie]]: '{first}' and '{second}' are tied but fixed to different values")]
    TiedFixedDiffer {
        /// One parameter.
        first: String,
        /// The other.
        second: String,
    },
    /// Bounds of a tied group (or one parameter) with no common value.
    #[error("[bounds]: the bounds of [{}] leave no admissible value", .params.join(", "))]
    EmptyBounds {
        /// The parameters.
        params: Vec<String>,
    },
    /// A fixed value (of the parameter, or of one tied to it) outside the
    /// parameter's bounds: the fitted model would not read back.
    #[error("[fixed]: {name} = {value} lies outside its bounds [{}, {}] (widen them with [bounds])", .bounds[0], .bounds[1])]
    FixedOutsideBounds {
        /// The parameter.
        name: String,
        /// The value it would take.
        value: f64,
        /// Its bounds after the priors.
        bounds: [f64; 2],
    },
    /// Bounds or fixed values the model refuses (a friction level below 0).
    #[error("[bounds]/[fixed]: {0}")]
    Refused(hysid_mechanical::InvalidMechanical),
}

/// How the free coordinates `z in [0, 1]^d` map onto the model's parameters:
/// fixed parameters keep their value, tied ones share a coordinate, each
/// coordinate spans its (intersected) bounds. The initial states the model
/// leaves unknown ([`Target::estimated_states`]) follow the parameters,
/// one coordinate each over their bounds, for each record in turn:
/// nuisance parameters of the record, searched with the parameters but not
/// written into the model. With several records a state is named
/// `name[r]` (`r` counted from 1).
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterMap {
    /// Number of the model's parameters: the values after them are the
    /// estimated initial states.
    pub parameters: usize,
    /// Value of every parameter when `z` is not involved (fixed ones).
    pub base: Vec<f64>,
    /// Per free coordinate: the parameters it sets.
    pub groups: Vec<Vec<usize>>,
    /// Per free coordinate: `[low, high]`.
    pub bounds: Vec<[f64; 2]>,
    /// Per parameter: its bounds after priors.
    pub param_bounds: Vec<[f64; 2]>,
    /// Parameter names.
    pub names: Vec<String>,
}

impl ParameterMap {
    /// Builds the map from the model (its `fixed` flags and bounds) and the
    /// priors (`[fixed]`, `[bounds]`, `[[tie]]`), checking every name, with
    /// the estimated initial states of `records` records.
    pub fn new(
        model: &impl Target,
        priors: &Priors,
        records: usize,
    ) -> Result<Self, ParameterError> {
        let parameters = model.parameters();
        let mut names: Vec<String> = parameters.iter().map(|p| p.name.clone()).collect();
        let idx = |n: &str, entry: &'static str| {
            names
                .iter()
                .position(|p| p == n)
                .ok_or_else(|| ParameterError::UnknownName {
                    entry,
                    name: n.to_string(),
                    known: names.clone(),
                })
        };
        let mut base: Vec<f64> = parameters.iter().map(|p| p.value).collect();
        let mut bounds: Vec<[f64; 2]> = parameters.iter().map(|p| p.bounds).collect();
        let mut fixed: Vec<bool> = parameters.iter().map(|p| p.fixed).collect();
        for (n, [lo, hi]) in &priors.bounds {
            let i = idx(n, "[bounds]")?;
            bounds[i] = [*lo, *hi];
        }
        for (n, v) in &priors.fixed {
            let i = idx(n, "[fixed]")?;
            base[i] = *v;
            fixed[i] = true;
        }
        let ties = priors
            .tie
            .iter()
            .map(|t| t.params.iter().map(|n| idx(n, "[[tie]]")).collect())
            .collect::<Result<Vec<Vec<usize>>, ParameterError>>()?;
        if let Some((i, t)) = (priors.tie.iter().enumerate()).find(|(_, t)| t.params.len() == 1) {
            return Err(ParameterError::LoneTie {
                entry: i + 1,
                name: t.params[0].clone(),
            });
        }
        let mut free_groups = Vec::new();
        let mut free_bounds = Vec::new();
        for g in tie_groups(names.len(), &ties) {
            let group = Group {
                members: &g,
                names: &names,
                fixed: &fixed,
                bounds: &bounds,
            };
            if let Some(b) = group.settle(&mut base)? {
                free_groups.push(g);
                free_bounds.push(b);
            }
        }
        for (g, b) in free_groups.iter().zip(&free_bounds) {
            for &i in g {
                bounds[i] = *b;
            }
        }
        let np = names.len();
        for r in 1..=records {
            for (name, b, start) in model.estimated_states() {
                free_groups.push(vec![names.len()]);
                free_bounds.push(b);
                bounds.push(b);
                base.push(start);
                names.push(if records > 1 {
                    format!("{name}[{r}]")
                } else {
                    name
                });
            }
        }
        Ok(Self {
            parameters: np,
            base,
            groups: free_groups,
            bounds: free_bounds,
            param_bounds: bounds,
            names,
        })
    }

    /// Number of free coordinates.
    pub fn dim(&self) -> usize {
        self.groups.len()
    }

    /// Whether free coordinate `g` is an estimated initial state rather
    /// than a parameter.
    pub fn is_initial_state(&self, g: usize) -> bool {
        self.groups[g][0] >= self.parameters
    }

    /// The estimated initial states at the values `values`, by name.
    pub fn initial_states(&self, values: &[f64]) -> std::collections::BTreeMap<String, f64> {
        (self.parameters..self.names.len())
            .map(|i| (self.names[i].clone(), values[i]))
            .collect()
    }

    /// Parameter values for `z` (clamped into `[0, 1]`).
    pub fn values(&self, z: &[f64]) -> Vec<f64> {
        let mut v = self.base.clone();
        for ((g, [lo, hi]), zi) in self.groups.iter().zip(&self.bounds).zip(z) {
            let x = lo + (hi - lo) * zi.clamp(0.0, 1.0);
            for &i in g {
                v[i] = x;
            }
        }
        v
    }

    /// A Jacobian in the values (a column per value) as one in the free
    /// coordinates: column `g` is `(high - low)` times the sum of the
    /// columns of the values coordinate `g` sets ([`ParameterMap::values`]).
    pub fn in_coordinates(&self, jacobian: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = self.grouped(jacobian);
        for (mut column, [lo, hi]) in out.column_iter_mut().zip(&self.bounds) {
            column *= hi - lo;
        }
        out
    }

    /// A Jacobian in the values as one in the free coordinates' values
    /// (physical units): column `g` is the sum of the columns of the values
    /// coordinate `g` sets.
    pub fn grouped(&self, jacobian: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(jacobian.nrows(), self.dim());
        for (mut column, g) in out.column_iter_mut().zip(&self.groups) {
            for &i in g {
                column += jacobian.column(i);
            }
        }
        out
    }

    /// Normalised coordinates of the parameter values `values`.
    pub fn coords(&self, values: &[f64]) -> Vec<f64> {
        self.groups
            .iter()
            .zip(&self.bounds)
            .map(|(g, [lo, hi])| {
                if hi > lo {
                    ((values[g[0]] - lo) / (hi - lo)).clamp(0.0, 1.0)
                } else {
                    0.5
                }
            })
            .collect()
    }

    /// `model` with the parameter values `values`, the bounds after priors,
    /// and `fixed` set on every parameter no free coordinate moves.
    pub fn apply<M: Target>(&self, model: &M, values: &[f64]) -> M {
        let mut fitted = model.clone();
        for (i, (p, (v, b))) in fitted
            .parameters_mut()
            .iter_mut()
            .zip(values.iter().zip(&self.param_bounds))
            .enumerate()
        {
            p.value = *v;
            p.bounds = *b;
            p.fixed = !self.groups.iter().any(|g| g.contains(&i));
        }
        fitted
    }

    /// Names of the parameters whose free coordinate lies within `1e-6` of
    /// its range from either bound, in coordinate order.
    pub fn at_bound(&self, values: &[f64]) -> Vec<String> {
        self.at_bound_of(values, false)
    }

    /// The estimated initial states at a bound of their estimate, as
    /// [`Self::at_bound`] tells parameters.
    pub fn initial_states_at_bound(&self, values: &[f64]) -> Vec<String> {
        self.at_bound_of(values, true)
    }

    /// The names, at `values`, within `1e-6` of the range of a bound of
    /// their coordinate: those of initial states when `states`, else the
    /// parameters'.
    fn at_bound_of(&self, values: &[f64], states: bool) -> Vec<String> {
        let mut at_bound = Vec::new();
        for (gi, (g, [lo, hi])) in self.groups.iter().zip(&self.bounds).enumerate() {
            if self.is_initial_state(gi) != states {
                continue;
            }
            let v = values[g[0]];
            if (v - lo).abs() <= 1e-6 * (hi - lo) || (hi - v).abs() <= 1e-6 * (hi - lo) {
                at_bound.extend(g.iter().map(|&i| self.names[i].clone()));
            }
        }
        at_bound
    }
}

/// The classes of the tie relation over `n` parameters (union-find over
/// the `[[tie]]` lists `ties`), each in ascending order, ordered by their
/// first member.
fn tie_groups(n: usize, ties: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], i: usize) -> usize {
        let mut r = i;
        while p[r] != r {
            r = p[r];
        }
        p[i] = r;
        r
    }
    for ids in ties {
        for w in ids.windows(2) {
            let (a, b) = (find(&mut parent, w[0]), find(&mut parent, w[1]));
            if a != b {
                parent[b.max(a)] = a.min(b);
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut roots: Vec<usize> = Vec::new();
    for i in 0..n {
        let r = find(&mut parent, i);
        match roots.iter().position(|&x| x == r) {
            Some(g) => groups[g].push(i),
            None => {
                roots.push(r);
                groups.push(vec![i]);
            }
        }
    }
    groups
}

/// One class of tied parameters, with the priors' flags and bounds.
struct Group<'a> {
    members: &'a [usize],
    names: &'a [String],
    fixed: &'a [bool],
    bounds: &'a [[f64; 2]],
}

impl Group<'_> {
    /// Sets the group's common starting value in `base` and returns its
    /// free range, or `None` when a fixed member fixes the whole group.
    fn settle(&self, base: &mut [f64]) -> Result<Option<[f64; 2]>, ParameterError> {
        let g = self.members;
        let fixed_members: Vec<usize> = g.iter().copied().filter(|&i| self.fixed[i]).collect();
        if let Some(&f) = fixed_members.first() {
            // A tie with a fixed member fixes the whole group.
            for &i in &fixed_members {
                if base[i] != base[f] {
                    return Err(ParameterError::TiedFixedDiffer {
                        first: self.names[f].clone(),
                        second: self.names[i].clone(),
                    });
                }
            }
            for &i in g {
                let [lo, hi] = self.bounds[i];
                if !(lo <= base[f] && base[f] <= hi) {
                    return Err(ParameterError::FixedOutsideBounds {
                        name: self.names[i].clone(),
                        value: base[f],
                        bounds: [lo, hi],
                    });
                }
                base[i] = base[f];
            }
            return Ok(None);
        }
        let lo = g
            .iter()
            .map(|&i| self.bounds[i][0])
            .fold(f64::NEG_INFINITY, f64::max);
        let hi = g
            .iter()
            .map(|&i| self.bounds[i][1])
            .fold(f64::INFINITY, f64::min);
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(ParameterError::EmptyBounds {
                params: g.iter().map(|&i| self.names[i].clone()).collect(),
            });
        }
        // A tied group starts from the mean of its nominal values, clamped.
        let start = (g.iter().map(|&i| base[i]).sum::<f64>() / g.len() as f64).clamp(lo, hi);
        for &i in g {
            base[i] = start;
        }
        Ok(Some([lo, hi]))
    }
}
