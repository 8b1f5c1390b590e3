"""Identification from numpy: the README's figures, files shared with the
program, priors, options and automatic selection."""

import json
import warnings

import numpy as np
import pytest

import hysid
from conftest import BOTH_STOPS, PICK_AND_PLACE


def test_arx_reproduces_the_pick_and_place_figure(record):
    u, y, ts = record
    assert u.shape == (6001, 1) and y.shape == (6001,) and ts == pytest.approx(0.0025)
    model = hysid.identify(u[:5000], y[:5000], method="arx", na=2, nb=2, ts=ts)
    report = model.validate(u[5000:6001], y[5000:6001])
    assert round(report["fit_sim"], 2) == 70.48
    assert report["n"] == 991 and report["warmup"] == 10


def test_a_model_from_python_validates_in_the_program_to_the_same_figures(record, program, tmp_path):
    u, y, ts = record
    # The published procedure, which on these rows falls below ARX(2,2).
    model = hysid.identify(u[:5000], y[:5000], method="cluster", modes=3, seed=2, ts=ts,
                           options={"preset": "paper"})
    path = tmp_path / "cluster.json"
    model.save(path)
    out = program("validate", path, PICK_AND_PLACE, "--decimate", "10", "--rows", "5000..6001", "--json")
    theirs = json.loads(out.stdout)
    # This model simulates the test rows worse than ARX(2,2) does, and
    # both front ends say so.
    with pytest.warns(UserWarning, match="below that of an affine ARX"):
        ours = model.validate(u[5000:6001], y[5000:6001])
    assert theirs == ours
    assert "below that of an affine ARX" in out.stderr and "fitted on these same rows" in out.stderr


def test_a_model_from_the_program_loads_and_validates_here_to_the_same_figures(record, program, tmp_path):
    u, y, _ = record
    path = tmp_path / "arx.json"
    program("identify", PICK_AND_PLACE, "-m", "arx", "--na", "3", "--nb", "3",
            "--decimate", "10", "--rows", "0..5000", "-o", path)
    model = hysid.Model.load(path)
    assert model.kind == "pwarx" and model.orders == (3, 3) and model.method == "arx"
    theirs = json.loads(program("validate", path, PICK_AND_PLACE, "--decimate", "10",
                                "--rows", "5000..6001", "--json").stdout)
    assert model.validate(u[5000:6001], y[5000:6001]) == theirs
    # The same identification from Python writes the same file.
    again = hysid.identify(u[:5000], y[:5000], method="arx", na=3, nb=3, ts=model.ts)
    assert json.loads(again.to_json())["modes"] == json.loads(path.read_text())["modes"]


def test_identification_is_deterministic_for_a_seed(record):
    u, y, ts = record
    a = hysid.identify(u[:3000], y[:3000], method="cluster", modes=3, seed=5, ts=ts)
    b = hysid.identify(u[:3000], y[:3000], method="cluster", modes=3, seed=5, ts=ts)
    assert a.to_json() == b.to_json()


def test_options_are_those_of_set_and_are_recorded(record):
    u, y, ts = record
    model = hysid.identify(u[:5000], y[:5000], method="cluster", modes=2,
                           options={"c": 40, "reattribute": False}, seed=1, ts=ts)
    used = model.info["options"]
    assert used["c"] == 40 and used["reattribute"] is False


def test_stop_priors_become_stop_modes():
    u, y, ts = hysid.load(BOTH_STOPS, rows=(0, 4000))
    priors = {"saturation": [{"level": 0.0, "bound": "min", "tol": 0.02},
                             {"level": 25.0, "bound": "max", "tol": 0.02}]}
    # The mode count includes the two stop modes.
    model = hysid.identify(u, y, method="cluster", modes=4, priors=priors, seed=1, ts=ts)
    assert model.kind == "hybrid_automaton"
    assert sorted(model.stops) == [(0.0, "min"), (25.0, "max")]
    sim, modes = model.simulate(u, y0=y[:2])
    # After the two measured initial outputs, the simulation never passes a stop.
    assert (modes[:2] == -1).all() and (modes[2:] >= 0).all()
    assert sim[2:].min() >= 0.0 and sim[2:].max() <= 25.0


def test_priors_from_a_file_and_from_a_dictionary_give_the_same_model(record, tmp_path):
    u, y, ts = record
    path = tmp_path / "ties.toml"
    path.write_text('[[tie]]\nparams = ["b1", "b2"]\n')
    from_file = hysid.identify(u[:5000], y[:5000], method="cluster", modes=2, priors=path, seed=1, ts=ts)
    from_dict = hysid.identify(u[:5000], y[:5000], method="cluster", modes=2,
                               priors={"tie": [{"params": ["b1", "b2"]}]}, seed=1, ts=ts)
    assert from_file.thetas.tolist() == from_dict.thetas.tolist()
    # The tie holds: b1 and b2 (columns 2 and 3 of na = nb = 2) are shared by the modes.
    thetas = from_dict.thetas
    assert np.ptp(thetas[:, 2]) < 1e-9 and np.ptp(thetas[:, 3]) < 1e-9


def test_auto_chooses_on_the_last_fifth_and_records_its_candidates(record):
    u, y, ts = record
    grid = {"na": [1, 2], "nb": [1, 2]}
    model = hysid.identify(u[:5000], y[:5000], method="arx", auto=True, grid=grid, ts=ts)
    selection = model.info["selection"]
    assert [s["select_rows"] for s in selection["splits"]] == ["4000..5000"]
    scores = [c["fit_sim"] for c in selection["candidates"]]
    # The four orders, then the best one refined on simulation error.
    assert len(scores) == 5 and selection["candidates"][4]["values"][-1] == ["refine", "sim"]
    assert selection["candidates"][selection["chosen"]]["fit_sim"] == max(scores)
    # Other selection rows, another split recorded.
    other = hysid.identify(u[:5000], y[:5000], method="arx", auto=True, grid=grid, select_rows=(0, 1000), ts=ts)
    assert [s["select_rows"] for s in other.info["selection"]["splits"]] == ["0..1000"]
    # arx's fit does not depend on the seed: one refit start, written.
    assert [(r["seed"], r["kept"]) for r in model.info["selection"]["refit"]] == [(0, True)]


def test_multiple_inputs_take_a_two_dimensional_u():
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, size=(800, 2))
    y = np.zeros(800)
    for k in range(1, 800):
        y[k] = 0.5 * y[k - 1] + 0.8 * u[k - 1, 0] - 0.3 * u[k - 1, 1]
    model = hysid.identify(u, y, method="arx", na=1, nb=1)
    assert model.inputs == 2
    assert np.allclose(model.thetas[0], [0.5, 0.8, -0.3, 0.0], atol=1e-9)


def test_methods_lists_every_back_end_with_options_and_priors():
    listed = {m["name"]: m for m in hysid.methods()}
    assert {"arx", "cluster", "bounded", "physical"} <= set(listed)
    keys = {o["key"] for o in listed["cluster"]["options"]}
    assert {"c", "regions", "refine"} <= keys
    assert "saturation" in listed["cluster"]["priors"]


def test_a_record_with_its_own_column_names_loads_with_its_time(tmp_path):
    path = tmp_path / "rec.csv"
    t = np.arange(200) * 0.004
    rows = "\n".join(f"{a:.3f},{np.sin(a):.6f},{np.cos(a):.6f}" for a in t)
    path.write_text("clock,force,pos\n" + rows + "\n")
    u, y, ts = hysid.load(path, inputs="force", output="pos", time="clock")
    assert u.shape == (200, 1) and y.shape == (200,)
    assert ts == pytest.approx(0.004)
    # Without the name, the time column is not found and no sampling time is read.
    assert hysid.load(path, inputs="force", output="pos")[2] is None
    with pytest.raises(hysid.HysidError, match="'stamp'"):
        hysid.load(path, inputs="force", output="pos", time="stamp")


def test_several_records_fit_one_model_and_validate_each(record, program, tmp_path):
    u, y, ts = record
    us, ys = [u[:2500], u[2500:5000]], [y[:2500], y[2500:5000]]
    model = hysid.identify(us, ys, method="arx", na=2, nb=2, ts=ts)
    # The same records as two files in the program give the same model.
    files = []
    for i, (ui, yi) in enumerate(zip(us, ys)):
        path = tmp_path / f"r{i}.csv"
        t = ts * np.arange(len(yi))
        np.savetxt(path, np.column_stack([t, ui[:, 0], yi]), delimiter=",", header="t,u,y",
                   comments="")
        files.append(path)
    out = tmp_path / "arx.json"
    program("identify", *files, "-m", "arx", "--na", "2", "--nb", "2", "-o", out)
    assert json.loads(model.to_json())["modes"] == json.loads(out.read_text())["modes"]
    # Not the model of the rows as one record.
    one = hysid.identify(u[:5000], y[:5000], method="arx", na=2, nb=2, ts=ts)
    assert json.loads(one.to_json())["modes"] != json.loads(model.to_json())["modes"]
    report = model.validate(us, ys)
    assert [r["n"] for r in report["records"]] == [2490, 2490] and report["n"] == 4980
    assert report["records"][1] == model.validate(us[1], ys[1])
    with pytest.raises(hysid.InputError, match="record 2: "):
        hysid.identify(us, [ys[0], ys[1][:-1]], method="arx")
    with pytest.raises(hysid.InputError, match=r"3 input record\(s\) for 2 output record"):
        hysid.identify(us + [u[:10]], ys, method="arx")
    with pytest.raises(hysid.InputError, match="select_records=2: must be between 1"):
        hysid.identify(us, ys, method="arx", auto=True, select_records=2)


LAG = """kind = "gray_box"
format = 1
internal_step = 0.025
states = ["x"]
inputs = ["u"]
outputs = ["x"]
initial_state = {{ from = "given", values = {{ x = 0.0 }} }}
parameters = [{{ name = "a", value = {a}, bounds = [{low}, 4.0] }}]

[[modes]]
name = "only"
flow = {{ x = "-a*x + u" }}
"""


def test_a_physical_fit_warns_of_a_parameter_at_a_bound(tmp_path):
    truth = tmp_path / "truth.toml"
    truth.write_text(LAG.format(a=0.8, low=0.2))
    u = np.repeat(np.random.default_rng(1).uniform(-1, 1, 20), 10)
    y, _ = hysid.Model.load(truth).simulate(u, ts=0.05)
    held = tmp_path / "held.toml"
    held.write_text(LAG.format(a=2.0, low=1.5))
    # The record asks for a = 0.8; the file's bounds stop the fit at 1.5.
    with pytest.warns(UserWarning, match=r"^physical: a = 1\.5 ended at a bound") as said:
        hysid.identify(u, y, method="physical", ts=0.05, options={"model": str(held)})
    assert {w.filename for w in said} == {__file__}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hysid.identify(u, y, method="physical", ts=0.05, options={"model": str(truth)})
