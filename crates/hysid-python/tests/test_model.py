"""Model: simulation and prediction against the PWARX equations computed
here, regions and stops, files."""

import numpy as np
import pytest

import hysid


def two_mode_model():
    """y(k) = a_q y(k-1) + b_q u(k-1) + c_q, mode 1 where y(k-1) <= 0."""
    return hysid.Model.from_json("""{
      "kind": "pwarx", "na": 1, "nb": 1, "inputs": 1,
      "modes": [
        {"theta": [0.5, 1.0, 0.1], "region": {"a": [[1.0, 0.0]], "b": [0.0]}},
        {"theta": [0.8, -0.5, -0.2], "region": {"a": [[-1.0, 0.0]], "b": [0.0]}}
      ]
    }""")


def reference(u, y0):
    y = np.zeros(len(u))
    y[0] = y0
    modes = np.full(len(u), -1)
    for k in range(1, len(u)):
        q = 0 if y[k - 1] <= 0 else 1
        a, b, c = [(0.5, 1.0, 0.1), (0.8, -0.5, -0.2)][q]
        y[k] = a * y[k - 1] + b * u[k - 1] + c
        modes[k] = q
    return y, modes


def test_simulation_follows_the_piecewise_equations():
    model = two_mode_model()
    u = np.random.default_rng(1).uniform(-1, 1, 300)
    y, modes = model.simulate(u, y0=[0.3])
    want_y, want_modes = reference(u, 0.3)
    assert np.allclose(y, want_y, atol=1e-12)
    assert (modes == want_modes).all()
    assert {0, 1} <= set(modes[1:].tolist())


def test_prediction_is_one_step_from_the_measured_output():
    model = two_mode_model()
    rng = np.random.default_rng(2)
    u, y = rng.uniform(-1, 1, 200), rng.normal(0, 1, 200)
    pred, modes = model.predict(u, y)
    for k in range(1, 200):
        q = 0 if y[k - 1] <= 0 else 1
        a, b, c = [(0.5, 1.0, 0.1), (0.8, -0.5, -0.2)][q]
        assert pred[k] == pytest.approx(a * y[k - 1] + b * u[k - 1] + c, abs=1e-12)
        assert modes[k] == q


def test_validation_scores_a_perfect_model_at_one_hundred_percent():
    model = two_mode_model()
    u = np.random.default_rng(3).uniform(-1, 1, 400)
    y, _ = reference(u, -0.2)
    report = model.validate(u, y, warmup=5)
    assert report["fit_sim"] == pytest.approx(100.0) and report["fit_pred"] == pytest.approx(100.0)
    assert report["n"] == 395 and sum(report["mode_counts"]) == 395


def test_a_fit_over_a_constant_output_is_said_to_be_undefined():
    model = two_mode_model()
    u = np.random.default_rng(3).uniform(-1, 1, 400)
    with pytest.warns(RuntimeWarning, match="the scored output is constant: FIT is undefined"):
        report = model.validate(u, np.full(400, 2.0))
    assert report["constant_output"] is True and report["fit_sim"] == 0.0
    y, _ = reference(u, -0.2)
    assert "constant_output" not in model.validate(u, y)


def test_a_model_describes_itself_as_hysid_show_does():
    text = two_mode_model().describe()
    assert str(two_mode_model()) == text
    assert text.startswith("pwarx model, 2 mode(s)")
    assert "mode 1: y(k) = 0.5 y(k-1) + u(k-1) + 0.1\n  where y(k-1) <= 0\n" in text
    assert "mode 2: y(k) = 0.8 y(k-1) - 0.5 u(k-1) - 0.2\n  where -y(k-1) <= 0\n" in text


def test_structure_is_exposed_as_arrays():
    model = two_mode_model()
    assert model.kind == "pwarx" and model.mode_count == 2 and model.orders == (1, 1)
    assert model.thetas.shape == (2, 3)
    (a0, b0), (a1, b1) = model.regions
    assert a0.shape == (1, 2) and b0.tolist() == [0.0]
    assert a1.tolist() == [[-1.0, 0.0]]
    assert model.stops == []


def test_files_round_trip(tmp_path):
    model = two_mode_model()
    path = tmp_path / "m.json"
    model.save(path)
    again = hysid.Model.load(path)
    assert again.to_json() == model.to_json()
    assert "Model(kind='pwarx'" in repr(again)


def test_a_mechanical_model_simulates_from_its_file():
    import pathlib

    head = pathlib.Path(__file__).resolve().parents[3] / "models" / "pick-and-place" / "head.toml"
    model = hysid.Model.load(head)
    assert model.kind == "mechanical" and sorted(model.stops) == [(0.0, "min"), (25.0, "max")]
    u = np.full(2000, -0.1)
    y, modes = model.simulate(u, ts=0.0025)
    assert np.isfinite(y).all() and y.min() >= -1e-9 and y.max() <= 25.0 + 1e-9


def test_a_physical_model_starts_from_the_state_given():
    import pathlib

    axis = pathlib.Path(__file__).resolve().parents[3] / "models" / "examples" / "positioning-axis.toml"
    model = hysid.Model.load(axis)
    u = np.zeros(30)
    # At rest under no input, the axis sticks where it was put.
    y, _ = model.simulate(u, ts=0.01, x0={"q": 0.25, "v": 0.0})
    assert (y == 0.25).all()
    y, _ = model.simulate(u, ts=0.01, x0={"q": 0.25, "v": 0.05})
    assert y[0] == 0.25 and y[-1] > 0.25
    with pytest.raises(ValueError, match=r"x0: no value for the state 'v' \(give every state: q, v\)"):
        model.simulate(u, ts=0.01, x0={"q": 0.25})
    with pytest.raises(ValueError, match="x0: q = NaN is not finite"):
        model.simulate(u, ts=0.01, x0={"q": float("nan"), "v": 0.0})
    with pytest.raises(ValueError, match="x0 and y0: give one"):
        model.simulate(u, ts=0.01, x0={"q": 0.25, "v": 0.0}, y0=[0.0])
    with pytest.raises(ValueError, match="x0: a pwarx model has no state"):
        two_mode_model().simulate(u, x0={"y": 1.0})


def test_a_file_that_extends_another_reads_as_its_base_with_the_changes():
    import pathlib

    models = pathlib.Path(__file__).resolve().parents[3] / "models" / "pick-and-place"
    base = hysid.Model.load(models / "structures" / "load-bounce.toml")
    free_f1 = hysid.Model.load(models / "structures" / "load-bounce-f1.toml")
    assert base.kind == free_f1.kind == "gray_box"
    # load-bounce-f1 changes only the kinetic friction's bounds (its
    # lower bound 0 instead of 200), so at the nominal values both
    # simulate alike.
    import json

    a, b = json.loads(base.to_json()), json.loads(free_f1.to_json())
    f1 = [[p["bounds"] for p in m["parameters"] if p["name"] == "f1"][0] for m in (a, b)]
    assert f1 == [[200.0, 1200.0], [0.0, 1200.0]]
    del a["parameters"], b["parameters"], a["name"], b["name"]
    assert a == b
    u = np.full(2000, -0.1)
    y0, _ = base.simulate(u, ts=0.0025)
    y1, _ = free_f1.simulate(u, ts=0.0025)
    assert np.isfinite(y0).all() and np.array_equal(y0, y1)


def test_a_mechanical_model_as_a_gray_box_simulates_alike(tmp_path):
    import pathlib

    head = pathlib.Path(__file__).resolve().parents[3] / "models" / "pick-and-place" / "head.toml"
    mechanical = hysid.Model.load(head)
    gray = mechanical.to_gray_box()
    assert gray.kind == "gray_box"
    assert sorted(gray.mode_names) == sorted(mechanical.mode_names)
    gray.save(tmp_path / "head-gray.toml")
    again = hysid.Model.load(tmp_path / "head-gray.toml")
    u = np.repeat(np.random.default_rng(3).uniform(-0.3, 0.05, 30), 120)
    runs = [m.simulate(u, ts=0.0025) for m in (mechanical, gray, again)]
    names = [[m.mode_names[q] if q >= 0 else None for q in modes]
             for m, (_, modes) in zip((mechanical, gray, again), runs)]
    assert names[0] == names[1] == names[2]
    assert len(set(names[0]) - {None}) == 5
    assert np.abs(runs[0][0] - runs[1][0]).max() < 1e-9
    assert np.array_equal(runs[1][0], runs[2][0])
    with pytest.raises(hysid.InputError, match="only a 'mechanical' model has a gray-box form"):
        gray.to_gray_box()


def test_a_definition_no_expression_reads_is_warned_of(tmp_path):
    import pathlib

    base = pathlib.Path(__file__).resolve().parents[3] / "models" / "pick-and-place" / "structures" / "load-bounce.toml"
    changed = tmp_path / "changed.toml"
    changed.write_text(f'extends = "{base.as_posix()}"\n[definitions]\nkinetc = "1"\n')
    model = hysid.Model.load(changed)
    u = np.full(200, -0.1)
    with pytest.warns(UserWarning, match=r"no expression reads the definition\(s\) kinetc: a misspelt name\?"):
        model.simulate(u, ts=0.0025)
