//! PWARX simulation and prediction.

use super::{SimError, Simulation, SimulationOptions};
use crate::data::Dataset;
use crate::model::PwarxModel;

fn empty(m: &PwarxModel, data: &Dataset) -> Result<Simulation, SimError> {
    let lag = m.spec().lag();
    if data.len() <= lag {
        return Err(SimError::TooShort {
            samples: data.len(),
            needed: lag,
        });
    }
    Ok(Simulation {
        y: data.y().to_vec(),
        modes: vec![None; data.len()],
        start: lag,
        covered: vec![true; data.len()],
        diverged_at: None,
        diverged_to: None,
        zeno: None,
    })
}

/// Free-run simulation of a PWARX model from the first `max(na, nb)` measured outputs.
pub fn simulate(
    m: &PwarxModel,
    data: &Dataset,
    opts: SimulationOptions,
) -> Result<Simulation, SimError> {
    let mut sim = empty(m, data)?;
    let spec = m.spec();
    let u: Vec<&[f64]> = (0..m.inputs).map(|i| data.u(i)).collect();
    let mut x = vec![0.0; spec.dim()];
    for k in sim.start..data.len() {
        spec.fill(&sim.y, &u, k, &mut x);
        let (v, c) = m.predict(&x);
        sim.modes[k] = Some(c.mode);
        sim.covered[k] = c.covered;
        if !sim.push_checked(k, v, opts.bound) {
            break;
        }
    }
    Ok(sim)
}

/// One-step prediction of a PWARX model from measured regressors.
pub fn predict(m: &PwarxModel, data: &Dataset) -> Result<Simulation, SimError> {
    let mut sim = empty(m, data)?;
    let spec = m.spec();
    let u: Vec<&[f64]> = (0..m.inputs).map(|i| data.u(i)).collect();
    let mut x = vec![0.0; spec.dim()];
    for k in sim.start..data.len() {
        spec.fill(data.y(), &u, k, &mut x);
        let (v, c) = m.predict(&x);
        sim.modes[k] = Some(c.mode);
        sim.covered[k] = c.covered;
        sim.y[k] = v;
    }
    Ok(sim)
}
