"""hysid's `parc` and `cluster` beside PyPARC 2.0.4 on the same records,
in one run: identification time end to end and mode accuracy on a fresh
record (docs/parc.md, "Beside PyPARC"; docs/performance.md). Not run in CI; PyPARC is not a
dependency of the repository.

The record: a 3-mode PWARX system, na = 2, nb = 1, regressor
x = [y(k-1), y(k-2), u(k-1)], two hyperplane boundaries,
u uniform in [-2, 2], Gaussian equation noise of standard deviation 0.1,
N = 8000 for identification and a fresh N = 8000 (another seed) to score
the regions. Mode accuracy: the share of fresh regressors whose identified
region is their true mode, after the best matching of modes.

PyPARC 2.0.4 needs, in a throwaway virtual environment:
    pip install "scikit-learn==1.6.1" numpy scipy matplotlib faiss-cpu mip
    pip install --no-deps pyparc==2.0.4
and an empty module `pypoman` (used for plots only), since pypoman's
dependency pycddlib does not build.

Run: cargo build --release -p hysid-cli
     python crates/hysid-parc/benches/pyparc_side_by_side.py [--repeats 5]
"""

import argparse
import itertools
import json
import pathlib
import statistics
import subprocess
import tempfile
import time

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[3]
THETAS = np.array([[0.6, -0.2, 1.0, 0.3], [0.3, 0.2, -1.0, 0.0], [-0.4, 0.1, 0.5, -0.3]])


def true_mode(x):
    """Mode 0 where y(k-1) + u(k-1) <= -0.5, else mode 2 where
    y(k-1) - u(k-1) >= 0.5, else mode 1."""
    if x[0] + x[2] <= -0.5:
        return 0
    if x[0] - x[2] >= 0.5:
        return 2
    return 1


def record(n, seed):
    rng = np.random.default_rng(seed)
    u = rng.uniform(-2, 2, n)
    y = np.zeros(n)
    modes = np.full(n, -1)
    for k in range(2, n):
        x = np.array([y[k - 1], y[k - 2], u[k - 1]])
        q = true_mode(x)
        y[k] = THETAS[q, :3] @ x + THETAS[q, 3] + rng.normal(0, 0.1)
        modes[k] = q
    return u, y, modes


def regressors(u, y):
    return np.column_stack([y[1:-1], y[:-2], u[1:-1]]), y[2:]


def accuracy(truth, found, k):
    best = 0.0
    for perm in itertools.permutations(range(max(k, 3))):
        best = max(best, np.mean([perm[f] == t if f < len(perm) else False for t, f in zip(truth, found)]))
    return best


def hysid_regions(model_file):
    m = json.loads(pathlib.Path(model_file).read_text())
    return [(np.array(q["region"].get("a", []) or np.zeros((0, 3))), np.array(q["region"].get("b", []))) for q in m["modes"]]


def classify(regions, X):
    out = []
    for x in X:
        viol = [np.max(A @ x - b, initial=-np.inf) if len(b) else -np.inf for A, b in regions]
        out.append(int(np.argmin(viol)))
    return np.array(out)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=5)
    a = parser.parse_args()
    from pyparc.parc import PARC

    d = pathlib.Path(tempfile.mkdtemp())
    u, y, _ = record(8000, 1)
    np.savetxt(d / "train.csv", np.column_stack([u, y]), delimiter=",", header="u,y", comments="")
    uf, yf, mf = record(8000, 2)
    Xf, _ = regressors(uf, yf)
    truth = mf[2:]
    exe = str(REPO / "target" / "release" / "hysid")
    rows = []
    runs = [
        ("hysid parc, K = 3", "parc", []),
        ("hysid cluster, 3 modes, as published", "cluster", ["--set", "preset=paper"]),
        ("hysid cluster, 3 modes (the alternation by default)", "cluster", []),
    ]
    for k, (label, method, extra) in enumerate(runs):
        times = []
        model = d / f"{k}.json"
        for _ in range(a.repeats):
            t = time.perf_counter()
            subprocess.run([exe, "identify", str(d / "train.csv"), "-m", method, "--modes", "3", "--na", "2",
                            "--nb", "1", "--seed", "1", *extra, "-o", str(model)], check=True,
                           capture_output=True)
            times.append(time.perf_counter() - t)
        found = classify(hysid_regions(model), Xf)
        rows.append((label, statistics.median(times), accuracy(truth, found, 3)))
    times = []
    for _ in range(a.repeats):
        t = time.perf_counter()
        data = np.loadtxt(d / "train.csv", delimiter=",", skiprows=1)
        X, Y = regressors(data[:, 0], data[:, 1])
        model = PARC(K=3)
        model.fit(X, Y)
        times.append(time.perf_counter() - t)
    _, found = model.predict(Xf)
    rows.append(("PyPARC 2.0.4, K = 3", statistics.median(times), accuracy(truth, found, model.K)))
    print("| method | end to end (median, s) | mode accuracy on a fresh record |")
    print("|---|---|---|")
    for label, t, acc in rows:
        print(f"| {label} | {t:.3f} | {100 * acc:.1f} % |")
    for label, t, _ in rows[:-1]:
        print(f"PyPARC / {label}: {rows[-1][1] / t:.0f} times the time")


if __name__ == "__main__":
    main()
