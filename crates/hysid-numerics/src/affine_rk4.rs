//! RK4 in closed form for affine flows, `dx/dt = A x + B u + c` with the
//! input `u` held over the step, as the flows of most mechanical and
//! electrical models are in one regime once their parameters are bound.
//!
//! With `w = B u + c` and `M = h A`, the four stages of classical RK4
//! collapse into one affine map of the state:
//!
//! ```text
//! x(t + h) = P x(t) + Q w,   T = I + M/2 + M^2/6 + M^3/24,   Q = h T,   P = I + T M
//! ```
//!
//! (the stages `k2 = k1 + (h/2) A k1`, `k3 = k1 + (h/2) A k2`,
//! `k4 = k1 + h A k3` summed with weights 1, 2, 2, 1 over 6). `P` and `Q`
//! depend on `A` and `h` only, so a simulator forms them once per regime
//! and step length ([`ClosedStep::new`]) and reuses them for every full
//! sub-step spent in it: a step is then two small matrix-vector products
//! instead of four evaluations of the flows. The step is applied as an
//! increment, `x + (P - I) x + Q w`, whose rows are built with `M` on the
//! left: two states with the same flow move by the same amount, bit for
//! bit, as they do stage by stage, and a zero row of `A`, `B` and `c` (a
//! held state) keeps its state exactly. The result equals the
//! stage-by-stage RK4 up to rounding.

/// One closed-form step as an increment,
/// `x(t + h) = x(t) + D x(t) + G u + g` with `D = P - I`, `G = Q B` and
/// `g = Q c` (see the module doc).
#[derive(Debug, Clone)]
pub struct ClosedStep {
    d: Vec<f64>,
    g: Vec<f64>,
    offset: Vec<f64>,
    /// `A`, `B` and `c`, for steps of other lengths.
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
}

impl ClosedStep {
    /// The step of length `h` of `dx/dt = A x + B u + c`, with `A` the
    /// row-major `n x n` matrix `a`, `B` the row-major `n x m` matrix `b`
    /// and `n = c.len()`.
    pub fn new(a: Vec<f64>, b: Vec<f64>, c: Vec<f64>, h: f64) -> Self {
        let n = c.len();
        let m = b.len() / n.max(1);
        let mh = scaled(&a, h);
        // M = h A; V = T - I = M (I/2 + M (I/6 + M/24)), by Horner; every product
        // takes M on the left, so two states with the same flow get the
        // same rows and the same increments, as stage by stage.
        let mut v = identity_plus(&scaled(&mh, 1.0 / 24.0), 1.0 / 6.0, n);
        v = identity_plus(&product(&mh, &v, n, n), 0.5, n);
        v = product(&mh, &v, n, n);
        // D = P - I = T M = M + V M, G = h T B, g = h T c.
        let along = |e: &[f64], cols: usize| -> Vec<f64> {
            let ve = product(&v, e, n, cols);
            e.iter().zip(&ve).map(|(e, ve)| e + ve).collect()
        };
        ClosedStep {
            d: along(&mh, n),
            g: scaled(&along(&b, m), h),
            offset: scaled(&along(&c, 1), h),
            a,
            b,
            c,
        }
    }

    /// `out = x + D x + G u + g`. Inlined at every call: left to the
    /// compiler, the mechanical simulator's sub-step loop called it, and
    /// the head's record took 0.43 ms against 0.24 ms.
    #[inline(always)]
    pub fn apply(&self, x: &[f64], u: &[f64], out: &mut [f64]) {
        match (x.len(), u.len()) {
            (1, 1) => self.apply_sized(x, u, out, 1, 1),
            (2, 1) => self.apply_sized(x, u, out, 2, 1),
            (2, 2) => self.apply_sized(x, u, out, 2, 2),
            (3, 1) => self.apply_sized(x, u, out, 3, 1),
            (4, 1) => self.apply_sized(x, u, out, 4, 1),
            (4, 2) => self.apply_sized(x, u, out, 4, 2),
            (n, m) => self.apply_sized(x, u, out, n, m),
        }
    }

    /// [`ClosedStep::apply`] for `n` states and `m` inputs; inlined where
    /// they are constants (the common small models), so its loops unroll.
    #[inline(always)]
    fn apply_sized(&self, x: &[f64], u: &[f64], out: &mut [f64], n: usize, m: usize) {
        let (x, u) = (&x[..n], &u[..m]);
        for (i, o) in out.iter_mut().enumerate().take(n) {
            let mut increment = self.offset[i];
            for (a, xj) in self.d[i * n..(i + 1) * n].iter().zip(x) {
                increment += a * xj;
            }
            for (g, uj) in self.g[i * m..(i + 1) * m].iter().zip(u) {
                increment += g * uj;
            }
            *o = x[i] + increment;
        }
    }

    /// The step for `N` states and `M` inputs in arrays ([`FixedStep`]);
    /// `None` when the step has other sizes.
    pub fn fixed<const N: usize, const M: usize>(&self) -> Option<FixedStep<N, M>> {
        (self.offset.len() == N && self.g.len() == N * M).then(|| FixedStep {
            d: std::array::from_fn(|i| std::array::from_fn(|j| self.d[i * N + j])),
            g: std::array::from_fn(|i| std::array::from_fn(|k| self.g[i * M + k])),
            offset: std::array::from_fn(|i| self.offset[i]),
        })
    }

    /// RK4's step of another length `h` of the same flows, by Horner on
    /// the state: with `k = A x + B u + c`,
    /// `x(t + h) = x + h (k + (h/2) A' (k + (h/3) A' (k + (h/4) A' k)))`;
    /// `k` and `t` are workspaces of `n`.
    pub fn apply_length(
        &self,
        h: f64,
        x: &[f64],
        u: &[f64],
        work: (&mut [f64], &mut [f64]),
        out: &mut [f64],
    ) {
        match (x.len(), u.len()) {
            (1, 1) => self.apply_length_sized(h, x, u, work, out, 1, 1),
            (2, 1) => self.apply_length_sized(h, x, u, work, out, 2, 1),
            (2, 2) => self.apply_length_sized(h, x, u, work, out, 2, 2),
            (3, 1) => self.apply_length_sized(h, x, u, work, out, 3, 1),
            (4, 1) => self.apply_length_sized(h, x, u, work, out, 4, 1),
            (4, 2) => self.apply_length_sized(h, x, u, work, out, 4, 2),
            (n, m) => self.apply_length_sized(h, x, u, work, out, n, m),
        }
    }

    /// [`ClosedStep::apply_length`] for `n` states and `m` inputs, inlined
    /// as [`ClosedStep::apply_sized`] is.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn apply_length_sized(
        &self,
        h: f64,
        x: &[f64],
        u: &[f64],
        (k, t): (&mut [f64], &mut [f64]),
        out: &mut [f64],
        n: usize,
        m: usize,
    ) {
        let (x, u) = (&x[..n], &u[..m]);
        let row = |i: usize| &self.a[i * n..(i + 1) * n];
        for (i, ki) in k.iter_mut().enumerate().take(n) {
            let mut sum = self.c[i];
            for (a, xj) in row(i).iter().zip(x) {
                sum += a * xj;
            }
            for (b, uj) in self.b[i * m..(i + 1) * m].iter().zip(u) {
                sum += b * uj;
            }
            *ki = sum;
        }
        // The three Horner terms written into `t`, `out` and `t` in turn
        // (no copies: a few states are too few to pay for one).
        let k: &[f64] = k;
        let horner = |from: &[f64], s: f64, into: &mut [f64]| {
            for (i, o) in into.iter_mut().enumerate().take(n) {
                let at: f64 = row(i).iter().zip(&from[..n]).map(|(a, t)| a * t).sum();
                *o = k[i] + s * at;
            }
        };
        horner(k, h / 4.0, t);
        horner(t, h / 3.0, out);
        horner(out, h / 2.0, t);
        for ((o, x), t) in out.iter_mut().zip(x).zip(&t[..n]) {
            *o = x + h * t;
        }
    }
}

/// A [`ClosedStep`] of `N` states and `M` inputs held in arrays, for a
/// simulator's inner loop: [`FixedStep::apply`] takes the same operations
/// in the same order as [`ClosedStep::apply`], without its size dispatch
/// and bounds checks, so that a small model's state can stay in registers
/// from one step to the next.
#[derive(Debug, Clone, Copy)]
pub struct FixedStep<const N: usize, const M: usize> {
    d: [[f64; N]; N],
    g: [[f64; M]; N],
    offset: [f64; N],
}

impl<const N: usize, const M: usize> FixedStep<N, M> {
    /// `x + D x + G u + g`, bit for bit [`ClosedStep::apply`]'s.
    #[inline(always)]
    pub fn apply(&self, x: &[f64; N], u: &[f64; M]) -> [f64; N] {
        std::array::from_fn(|i| {
            let mut increment = self.offset[i];
            for (a, xj) in self.d[i].iter().zip(x) {
                increment += a * xj;
            }
            for (g, uj) in self.g[i].iter().zip(u) {
                increment += g * uj;
            }
            x[i] + increment
        })
    }
}

/// `a * s` entrywise.
fn scaled(a: &[f64], s: f64) -> Vec<f64> {
    a.iter().map(|v| v * s).collect()
}

/// `a + s I` for an `n x n` matrix.
fn identity_plus(a: &[f64], s: f64, n: usize) -> Vec<f64> {
    let mut out = a.to_vec();
    for i in 0..n {
        out[i * n + i] += s;
    }
    out
}

/// The product of the row-major `n x n` matrix `a` and `n x m` matrix `b`.
fn product(a: &[f64], b: &[f64], n: usize, m: usize) -> Vec<f64> {
    let mut out = vec![0.0; n * m];
    for i in 0..n {
        for k in 0..n {
            let aik = a[i * n + k];
            for j in 0..m {
                out[i * m + j] += aik * b[k * m + j];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Classical RK4 of `dx/dt = A x + w`, stage by stage.
    fn stages(a: &[f64], w: &[f64], x: &[f64], h: f64) -> Vec<f64> {
        let n = x.len();
        let flow = |z: &[f64]| -> Vec<f64> {
            (0..n)
                .map(|i| w[i] + (0..n).map(|j| a[i * n + j] * z[j]).sum::<f64>())
                .collect()
        };
        let along =
            |k: &[f64], s: f64| -> Vec<f64> { x.iter().zip(k).map(|(x, k)| x + s * k).collect() };
        let k1 = flow(x);
        let k2 = flow(&along(&k1, 0.5 * h));
        let k3 = flow(&along(&k2, 0.5 * h));
        let k4 = flow(&along(&k3, h));
        (0..n)
            .map(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
            .collect()
    }

    /// [`FixedStep::apply`] on `N` states and `M` inputs against
    /// [`ClosedStep::apply`], to the bit.
    fn fixed_agrees<const N: usize, const M: usize>(seed: &[f64], h: f64) -> bool {
        let take = |from: usize, len: usize, scale: f64| -> Vec<f64> {
            seed[from..from + len].iter().map(|v| v * scale).collect()
        };
        let step = ClosedStep::new(
            take(0, N * N, 40.0),
            take(16, N * M, 10.0),
            take(24, N, 5.0),
            h,
        );
        let (x, u) = (take(32, N, 2.0), take(40, M, 1.0));
        let mut out = vec![0.0; N];
        step.apply(&x, &u, &mut out);
        let fixed = step.fixed::<N, M>().unwrap();
        let got = fixed.apply(&x.try_into().unwrap(), &u.try_into().unwrap());
        got.iter()
            .zip(&out)
            .all(|(a, b)| a.to_bits() == b.to_bits())
            && step.fixed::<N, 3>().is_none()
    }

    proptest! {
        /// The array form of a step is the step, to the bit, at every
        /// size the simulators specialise; it is refused at another size.
        #[test]
        fn the_fixed_step_is_the_step(seed in prop::collection::vec(-1.0f64..1.0, 48), h in 1e-4f64..0.05) {
            prop_assert!(fixed_agrees::<1, 1>(&seed, h));
            prop_assert!(fixed_agrees::<2, 1>(&seed, h));
            prop_assert!(fixed_agrees::<2, 2>(&seed, h));
            prop_assert!(fixed_agrees::<3, 1>(&seed, h));
            prop_assert!(fixed_agrees::<4, 1>(&seed, h));
            prop_assert!(fixed_agrees::<4, 2>(&seed, h));
        }

        /// One closed-form step, and one of another length by Horner,
        /// equal RK4's four stages; a zero row keeps its state exactly.
        #[test]
        fn the_closed_form_is_rk4(
            (n, m) in (1usize..5, 1usize..3),
            seed in prop::collection::vec(-1.0f64..1.0, 48),
            h in 1e-4f64..0.05,
            held_mask in 0u32..16,
            fraction in 0.0f64..1.0,
        ) {
            let take = |from: usize, len: usize, scale: f64| -> Vec<f64> {
                seed[from..from + len].iter().map(|v| v * scale).collect()
            };
            let (mut a, mut b, mut c) = (take(0, n * n, 40.0), take(16, n * m, 10.0), take(24, n, 5.0));
            let held: Vec<bool> = (0..n).map(|i| held_mask >> i & 1 == 1).collect();
            for i in (0..n).filter(|&i| held[i]) {
                a[i * n..(i + 1) * n].fill(0.0);
                b[i * m..(i + 1) * m].fill(0.0);
                c[i] = 0.0;
            }
            let (x, u) = (take(32, n, 2.0), take(40, m, 1.0));
            let w: Vec<f64> = (0..n)
                .map(|i| c[i] + (0..m).map(|j| b[i * m + j] * u[j]).sum::<f64>())
                .collect();
            let step = ClosedStep::new(a.clone(), b, c, h);
            let mut out = vec![0.0; n];
            step.apply(&x, &u, &mut out);
            let want = stages(&a, &w, &x, h);
            let short = h * fraction;
            let (mut k, mut t, mut out_short) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            step.apply_length(short, &x, &u, (&mut k, &mut t), &mut out_short);
            let want_short = stages(&a, &w, &x, short);
            for (got, want) in [(&out, &want), (&out_short, &want_short)] {
                for i in 0..n {
                    let scale = 1.0 + want[i].abs() + x[i].abs();
                    prop_assert!((got[i] - want[i]).abs() <= 1e-12 * scale, "{i}: {} vs {}", got[i], want[i]);
                    if held[i] {
                        prop_assert_eq!(got[i], x[i]);
                    }
                }
            }
        }
    }
}
