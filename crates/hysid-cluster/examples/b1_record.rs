//! Writes a B1 record (the three-mode PWARX of Ferrari-Trecate et al. 2003,
//! `hysid_testkit::b1`: `u ~ U[-4, 4]`, noise `U[-0.1, 0.1]`) of `N`
//! samples as a CSV file with columns `u,y`, for the end-to-end timings of
//! `hysid identify` in `docs/performance-cluster.md`.
//!
//! ```text
//! cargo run --release -p hysid-cluster --example b1_record -- N SEED OUT.csv
//! ```

use hysid_testkit::Noise;
use std::io::{BufWriter, Write};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [n, seed, out] = args.as_slice() else {
        return Err("usage: b1_record N SEED OUT.csv".into());
    };
    let record = hysid_testkit::b1(n.parse()?, 4.0, Noise::Uniform(0.1), seed.parse()?);
    let mut w = BufWriter::new(std::fs::File::create(out)?);
    writeln!(w, "u,y")?;
    for (u, y) in record.data.u(0).iter().zip(record.data.y()) {
        writeln!(w, "{u},{y}")?;
    }
    w.flush()?;
    Ok(())
}
