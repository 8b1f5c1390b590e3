//! The founding experiment's record through the CLI, on the benchmark
//! protocol of `docs/cli.md` (decimate 10, identify rows
//! 0..5000, score rows 5000..6001 with warm-up 10).

use std::process::Command;

const DATA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../models/pick-and-place/headdata_1v6.mat"
);

/// Runs `hysid` and asserts it succeeded.
fn run(args: &[&str]) -> std::process::Output {
    let o = Command::new(env!("CARGO_BIN_EXE_hysid"))
        .args(args)
        .env("CI", "1")
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Standard output of a successful run.
fn hysid(args: &[&str]) -> String {
    String::from_utf8(run(args).stdout).unwrap()
}

/// Standard error of a successful run.
fn hysid_stderr(args: &[&str]) -> String {
    String::from_utf8_lossy(&run(args).stderr).into_owned()
}

/// Identifies with `method_args` (na = nb = 2) on rows 0..5000 of the
/// decimated record and returns `validate --json` on rows 5000..6001,
/// warm-up 10: the benchmark protocol.
fn on_the_protocol(method_args: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.json");
    let m = model.to_str().unwrap();
    let mut args = vec!["identify", DATA, "--na", "2", "--nb", "2"];
    args.extend_from_slice(method_args);
    args.extend_from_slice(&["--decimate", "10", "--rows", "0..5000", "-o", m]);
    hysid(&args);
    serde_json::from_str(&hysid(&[
        "validate",
        m,
        DATA,
        "--decimate",
        "10",
        "--rows",
        "5000..6001",
        "--warmup",
        "10",
        "--json",
    ]))
    .unwrap()
}

#[test]
fn arx_baseline_on_the_protocol() {
    let v = on_the_protocol(&["-m", "arx"]);
    let fit_sim = v["fit_sim"].as_f64().unwrap();
    let fit_pred = v["fit_pred"].as_f64().unwrap();
    // Reference point of the protocol, quoted by the README and the main
    // job's report: ARX(2,2) with offset, least squares (deterministic),
    // 70.48 % in simulation and 99.80 % one step ahead.
    assert!((fit_sim - 70.48).abs() < 0.005, "fit_sim {fit_sim}");
    assert!((fit_pred - 99.80).abs() < 0.005, "fit_pred {fit_pred}");
    assert_eq!(v["n"], 991);
    assert_eq!(v["coverage"], 1.0);
}

#[test]
fn the_record_reads_with_its_time_base() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("arx.json");
    let m = model.to_str().unwrap();
    hysid(&["identify", DATA, "-m", "arx", "--decimate", "10", "-o", m]);
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    // 4 kHz decimated by 10: Ts = 2.5 ms, 6001 samples minus the lag of 2.
    assert!((j["info"]["ts"].as_f64().unwrap() - 0.0025).abs() < 1e-12);
    assert_eq!(j["info"]["diagnostics"]["samples"], 5999);
}

/// The choice of `c` on the real record, through `hysid sweep` (the helper that
/// chooses `c` and the mode count by validation simulation FIT): `c` at its
/// theoretical minimum (`n + 2 = 6` for na = nb = 2) gives clearly worse
/// models than a large `c` at every mode count (the founding paper's
/// finding), and the best point of `docs/cluster.md` (c = 320, 5 modes,
/// seed 1) passes the 80 % target; all with the published procedure
/// (`preset=paper`). Measured (release and test builds
/// alike): c = 6: 59.4 / 70.2 %, c = 320: 74.3 / 79.6 % (2 / 3 modes);
/// c = 320, 5 modes: 89.4 %.
#[test]
fn cluster_c_sweep_reproduces_the_paper_and_meets_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    let table = hysid(&[
        "sweep",
        DATA,
        "-m",
        "cluster",
        "--grid",
        "c=6,320",
        "--grid",
        "modes=2,3",
        "--decimate",
        "10",
        "--identify-rows",
        "0..5000",
        "--validate-rows",
        "5000..6001",
        "--seed",
        "1",
        "--set",
        "preset=paper",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(
        table
            .lines()
            .filter(|l| l.starts_with("| cluster [c="))
            .count(),
        4,
        "the table on stdout has one row per grid point:\n{table}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let fit = |c: &str, modes: &str| -> f64 {
        let row = report["results"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| {
                let v = &r["sweep"]["values"];
                v[0][1] == c && v[1][1] == modes
            })
            .unwrap_or_else(|| panic!("no sweep point c = {c}, modes = {modes}"));
        assert_eq!(row["modes"].as_u64(), Some(modes.parse().unwrap()));
        assert!(
            out.join(row["model_file"].as_str().unwrap()).is_file(),
            "model file of c = {c}, modes = {modes}"
        );
        row["report"]["fit_sim"].as_f64().unwrap()
    };
    for modes in ["2", "3"] {
        let (small, large) = (fit("6", modes), fit("320", modes));
        assert!(
            large > small + 5.0,
            "{modes} modes: c = 320 gives {large:.2} %, c = 6 {small:.2} %"
        );
    }
    let v = on_the_protocol(&[
        "-m",
        "cluster",
        "--modes",
        "5",
        "--set",
        "c=320",
        "--set",
        "preset=paper",
        "--seed",
        "1",
    ]);
    let fit_sim = v["fit_sim"].as_f64().unwrap();
    assert!(
        fit_sim >= 80.0,
        "cluster c = 320, 5 modes: fit_sim {fit_sim:.2} %"
    );
    assert_eq!(v["coverage"], 1.0);
}

#[test]
fn a_hybrid_model_below_the_affine_one_is_flagged() {
    // cluster as published at c = 10 with 2 modes simulates the record
    // worse than ARX(2,2) on its own identification rows (72.8 % against
    // 75.0 %).
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.json");
    let m = model.to_str().unwrap();
    let err = hysid_stderr(&[
        "identify",
        DATA,
        "-m",
        "cluster",
        "--na",
        "2",
        "--nb",
        "2",
        "--modes",
        "2",
        "--set",
        "c=10",
        "--set",
        "preset=paper",
        "--decimate",
        "10",
        "--rows",
        "0..5000",
        "-o",
        m,
    ]);
    assert!(
        err.contains("is below that of an affine ARX(2,2) fitted on these same rows"),
        "{err}"
    );
    // ARX itself is never compared with itself.
    let err = hysid_stderr(&[
        "identify",
        DATA,
        "-m",
        "arx",
        "--decimate",
        "10",
        "--rows",
        "0..5000",
        "-o",
        m,
    ]);
    assert!(!err.contains("warning"), "{err}");
}

/// The prior file of docs/priors.md, as printed there, on the record:
/// `cluster` and `bounded` run it (an equality, a fixed offset and a bound
/// together, where clarabel at strict tolerances makes no progress) and every
/// ordinary mode honours it: `b1 = b2`, `c = 0`, `b1` in `[0, 1e3]`.
#[test]
fn the_prior_file_of_the_reference_runs_on_the_record() {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/priors.md"))
            .unwrap();
    let example = text
        .split("```toml\n")
        .nth(1)
        .and_then(|t| t.split("```").next())
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let priors = dir.path().join("priors.toml");
    std::fs::write(&priors, example).unwrap();
    for method in ["cluster", "bounded"] {
        let out = dir.path().join(format!("{method}.json"));
        let (p, o) = (priors.to_str().unwrap(), out.to_str().unwrap());
        hysid_stderr(&[
            "identify",
            DATA,
            "--decimate",
            "10",
            "--rows",
            "0..5000",
            "-m",
            method,
            "--prior",
            p,
            "-o",
            o,
        ]);
        let model: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let modes = model["modes"].as_array().unwrap();
        assert_eq!(modes.len(), 4, "{method}");
        // The ordinary modes (the two stops' are `sat_max_25`, `sat_min_0`).
        let ordinary = modes
            .iter()
            .filter(|m| !m["name"].as_str().unwrap().starts_with("sat_"));
        assert_eq!(ordinary.clone().count(), 2, "{method}");
        for mode in ordinary {
            let flow = &mode["flow"];
            let (b1, b2) = (
                flow["b"][0][0].as_f64().unwrap(),
                flow["a"][0][2].as_f64().unwrap(),
            );
            let c = flow["f"][0].as_f64().unwrap();
            assert!((b1 - b2).abs() <= 1e-12, "{method}: {b1} {b2}");
            assert!((0.0..=1e3).contains(&b1) && c == 0.0, "{method}: {b1} {c}");
        }
    }
}
