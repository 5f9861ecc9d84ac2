"""Optional parameters: terms a user's model may lack (the contract's ``OPTIONAL``), held at
their start until the selection or the covariates bring them in; the Hamiltonian's parasitic
couplings are such terms."""

import pickle
import textwrap

import numpy as np
import pytest
from test_parametric import DECAY, _data

from workbench.param_boost import device_model
from workbench.param_regressor import HamiltonianParameterRegressor, ParametricRegressor
from workbench.parametric import ModelError, ParametricModel, load_model
from workbench.parametric_boost import ParametricBoostRegressor
from workbench.simulate import Mismatch, simulate

# the decay law and a term it may lack: a step at t = 1.5 (0 unless the data ask for it)
STEP = DECAY.replace('"offset": 0.0}', '"offset": 0.0, "step": 0.0}').replace(
    '+ params["offset"]', '+ params["offset"] + params["step"] * (t > 1.5)') + \
    '\nOPTIONAL = ["step"]\n'


def _write(tmp_path, text, name="model.py"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return str(path)


def test_an_optional_term_enters_where_cv_says_the_model_lacks_it(tmp_path):
    path = _write(tmp_path, STEP)
    X, y = _data(drift=0.0, missing=0.2)  # the step the decay law lacks
    est = ParametricBoostRegressor(model=path, features=["temp", "humidity"], huber_delta=0.05,
                                   alpha=0.01, max_steps=2, random_state=0).fit(X, y)
    assert est.choice_ == "drift"
    assert est.selection_.selected[0][0] == "step"  # with its intercept: the step's size
    table = est.estimator_.coefficient_table().set_index(["parameter", "covariate"])
    assert table.loc[("step", "intercept"), "coef"] == pytest.approx(0.2, abs=0.02)
    assert est.estimator_.parameter_names_ == ["amplitude", "tau", "offset", "step"]
    cv = est.choices_.set_index("candidate")["cv_mae"]
    assert cv["drift"] < 0.5 * cv["calibrated"]
    # the calibrated model is the user's model as declared: the optional term held at 0
    calibrated = est.calibrated_model().fit(X, y)
    assert calibrated.parameter_names_ == ["amplitude", "tau", "offset"]
    assert list(calibrated.calibration_["parameter"]) == ["amplitude", "tau", "offset"]


def test_a_held_term_leaves_the_fit_as_without_it(tmp_path):
    """Without covariates an optional parameter is not fitted: the same numbers as the model
    that does not have it."""
    X, y = _data(missing=0.0)
    cov = {"tau": ["temp"]}
    without = ParametricRegressor(model=_write(tmp_path, DECAY, "decay.py"),
                                  covariates=cov).fit(X, y)
    held = ParametricRegressor(model=_write(tmp_path, STEP, "step.py"), covariates=cov).fit(X, y)
    assert held.parameter_names_ == without.parameter_names_ == ["amplitude", "tau", "offset"]
    np.testing.assert_array_equal(held.coef_["coef"], without.coef_["coef"])
    np.testing.assert_array_equal(held.predict(X), without.predict(X))
    # an optional parameter named with covariates is fitted, "intercept" alone included
    both = ParametricRegressor(model=str(tmp_path / "step.py"),
                               covariates={**cov, "step": ["intercept"]}).fit(X, y)
    assert both.parameter_names_ == ["amplitude", "tau", "offset", "step"]
    assert both.covariate_names_["step"] == ["intercept"]
    # a fitted model pickles with its held parameters (a logged model needs no file)
    again = pickle.loads(pickle.dumps(held))
    np.testing.assert_array_equal(again.predict(X), held.predict(X))


def test_restricted_models(tmp_path):
    model = load_model(_write(tmp_path, STEP))
    assert model.optional == ("step",) and model.names == ["amplitude", "tau", "offset", "step"]
    small = model.restricted(["amplitude", "tau", "offset"])
    assert small is model.restricted(["offset", "tau", "amplitude"])  # one object per keep
    assert small.names == ["amplitude", "tau", "offset"] and small.held == ("step",)
    X, _ = _data(n=20)
    theta = small.start(X)
    assert theta.shape == (20, 3)
    full = np.column_stack([theta, np.zeros(20)])
    np.testing.assert_array_equal(small.predict(theta, X, 1), model.predict(full, X, 1))
    np.testing.assert_array_equal(small.jacobian(theta, X, 1),
                                  model.jacobian(full, X, 1)[:, :, :3])
    assert pickle.loads(pickle.dumps(small)).names == small.names
    assert model.restricted(model.names) is model
    with pytest.raises(ValueError, match=r"not optional: only the model's optional"):
        model.restricted(["amplitude", "tau"])
    with pytest.raises(ValueError, match="unknown parameter"):
        model.restricted(["amplitude", "tau", "offset", "nope"])
    # a file's own jacobian: every parameter's column, the held ones dropped
    exact = ParametricModel.from_functions(
        {"a": 1.0, "b": 0.0}, lambda p, d: p["a"] * d["t"] + p["b"],
        lambda p, d: np.stack([d["t"], np.ones(len(d))], axis=1), optional=["b"])
    assert exact.restricted(["a"]).jacobian(np.ones((20, 1)), X, 1).shape == (20, 1, 1)


BAD_OPTIONAL = {
    "unknown": ('["nope"]', "OPTIONAL names 'nope', not a parameter"),
    "column": ('["offset"]', "must start at a number"),
    "every": ('["amplitude", "tau", "offset"]', "every parameter is OPTIONAL"),
    "not a list": ('"offset"', "OPTIONAL must be a list"),
}


@pytest.mark.parametrize("case", sorted(BAD_OPTIONAL))
def test_a_bad_optional_gets_one_line(tmp_path, case):
    value, expected = BAD_OPTIONAL[case]
    text = DECAY.replace('"offset": 0.0}', '"offset": "t"}') if case == "column" else DECAY
    path = _write(tmp_path, text + f"\nOPTIONAL = {value}\n", f"bad_{case.replace(' ', '_')}.py")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert expected in str(info.value) and "\n" not in str(info.value)
    assert "bad_" in str(info.value)


ONSITE = [f"model_f{k}" for k in range(1, 5)]
COUPLINGS = [f"model_g{k}" for k in range(1, 4)]
TARGETS = [f"measured_E{k}" for k in range(1, 5)]


def test_parasitic_couplings_are_optional_parameters():
    """One engine: the Hamiltonian regressor's parasitic couplings (in the model only where
    given covariates) are the device model's optional parameters, fitted alike by the
    parametric regressor, geometric-mean covariates included."""
    device = simulate(4, 120, device_seed=5,
                      mismatch=Mismatch(drift=0.3, crosstalk=0.05, noise_sd=0.2)).data
    covariates = {"model_f1": ["model_f1", "v_q1"], "model_g2": ["model_g2^2"],
                  "model_f1~model_f3": ["sqrt|model_g1*model_g2|"]}  # model_f2~model_f4 held
    train, test = device.iloc[:90], device.iloc[90:]
    hamiltonian = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS,
                                                parasitic="next_nearest",
                                                covariates=covariates, alpha=0.5)
    hamiltonian.fit(train, train[TARGETS])
    model = device_model(ONSITE, COUPLINGS, parasitic="next_nearest")
    assert model.optional == ("model_f1~model_f3", "model_f2~model_f4")
    parametric = ParametricRegressor(model=model, covariates=covariates, calibrate=False,
                                     loss="squared_error", alpha=0.5)
    parametric.fit(train, train[TARGETS].to_numpy())
    assert parametric.parameter_names_ == hamiltonian.parameter_names_ == \
        ONSITE + COUPLINGS + ["model_f1~model_f3"]
    assert hamiltonian.n_iter_ == parametric.n_iter_ > 1
    np.testing.assert_allclose(hamiltonian.coef_["coef"], parametric.coef_["coef"],
                               rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(hamiltonian.predict(test), parametric.predict(test),
                               rtol=0, atol=1e-9)
    assert parametric._physics().graph.edges == hamiltonian.graph_.edges


def test_the_family_offers_a_model_files_optional_term(tmp_path):
    """``workbench init --model`` and ``evaluate`` on a model file with ``OPTIONAL``: the
    (linearised) selection brings the missing step in, the tables name it."""
    import json

    import pandas as pd

    from workbench.experiment.cli import main

    X, y = _data(n=90, drift=0.0, missing=0.2)
    X.assign(y=y).to_csv(tmp_path / "decay.csv", index=False)
    _write(tmp_path, STEP, "decay_step.py")
    config = tmp_path / "decay.toml"
    assert main(["init", str(tmp_path / "decay.csv"), "--model", str(tmp_path / "decay_step.py"),
                 "--target", "y", "--out", str(config)]) == 0
    out = tmp_path / "result.json"
    assert main(["evaluate", str(config), "--no-track", "--json", str(out), "--jobs", "1",
                 "--out", str(tmp_path / "tables"), "--no-intervals",
                 "--set", "model.parametric.max_steps=1",
                 "--set", "model.parametric.products=false",
                 "--set", 'model.parametric.selection="linearised"',
                 "--set", "model.parametric.boost_stage=false"]) == 0
    info = json.loads(out.read_text())["parametric"]
    assert info["choice"] == "drift" and info["selection"]["path"][1]["parameter"] == "step"
    calibration = pd.read_csv(tmp_path / "tables" / "calibration.csv")
    assert "step" in set(calibration["parameter"])


def test_linearised_scores_are_the_same_for_both_regressors():
    """The linearised selection's one-step scores of a parametric regressor (the whole
    model's Jacobian, optional parameters included) are the Hamiltonian regressor's (its
    eigenvectors): candidates of fitted, new parasitic and product covariates."""
    from workbench.param_linear import linear_scores

    device = simulate(4, 120, device_seed=5,
                      mismatch=Mismatch(drift=0.3, crosstalk=0.05, noise_sd=0.2)).data
    covariates = {"model_f1": ["model_f1", "v_q1"],
                  "model_f1~model_f3": ["sqrt|model_g1*model_g2|"]}
    fit, val = device.iloc[:90], device.iloc[90:]
    settings = dict(covariates=covariates, alpha=0.5, loss="huber", huber_delta=0.5)
    hamiltonian = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS,
                                                parasitic="next_nearest", **settings)
    hamiltonian.fit(fit, fit[TARGETS])
    parametric = ParametricRegressor(model=device_model(ONSITE, COUPLINGS,
                                                        parasitic="next_nearest"),
                                     calibrate=False, solver="irls", **settings)
    parametric.fit(fit, fit[TARGETS].to_numpy())
    candidates = [("model_f2", "v_q2"), ("model_f2", "v_q2^2"),
                  ("model_g1", "model_f1-model_f2"), ("model_f1", "v_q1*v_q2"),
                  ("model_f2~model_f4", "sqrt|model_g2*model_g3|"),
                  ("model_f2~model_f4", "v_q3"), ("model_f1~model_f3", "v_c1")]
    args = (fit, fit[TARGETS].to_numpy(), val, val[TARGETS].to_numpy(), candidates)
    ours = linear_scores(parametric, *args)
    np.testing.assert_allclose(ours, linear_scores(hamiltonian, *args), rtol=1e-9)
    assert len(set(np.round(ours, 6))) == len(candidates)  # the scores tell them apart


@pytest.mark.parametrize("missing, first", [(0.0, ("tau", "temp")), (0.2, "step")])
def test_the_linearised_selection_finds_what_the_refit_finds(tmp_path, missing, first):
    path = _write(tmp_path, STEP)
    X, y = _data(drift=0.0 if missing else 0.3, missing=missing)
    settings = dict(model=path, features=["temp", "humidity"], huber_delta=0.05, alpha=0.01,
                    max_steps=2, products=False, random_state=0)
    refit = ParametricBoostRegressor(**settings).fit(X, y)
    linear = ParametricBoostRegressor(method="linearised", **settings).fit(X, y)
    assert refit.choice_ == linear.choice_ == "drift"
    for est in (refit, linear):
        chosen = est.selection_.selected[0]
        assert (chosen == first) if isinstance(first, tuple) else (chosen[0] == first)
    assert linear.cv_mae_ == pytest.approx(refit.cv_mae_, rel=0.05)
    with pytest.raises(ValueError, match="method"):
        ParametricBoostRegressor(method="exact", **settings).fit(X, y)


def test_the_calibrated_guard_with_an_optional_term(tmp_path):
    """``out_of_bounds="calibrated"``: a warm start hands its calibration only to a fit of the
    same parameters (the selection bringing an optional term in used to break on it)."""
    path = _write(tmp_path, STEP)
    X, y = _data(drift=0.3, missing=0.2)
    est = ParametricBoostRegressor(model=path, features=["temp", "humidity"], huber_delta=0.05,
                                   alpha=0.01, max_steps=3, products=False,
                                   out_of_bounds="calibrated", random_state=0).fit(X, y)
    assert est.choice_ == "drift" and "step" in est.estimator_.parameter_names_
    assert est.estimator_.calibrated_offset_.shape == (4,)
    small = ParametricRegressor(model=path, covariates={"tau": ["temp"]},
                                out_of_bounds="calibrated").fit(X, y)
    grown = ParametricRegressor(model=path, covariates={"tau": ["temp"], "step": ["intercept"]},
                                out_of_bounds="calibrated").fit(X, y, coef_init=small.coef_dict())
    fresh = ParametricRegressor(model=path, covariates={"tau": ["temp"], "step": ["intercept"]},
                                out_of_bounds="calibrated").fit(X, y)
    np.testing.assert_allclose(grown.calibrated_offset_, fresh.calibrated_offset_)
    outside = X.assign(temp=X["temp"] * 5)
    assert np.all(np.isfinite(est.predict(outside)))


# two targets sharing an offset: the first needs it (and a slope drifting in temp), the
# second is exact at the start values, so a joint fit of the offset only hurts it
SHARED = """
PARAMETERS = {"a": 1.0, "c": 1.0, "s": 0.0}


def predict(params, data):
    x = data["x"].to_numpy()
    return np.stack([params["a"] * x + params["s"], params["c"] * x + params["s"]], axis=1)
"""


def test_fallback_keeps_the_start_values_per_target(tmp_path):
    """``FittedPriorBoost(fallback=<the model at its start values>)``: per target, the
    physics model only where its out-of-fold MAE beats the control prediction's."""
    import pandas as pd

    from workbench.fitted_prior import FittedPriorBoost

    path = _write(tmp_path, "import numpy as np\n" + SHARED)
    rng = np.random.default_rng(0)
    X = pd.DataFrame({"x": rng.uniform(1, 3, 150), "temp": rng.normal(0, 1, 150)})
    x = X["x"].to_numpy()
    Y = np.column_stack([(2.0 + 0.5 * X["temp"].to_numpy()) * x + 0.5,
                         x + rng.normal(0, 0.01, 150)])
    physics = ParametricBoostRegressor(model=path, features=["temp"], max_steps=2,
                                       products=False, squares=False, random_state=0)
    control = ParametricRegressor(model=path, max_iter=0, calibrate=False)
    model = FittedPriorBoost(physics, boost_stage=False, fallback=control, cv=5).fit(X, Y)
    assert model.physics_.choice_ == "drift"
    assert list(model.physics_selected_) == [True, False]
    start = control.fit(X, Y).predict(X)
    pred = np.asarray(model.predict(X), dtype=float)
    np.testing.assert_array_equal(pred[:, 1], start[:, 1])
    assert np.mean(np.abs(pred[:, 0] - Y[:, 0])) < 0.1 * np.mean(np.abs(start[:, 0] - Y[:, 0]))
    again = pickle.loads(pickle.dumps(model))
    np.testing.assert_array_equal(np.asarray(again.predict(X), dtype=float), pred)
