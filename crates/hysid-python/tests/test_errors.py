"""Bad input raises InputError (a ValueError), a method that ran and failed
raises MethodError (a RuntimeError), both HysidError, with the program's
one-line message; nothing panics across the boundary."""

import numpy as np
import pytest

import hysid
from conftest import HEAD_MODEL, PICK_AND_PLACE


def program_message(run, *args):
    """The program's one-line message for a command that must fail with exit code 2."""
    r = run(*args, check=False)
    assert r.returncode == 2, r.stderr
    line = r.stderr.strip()
    assert line.startswith("hysid: error: ") and "\n" not in line
    return line[len("hysid: error: "):]


def raised(f, *args, **kwargs):
    """The message of the InputError that f(*args, **kwargs) raises."""
    with pytest.raises(hysid.InputError) as e:
        f(*args, **kwargs)
    message = str(e.value)
    assert "\n" not in message and message
    return message


U = np.sin(np.arange(300) * 0.05)
Y = np.cos(np.arange(300) * 0.07)


def test_bad_input_is_a_value_error_and_a_failed_method_a_runtime_error():
    assert issubclass(hysid.InputError, hysid.HysidError) and issubclass(hysid.InputError, ValueError)
    assert issubclass(hysid.MethodError, hysid.HysidError) and issubclass(hysid.MethodError, RuntimeError)
    assert not issubclass(hysid.MethodError, ValueError)
    assert not issubclass(hysid.InputError, RuntimeError)
    assert hysid.InputError.__module__ == hysid.MethodError.__module__ == "hysid"
    # `except ValueError` still catches bad input.
    with pytest.raises(ValueError, match="modes=0"):
        hysid.identify(U, Y, method="cluster", modes=0)


@pytest.mark.parametrize(
    "u, y, words",
    [
        (np.where(np.arange(300) == 17, np.nan, U), Y, ["'u'", "non-finite", "sample 17"]),
        (U, np.where(np.arange(300) == 4, np.inf, Y), ["'y'", "non-finite", "sample 4"]),
        (U[:299], Y, ["299 samples", "300"]),
        (U, np.stack([Y, Y], axis=1), ["y:", "shape (300, 2)"]),
        (np.zeros((300, 1, 1)), Y, ["u:", "shape (300, 1, 1)"]),
        (["a", "b"], Y[:2], ["u:", "not an array of numbers"]),
    ],
)
def test_bad_arrays_are_named(u, y, words):
    message = raised(hysid.identify, u, y, method="arx")
    for w in words:
        assert w in message


def test_unknown_option_names_the_back_end_and_its_options():
    message = raised(hysid.identify, U, Y, method="arx", options={"nope": 1})
    assert message.startswith("option nope: method 'arx' has no such option (options: ")


@pytest.mark.parametrize(
    "given, words",
    [
        ({"na": "two"}, "na='two': must be a whole number"),
        ({"modes": 2.5}, "modes=2.5: must be a whole number"),
        ({"ts": "x"}, "ts='x': must be a number of seconds"),
        ({"options": [1, 2]}, "options=[1, 2]: must be a dictionary"),
        ({"priors": 5}, "priors=5: must be a dictionary or the path"),
    ],
)
def test_an_argument_of_the_wrong_type_is_named(given, words):
    message = raised(hysid.identify, U, Y, **{"method": "arx", **given})
    assert message.startswith(words), message


def test_the_ways_of_choosing_selection_rows_are_one_at_a_time():
    message = raised(hysid.identify, U, Y, method="arx", auto=True, folds=2, select_rows=(200, 300))
    assert message.startswith("folds=2: not with selection rows"), message


def test_selection_rows_where_the_output_rests_are_refused():
    resting = np.where(np.arange(300) < 200, Y, 0.5)
    message = raised(hysid.identify, U, resting, method="arx", auto=True, select_rows=(240, 300))
    assert message.endswith("the output is constant on rows 240..300 after the warm-up, so FIT cannot rank the candidates there"), message
    hysid.identify(U, resting, method="arx", auto=True, select_rows=(0, 60), options={"refine": "none"})


def test_standardize_is_named_as_the_argument():
    message = raised(hysid.identify, U, Y, method="arx", standardize=True, priors={"fixed": {"c": 0.0}})
    assert message.startswith("standardize=True cannot be combined with [fixed] c of priors, a prior in data units"), message


def test_a_record_without_samples_is_refused():
    assert raised(hysid.Record, np.zeros((0, 1)), np.zeros(0)).startswith("u, y: a record needs")


def test_a_negative_warmup_of_validate_is_named():
    model = hysid.identify(U, Y, method="arx")
    assert raised(model.validate, U, Y, warmup=-1).startswith("warmup=-1: must be a whole number")


def test_a_grid_is_checked_before_any_candidate_is_fitted():
    message = raised(hysid.identify, U, Y, method="arx", auto=True, grid={"cc": [1, 2]})
    assert message.startswith("grid cc: method 'arx' has no such option (options: "), message
    message = raised(hysid.identify, U, Y, method="arx", auto=True, grid={"ridge": [1, "x"]})
    assert message.startswith("grid ridge=x"), message
    # An axis an option or the mode count also fixes: the grid would override it.
    message = raised(hysid.identify, U, Y, method="arx", auto=True, grid={"ridge": [0, 1]}, options={"ridge": 2})
    assert message == "grid ridge: also fixed by options={'ridge': 2}; give it in one place", message
    message = raised(hysid.identify, U, Y, method="cluster", auto=True, grid={"modes": [2, 3]}, modes=2)
    assert message == "grid modes: also fixed by modes=2; give it in one place", message


def test_a_grid_takes_the_values_options_take():
    # True and None as options= takes them (true, none); a comma cannot
    # hide a second value.
    grid = {"scale": [True, False], "c": [None, 40], "modes": 2}
    model = hysid.identify(U, Y, method="cluster", auto=True, seed=1, grid=grid)
    tried = [dict(c["values"]) for c in model.info["selection"]["candidates"]]
    assert {"c": "none", "modes": "2", "scale": "true"} in tried, tried
    message = raised(hysid.identify, U, Y, method="cluster", auto=True, grid={"init": ["a,b"]})
    assert message == "grid init='a,b': a value cannot hold a comma", message
    model = hysid.identify(U, Y, method="cluster", modes=2, seed=1, options={"c": None})
    assert model.info["options"]["c"] is None


def test_option_value_is_checked_as_set_checks_it():
    message = raised(hysid.identify, U, Y, method="cluster", modes=2, options={"c": -3})
    assert message.startswith("option c=")


def test_unknown_method_has_the_program_message(program, tmp_path):
    ours = raised(hysid.identify, U, Y, method="nope")
    theirs = program_message(program, "identify", PICK_AND_PLACE, "-m", "nope", "-o", tmp_path / "m.json")
    assert ours == theirs
    assert not (tmp_path / "m.json").exists()


def test_a_prior_the_back_end_cannot_honour_has_the_program_message(program, tmp_path):
    prior = tmp_path / "fixed.toml"
    prior.write_text('[[saturation]]\nlevel = 25.0\nbound = "max"\n')
    ours = raised(hysid.identify, U, Y, method="physical", priors=prior, options={"model": str(HEAD_MODEL)})
    theirs = program_message(program, "identify", PICK_AND_PLACE, "-m", "physical", "--set", f"model={HEAD_MODEL}",
                             "--prior", prior, "-o", tmp_path / "m.json")
    assert ours == theirs and "does not honour the prior" in ours


def test_physical_without_a_model_file_names_the_option(program, tmp_path):
    ours = raised(hysid.identify, U, Y, method="physical", ts=0.0025)
    theirs = program_message(program, "identify", PICK_AND_PLACE, "-m", "physical", "-o", tmp_path / "m.json")
    assert "option model=FILE" in ours and "--set model=FILE" in theirs and "docs/gray-box-models.md" in ours
    assert not (tmp_path / "m.json").exists()


def test_a_missing_column_has_the_program_message(program, tmp_path):
    csv = tmp_path / "r.csv"
    csv.write_text("t,u,y\n0,1,2\n1,2,3\n2,3,4\n")
    ours = raised(hysid.load, csv, inputs=["v"])
    theirs = program_message(program, "identify", csv, "-m", "arx", "--input", "v", "-o", tmp_path / "m.json")
    assert ours == theirs and "no column 'v'" in ours


def test_a_malformed_model_file_has_the_program_message(program, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"kind": "pwarx", "na": 1}')
    ours = raised(hysid.Model.load, bad)
    theirs = program_message(program, "validate", bad, PICK_AND_PLACE)
    assert ours == theirs


def test_bad_arguments_are_refused():
    assert "modes=0" in raised(hysid.identify, U, Y, method="cluster", modes=0)
    assert "time_budget" in raised(hysid.identify, U, Y, method="arx", time_budget=-1.0)
    assert "decimate" in raised(hysid.load, PICK_AND_PLACE, decimate=0)
    assert "rows" in raised(hysid.load, PICK_AND_PLACE, rows="7")
    assert "named twice" in raised(hysid.load, PICK_AND_PLACE, inputs=["u", "u"])
    assert "need auto=True" in raised(hysid.identify, U, Y, method="arx", folds=3)
    assert "need auto=True" in raised(hysid.identify, U, Y, method="arx", refit_starts=2)
    assert "refit_starts=0" in raised(hysid.identify, U, Y, method="arx", auto=True, refit_starts=0)
    assert "warmup" in raised(hysid.Model.from_json(
        '{"kind": "pwarx", "na": 1, "nb": 1, "inputs": 1, "modes": [{"theta": [0.5, 1, 0], "region": {}}]}'
    ).validate, U[:5], Y[:5], warmup=5)


def test_a_cluster_run_without_a_mode_count_says_how_to_give_one():
    message = raised(hysid.identify, U, Y, method="cluster")
    assert "modes=S" in message and "max_modes=S" in message


def test_priors_that_contradict_each_other_are_refused():
    message = raised(hysid.identify, U, Y, method="cluster", priors={"modes": 3, "max_modes": 2})
    assert message.startswith("priors: ")


def test_a_mode_bound_past_any_candidate_fit_is_refused():
    # Every count up to the bound is a candidate fit: 10**11 asked for a
    # list of them all and aborted the interpreter.
    for bound in ({"max_modes": 10**11}, {"priors": {"max_modes": 10**11}}):
        message = raised(hysid.identify, U, Y, method="cluster", **bound)
        assert "max_modes = 100000000000: at most 1000" in message


def test_one_grid_value_and_one_input_name_are_not_split_into_characters():
    # na = "12" is one value, not na = 1 and na = 2.
    model = hysid.identify(U, Y, method="arx", auto=True, grid={"na": "12", "nb": 1})
    tried = [dict(c["values"]) for c in model.info["selection"]["candidates"]]
    assert {"na": "12", "nb": "1"} in tried and {"na": "1", "nb": "1"} not in tried
    assert hysid.identify(U, Y, method="arx", input_names="force").input_names == ["force"]


def test_input_lags_without_an_input_are_refused():
    # The model would have been one the package cannot load back.
    message = raised(hysid.identify, np.zeros((300, 0)), Y, method="arx")
    assert "nb = 2 input lags, but the record has no input" in message


def test_klinreg_without_a_mode_count_says_how_to_give_one():
    message = raised(hysid.identify, U, Y, method="klinreg")
    assert "modes=S" in message and "max_modes=S" in message and "auto=True" in message


def test_python_side_checks_raise_input_errors_too():
    assert "step" in raised(hysid.load, PICK_AND_PLACE, rows=slice(0, 10, 2))
    assert "not fitted" in raised(hysid.Estimator().score, hysid.Record(U, Y))


# Four modes of at least 100 points each from 300 samples: the clustering
# runs and leaves no cluster that large.
FAILING_OPTIONS = {"c": 100}


def test_a_method_that_fails_raises_a_method_error_with_the_program_message(program, tmp_path):
    csv = tmp_path / "r.csv"
    np.savetxt(csv, np.column_stack([U, Y]), delimiter=",", header="u,y", comments="")
    with pytest.raises(hysid.MethodError) as e:
        hysid.identify(U, Y, method="cluster", modes=4, options=FAILING_OPTIONS)
    ours = str(e.value)
    assert not isinstance(e.value, ValueError) and "\n" not in ours
    r = program("identify", csv, "-m", "cluster", "--modes", "4",
                *[f"--set={k}={v}" for k, v in FAILING_OPTIONS.items()], "-o", tmp_path / "m.json", check=False)
    # The program's exit code 1: a failure of the computation, not of the input.
    assert r.returncode == 1, r.stderr
    assert r.stderr.strip() == f"hysid: error: {ours}"


@pytest.mark.parametrize("rows", [(0.5, 100), (0, 100.7), ("0", 100), (True, 100)])
def test_row_bounds_that_are_not_whole_numbers_are_named(rows):
    message = raised(hysid.identify, U, Y, method="arx", auto=True, select_rows=rows)
    assert message.startswith("select_rows: row bounds must be whole numbers"), message


def test_complex_and_masked_samples_are_refused_not_cast():
    message = raised(hysid.identify, U + 1j, Y, method="arx")
    assert message.startswith("u: complex numbers"), message
    masked = np.ma.masked_array(Y, mask=np.arange(300) == 7)
    message = raised(hysid.identify, U, masked, method="arx")
    assert message.startswith("y: masked samples"), message
    # A masked array without a masked sample is its values.
    whole = np.ma.masked_array(Y, mask=np.zeros(300, bool))
    assert hysid.identify(U, whole, method="arx").to_json() == hysid.identify(U, Y, method="arx").to_json()


def test_plot_regressors_checks_the_record_against_the_model():
    import hysid.plot

    model = hysid.identify(U, Y, method="arx")
    assert hysid.plot.regressors(model, U, Y).shape == (298, 4)
    assert raised(hysid.plot.regressors, model, np.stack([U, U], axis=1), Y).startswith("u: expected shape (N, 1)")
    assert raised(hysid.plot.regressors, model, U, Y[:200]).startswith("y: 200 samples, u has 300")
    assert raised(hysid.plot.regressors, model, U, np.stack([Y, Y], axis=1)).startswith("y: expected shape (N,)")


@pytest.mark.parametrize("given", [{"seed": 2**70}, {"na": 2**64}, {"warmup": 2**64}, {"modes": -1}])
def test_counts_past_the_program_s_range_are_named(given):
    (name, value), = given.items()
    message = raised(hysid.identify, U, Y, **{"method": "arx", **given})
    assert message.startswith(f"{name}={value}: must be a whole number >= 0"), message


def test_the_model_s_methods_name_their_arguments():
    model = hysid.identify(U, Y, method="arx")
    for warmup in (2**70, -1, 2.5, True, "10"):
        assert raised(model.validate, U, Y, warmup=warmup).startswith(f"warmup={warmup!r}: must be a whole number")
    assert model.validate(U, Y, warmup=np.int64(10)) == model.validate(U, Y)
    for call in (lambda ts: model.simulate(U, ts=ts), lambda ts: model.predict(U, Y, ts=ts),
                 lambda ts: model.validate(U, Y, ts=ts)):
        assert raised(call, "x").startswith("ts='x': must be a number of seconds")
    assert raised(model.simulate, U, ts=-1.0).startswith("sampling time must be")


def test_validate_and_simulate_warn_of_another_sampling_time():
    model = hysid.identify(U, Y, method="arx", ts=0.01)
    with pytest.warns(UserWarning, match="sampling time 0.001 s differs from the 0.01 s"):
        model.validate(U, Y, ts=0.001)
    with pytest.warns(UserWarning, match="sampling time 0.001 s differs from the 0.01 s"):
        model.simulate(U, ts=0.001)


def test_simulate_counts_the_samples_outside_every_region():
    holed = hysid.Model.from_json("""{
      "kind": "pwarx", "na": 1, "nb": 1, "inputs": 1,
      "modes": [
        {"theta": [0.5, 1.0, 0.0], "region": {"a": [[1.0, 0.0]], "b": [0.0]}},
        {"theta": [0.5, 1.0, 0.0], "region": {"a": [[-1.0, 0.0]], "b": [-1.0]}}
      ]
    }""")
    u = np.sin(np.arange(200) / 5.0)
    with pytest.warns(UserWarning, match=r"\d+ of 199 simulated samples lie outside every region"):
        holed.simulate(u)


@pytest.mark.parametrize(
    "given, words",
    [
        ({"seed": None}, "seed=None: must be a whole number"),
        ({"na": None}, "na=None: must be a whole number"),
        ({"warmup": None}, "warmup=None: must be a whole number"),
        ({"method": None}, "method=None: must be a method name"),
        ({"auto": 1}, "auto=1: must be True or False"),
        ({"standardize": "yes"}, "standardize='yes': must be True or False"),
        ({"output_name": 5}, "output_name=5: must be a name"),
        ({"input_names": ["a", "a"]}, "input_names: input 'a' is named twice"),
        ({"input_names": ["y"]}, "input_names: input 'y' is also the output"),
    ],
)
def test_arguments_that_may_not_be_left_out_or_are_switches_are_named(given, words):
    message = raised(hysid.identify, np.c_[U, U + 1] if given.get("input_names") == ["a", "a"] else U, Y,
                     **{"method": "arx", **given})
    assert message.startswith(words), message


def test_load_record_and_compare_name_their_arguments(tmp_path):
    assert raised(hysid.load, PICK_AND_PLACE, ts="0.02").startswith("ts='0.02': must be a number of seconds")
    assert raised(hysid.load, PICK_AND_PLACE, output=["y"]).startswith("output=['y']: must be a name")
    assert raised(hysid.Record, U, Y, ts="0.01").startswith("ts='0.01': must be a number of seconds")
    assert raised(hysid.Record, U, Y, ts=True).startswith("ts=True: must be a number of seconds")
    report = tmp_path / "a-file"
    report.write_text("kept")
    message = raised(hysid.compare, tmp_path / "never-read.toml", report)
    assert "is a file; the report goes into a folder" in message and report.read_text() == "kept"


def test_a_dataframe_s_labels_are_used_as_given():
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({0: U, 1: Y})
    record = hysid.Record.from_dataframe(frame, inputs=[0], output=1)
    assert record.input_names == ["0"] and record.output_name == "1" and np.array_equal(record.y, Y)
    assert raised(hysid.Record.from_dataframe, frame, inputs=["0"], output=1).startswith(
        "inputs: no column '0' in the DataFrame (columns: 0, 1)")


def test_more_arguments_are_named():
    model = hysid.identify(U, Y, method="arx")
    assert raised(model.simulate, U, y0=[np.nan, 1.0]).startswith("y0: a non-finite value at sample 0")
    assert raised(hysid.identify, U, Y, method="arx", ts=-1).startswith("ts=-1: must be a positive number")
    assert raised(hysid.Record, U, Y, ts=0).startswith("ts=0: must be a positive number")
    assert raised(hysid.identify, U, Y, method="arx", auto=True, grid={"ridge": []}).startswith(
        "grid ridge: no values")
    est = hysid.Estimator(method="physical", options={"model": HEAD_MODEL})
    assert raised(est.fit, U, Y, ts=0.0025).startswith(
        "max_modes=3 (the Estimator's default): method 'physical' takes no mode count; give max_modes=None")


def test_plot_regions_names_its_arguments():
    pytest.importorskip("matplotlib")
    import hysid.plot

    model = hysid.identify(U, Y, method="cluster", na=1, nb=1, modes=2)
    assert raised(hysid.plot.regions, model, dims=(0,)).startswith("dims=(0,): two coordinates")
    assert raised(hysid.plot.regions, model, resolution=0).startswith("resolution=0: must be a whole number >= 2")
    assert raised(hysid.plot.regions, model, data=(U[:1], Y[:1])).startswith("data: no regressor")


def test_records_given_as_pandas_series_are_records():
    pd = pytest.importorskip("pandas")
    us, ys = [U[:150], U[150:]], [Y[:150], Y[150:]]
    from_arrays = hysid.identify(us, ys, method="arx")
    from_series = hysid.identify([pd.Series(u) for u in us], [pd.Series(y) for y in ys], method="arx")
    assert from_series.to_json() == from_arrays.to_json()


def test_a_record_too_short_to_score_is_named():
    # No free-run score could read past its warm-up: refused before any fit.
    with pytest.raises(hysid.InputError, match=r"^record 2 has 8 sample\(s\), no more than the warm-up of 10 .*\(warmup=\)$"):
        hysid.identify([U[:150], U[150:158]], [Y[:150], Y[150:158]], method="arx")
    with pytest.raises(hysid.InputError, match="record 2 has 8 sample"):
        hysid.identify([U[:150], U[150:158]], [Y[:150], Y[150:158]], method="arx", warmup=8)
    hysid.identify([U[:150], U[150:158]], [Y[:150], Y[150:158]], method="arx", warmup=7)
