//! The inputs as the model sees them over each sample: held, and cut
//! into pieces by the model's input delays.

use crate::compile::CompiledModel;
use hysid_model::data::Dataset;
use hysid_model::simulate::{SimError, substeps};

/// The inputs as the model sees them: each held over its sample and, when
/// the model gives it a delay `d = q ts + r`, seen `q` samples and `r`
/// seconds late. Within sample `k` such an input is the recorded one of
/// sample `k - q - 1` until `r`, then that of `k - q` (the first sample's
/// before the record starts), so a sample is cut into pieces of constant
/// input at the remainders.
pub(super) struct Schedule {
    /// Per input: whole samples of delay and the remainder, seconds.
    lags: Vec<(usize, f64)>,
    /// The ends of the pieces within a sample: the remainders, then `ts`.
    cuts: Vec<f64>,
    /// The sampling time.
    pub(super) ts: f64,
    /// The model's longest integration step.
    internal_step: f64,
    /// Sub-steps of a whole sample, where its step is valid.
    whole: Option<usize>,
}

/// A piece of a sample: duration, the inputs held over it, sub-steps.
type Piece = (f64, Vec<f64>, usize);

impl Schedule {
    /// The delays of the bound model `m` at the sampling time `ts`
    /// (negative delays count as 0).
    pub(super) fn new(m: &CompiledModel, ts: f64) -> Self {
        let lags: Vec<(usize, f64)> = m
            .delays
            .iter()
            .map(|d| {
                let d = d.as_constant().unwrap_or(0.0).max(0.0);
                let q = (d / ts + 1e-9).floor();
                let r = d - q * ts;
                (q as usize, if r <= 1e-9 * ts { 0.0 } else { r })
            })
            .collect();
        let mut cuts: Vec<f64> = lags.iter().map(|(_, r)| *r).filter(|r| *r > 0.0).collect();
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        cuts.push(ts);
        Schedule {
            lags,
            cuts,
            ts,
            internal_step: m.internal_step,
            whole: substeps(ts, m.internal_step).ok(),
        }
    }

    /// The input of sample `k` in effect from `t` seconds into it.
    #[inline]
    pub(super) fn inputs(&self, data: &Dataset, k: usize, t: f64, u: &mut [f64]) {
        for (i, (x, (q, r))) in u.iter_mut().zip(&self.lags).enumerate() {
            let back = q + usize::from(t < *r);
            *x = data.inputs[i].values[k.saturating_sub(back)];
        }
    }

    /// Writes the pieces of sample `k` into `pieces` (reusing its buffers)
    /// in time order, consecutive pieces of equal inputs merged, and
    /// returns how many there are (one without delays).
    #[inline]
    pub(super) fn fill(
        &self,
        data: &Dataset,
        k: usize,
        pieces: &mut Vec<Piece>,
    ) -> Result<usize, SimError> {
        if let (&[ts], Some(n)) = (&self.cuts[..], self.whole) {
            // No delay cuts the sample: one piece of the whole sample.
            if pieces.is_empty() {
                pieces.push((0.0, vec![0.0; self.lags.len()], 0));
            }
            self.inputs(data, k, 0.0, &mut pieces[0].1);
            pieces[0].0 = ts;
            pieces[0].2 = n;
            return Ok(1);
        }
        let mut count = 0;
        let mut from = 0.0;
        for &to in &self.cuts {
            if count == pieces.len() {
                pieces.push((0.0, vec![0.0; self.lags.len()], 0));
            }
            self.inputs(data, k, from, &mut pieces[count].1);
            if count > 0 && pieces[count].1 == pieces[count - 1].1 {
                pieces[count - 1].0 += to - from;
            } else {
                pieces[count].0 = to - from;
                count += 1;
            }
            from = to;
        }
        for piece in &mut pieces[..count] {
            piece.2 = match self.whole {
                Some(n) if piece.0 == self.ts => n,
                _ => substeps(piece.0, self.internal_step)?,
            };
        }
        Ok(count)
    }
}
