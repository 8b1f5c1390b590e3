//! The record both reading benchmarks write: `rows` samples of t (steps of
//! 1 ms), u (a telegraph-like input, a new level about every 50 samples,
//! from xorshift64) and y (a first-order response to u).

/// Every sample `(t, u, y)`, in order.
pub fn signals(rows: usize) -> impl Iterator<Item = (f64, f64, f64)> {
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let (mut u, mut y) = (0.0_f64, 0.0_f64);
    (0..rows).map(move |k| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        if state.is_multiple_of(50) || k == 0 {
            u = (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
        }
        y = 0.95 * y + 0.05 * u;
        (k as f64 * 1e-3, u, y)
    })
}
