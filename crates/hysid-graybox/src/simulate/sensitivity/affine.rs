//! The sensitivities of a regime whose flows are affine in the states and
//! inputs: the flows' derivatives read once from the tapes, and a step of
//! the sub-step's length in closed form (as `simulate::linear` is for
//! the state).

/// The derivatives of a regime's flows (the elements' effects included)
/// that are affine in the states and inputs, `f = A(θ) x + b(θ, u)`:
/// `f_x = A` and `f_θ = G0 + Σ_j x_j Gx_j + Σ_i u_i Gu_i`, read once from
/// the tapes, so that a stage costs a few small matrix products, and a
/// step of the sub-step's length one ([`LinearStep`]).
pub(super) struct Linear {
    /// `A`, row-major (states x states).
    pub(super) a: Vec<f64>,
    /// `G0`, then `Gx_j` per state, then `Gu_i` per input; each states x
    /// parameters, row-major.
    pub(super) g: Vec<Vec<f64>>,
    /// `b(u) = b0 + Σ_i u_i b_i`: `b0`, then `b_i` per input.
    pub(super) b: Vec<Vec<f64>>,
    /// The step of the last length asked for.
    pub(super) step: Option<(f64, LinearStep)>,
}

/// One RK4 step of length `h` of a [`Linear`] regime's sensitivities in
/// closed form: `S+ = T(hA) S + P(x, u)`, where
/// `T(z) = 1 + z + z^2/2 + z^3/6 + z^4/24` and the forcing
/// `P = P0 + Σ_j x_j Px_j + Σ_i u_i Pu_i` gathers the stages' `f_θ` terms;
/// and the step's rate in its length, `Φ_h = T'(hA) f(x, u)` with
/// `T'(z) = 1 + z + z^2/2 + z^3/6`.
pub(super) struct LinearStep {
    /// `T(hA)` and `T'(hA)`, row-major.
    pub(super) t: Vec<f64>,
    pub(super) dt: Vec<f64>,
    /// `P0`, then `Px_j`, then `Pu_i` (states x parameters each).
    pub(super) p: Vec<Vec<f64>>,
}

/// The points `(x, u)` at which an affine map of `n` states and `inputs`
/// inputs is read: the unit vectors of the states, then of the inputs.
pub(super) fn unit_points(n: usize, inputs: usize) -> impl Iterator<Item = (Vec<f64>, Vec<f64>)> {
    (0..n + inputs).map(move |j| {
        let (mut x, mut u) = (vec![0.0; n], vec![0.0; inputs]);
        if j < n {
            x[j] = 1.0;
        } else {
            u[j - n] = 1.0;
        }
        (x, u)
    })
}

/// `out = a b` for row-major `n x n` `a` and `n x c` `b`.
pub(super) fn product_into(a: &[f64], b: &[f64], n: usize, c: usize, out: &mut [f64]) {
    out.fill(0.0);
    for r in 0..n {
        for j in 0..n {
            let arj = a[r * n + j];
            if arj != 0.0 {
                for (o, bj) in out[r * c..(r + 1) * c]
                    .iter_mut()
                    .zip(&b[j * c..(j + 1) * c])
                {
                    *o += arj * bj;
                }
            }
        }
    }
}

/// [`product_into`] into a new matrix.
pub(super) fn product(a: &[f64], b: &[f64], n: usize, c: usize) -> Vec<f64> {
    let mut out = vec![0.0; n * c];
    product_into(a, b, n, c, &mut out);
    out
}

/// `out += m_0 + Σ_k w_k m_k` over the affine pieces `m` (`w_k` from
/// `weights`, for `m_1`, `m_2`, ...).
pub(super) fn add_affine(
    pieces: &[Vec<f64>],
    weights: impl IntoIterator<Item = f64>,
    out: &mut [f64],
) {
    for (m, w) in pieces.iter().zip(std::iter::once(1.0).chain(weights)) {
        if w != 0.0 {
            for (o, v) in out.iter_mut().zip(m) {
                *o += w * v;
            }
        }
    }
}

/// `out[.., ..p] += m` for `n x p` `m` and `n x c` `out` (a parameter
/// term into the sensitivities' columns, the estimated states' left).
pub(super) fn add_parameter_columns(m: &[f64], out: &mut [f64], p: usize, c: usize) {
    if p == 0 {
        return;
    }
    for (row, m) in out.chunks_mut(c).zip(m.chunks(p)) {
        for (o, v) in row[..p].iter_mut().zip(m) {
            *o += v;
        }
    }
}

/// A stage's derivatives of the flows from their partials `fx` (states x
/// states) and `ftheta` (states x parameters) at the stage state: in the
/// parameters `out = fx stage + ftheta`, in the step's length `out_h = fx
/// stage_h`.
pub(super) fn compose(
    (fx, ftheta): (&[f64], &[f64]),
    (stage, stage_h): (&[f64], &[f64]),
    (out, out_h): (&mut [f64], &mut [f64]),
    (p, c): (usize, usize),
) {
    let n = stage_h.len();
    product_into(fx, stage, n, c, out);
    add_parameter_columns(ftheta, out, p, c);
    product_into(fx, stage_h, n, 1, out_h);
}

impl Linear {
    /// `f(x, u) = A x + b(u)` into `out`.
    pub(super) fn flow_into(&self, x: &[f64], u: &[f64], out: &mut [f64]) {
        product_into(&self.a, x, x.len(), 1, out);
        add_affine(&self.b, u.iter().copied(), out);
    }

    /// `f(x, u)`.
    pub(super) fn flow(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        let mut f = vec![0.0; x.len()];
        self.flow_into(x, u, &mut f);
        f
    }

    /// `f_θ` at `(x, u)` into `out` (states x parameters).
    pub(super) fn f_theta_into(&self, x: &[f64], u: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        add_affine(&self.g, x.iter().chain(u).copied(), out);
    }

    /// `f_θ` at `(x, u)`.
    pub(super) fn f_theta(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        let mut g = vec![0.0; self.g[0].len()];
        self.f_theta_into(x, u, &mut g);
        g
    }

    /// The stages' `f_θ` terms of a step of length `h` from `(x, u)` with
    /// `S = 0`: the forcing `P(x, u)` of [`LinearStep`].
    fn forcing(&self, h: f64, x: &[f64], u: &[f64]) -> Vec<f64> {
        let n = x.len();
        let p = self.g[0].len() / n;
        let mut total = vec![0.0; n * p];
        let (mut stage_x, mut stage_s) = (x.to_vec(), vec![0.0; n * p]);
        for (i, (c, w)) in [(0.5, 1.0), (0.5, 2.0), (1.0, 2.0), (0.0, 1.0)]
            .into_iter()
            .enumerate()
        {
            let mut d = product(&self.a, &stage_s, n, p);
            for (o, g) in d.iter_mut().zip(self.f_theta(&stage_x, u)) {
                *o += g;
            }
            for (o, d) in total.iter_mut().zip(&d) {
                *o += w * h / 6.0 * d;
            }
            if i < 3 {
                let k = self.flow(&stage_x, u);
                stage_x = x.iter().zip(&k).map(|(x, k)| x + c * h * k).collect();
                stage_s = d.iter().map(|d| c * h * d).collect();
            }
        }
        total
    }

    /// Forms the closed-form step of length `h` into [`Linear::step`] when
    /// the length differs from the last one's.
    pub(super) fn form_step(&mut self, h: f64, n: usize, inputs: usize) {
        if !matches!(&self.step, Some((length, _)) if *length == h) {
            let z: Vec<f64> = self.a.iter().map(|a| h * a).collect();
            let mut t = vec![0.0; n * n];
            let mut dt = vec![0.0; n * n];
            let mut power = vec![0.0; n * n];
            for i in 0..n {
                power[i * n + i] = 1.0;
            }
            for (k, factor) in [1.0, 1.0, 0.5, 1.0 / 6.0, 1.0 / 24.0]
                .into_iter()
                .enumerate()
            {
                for ((t, dt), p) in t.iter_mut().zip(dt.iter_mut()).zip(&power) {
                    *t += factor * p;
                    if k < 4 {
                        *dt += [1.0, 1.0, 0.5, 1.0 / 6.0][k] * p;
                    }
                }
                power = product(&z, &power, n, n);
            }
            let p0 = self.forcing(h, &vec![0.0; n], &vec![0.0; inputs]);
            let mut p = vec![p0.clone()];
            for (x, u) in unit_points(n, inputs) {
                let pj = self.forcing(h, &x, &u);
                p.push(pj.iter().zip(&p0).map(|(a, b)| a - b).collect());
            }
            self.step = Some((h, LinearStep { t, dt, p }));
        }
    }
}
