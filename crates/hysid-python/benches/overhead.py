"""What identification from Python costs against the program, on the same
data, measured in one run (docs/performance.md, "Python").

For each job the program runs `hysid identify DATA ... -o MODEL.json` (a
process: reading the file, identifying, the comparison with the affine
model, writing the model) and Python runs `hysid.load`, `hysid.identify`
and `Model.save` with the same arguments in this process. Both are timed
wall-clock over REPEATS alternating runs; the table gives the medians and
their ratio.

Run (release builds of both):
    cargo build --release -p hysid-cli
    pip install crates/hysid-python
    python crates/hysid-python/benches/overhead.py [--repeats 15]
"""

import argparse
import pathlib
import statistics
import subprocess
import tempfile
import time
import warnings

import hysid

REPO = pathlib.Path(__file__).resolve().parents[3]
PP = REPO / "models" / "pick-and-place" / "headdata_1v6.mat"
BOTH = REPO / "models" / "pick-and-place" / "simulated" / "both-saturations.csv"

# (label, data file, load arguments, identify arguments)
JOBS = [
    ("arx(2,2), pick-and-place", PP, {"decimate": 10, "rows": (0, 5000)}, {"method": "arx"}),
    ("cluster, 3 modes, pick-and-place", PP, {"decimate": 10, "rows": (0, 5000)},
     {"method": "cluster", "modes": 3, "seed": 1}),
    ("cluster, 5 modes, c=320, pick-and-place", PP, {"decimate": 10, "rows": (0, 5000)},
     {"method": "cluster", "modes": 5, "seed": 1, "options": {"c": 320}}),
    ("bounded, delta=0.05, simulated head", BOTH, {"rows": (0, 4000)},
     {"method": "bounded", "options": {"delta": 0.05}}),
]


def cli_args(exe, data, load, ident, out):
    args = [exe, "identify", str(data), "-m", ident["method"], "-o", str(out)]
    if "decimate" in load:
        args += ["--decimate", str(load["decimate"])]
    a, b = load["rows"]
    args += ["--rows", f"{a}..{b}"]
    if "modes" in ident:
        args += ["--modes", str(ident["modes"])]
    if "seed" in ident:
        args += ["--seed", str(ident["seed"])]
    for k, v in ident.get("options", {}).items():
        args += ["--set", f"{k}={v}"]
    return args


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--program", default=str(REPO / "target" / "release" / "hysid"))
    a = parser.parse_args()
    # The warning on the affine model is printed by both; not timed twice here.
    warnings.simplefilter("ignore")
    out = pathlib.Path(tempfile.mkdtemp())
    print("| job | program (median, s) | Python (median, s) | Python / program |")
    print("|---|---|---|---|")
    for label, data, load, ident in JOBS:
        cli, py = [], []
        for _ in range(a.repeats):
            t = time.perf_counter()
            subprocess.run(cli_args(a.program, data, load, ident, out / "cli.json"), check=True,
                           capture_output=True)
            cli.append(time.perf_counter() - t)
            t = time.perf_counter()
            u, y, ts = hysid.load(data, **load)
            model = hysid.identify(u, y, ts=ts, **ident)
            model.save(out / "py.json")
            py.append(time.perf_counter() - t)
        # The same model both ways.
        assert (hysid.Model.load(out / "cli.json").thetas == model.thetas).all(), label
        c, p = statistics.median(cli), statistics.median(py)
        print(f"| {label} | {c:.4f} | {p:.4f} | {p / c:.3f} |")


if __name__ == "__main__":
    main()
