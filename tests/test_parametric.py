"""The parametric family's core: a user's model file, its checks, calibration, drift, choice."""

import textwrap

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone

from workbench.param_regressor import ParametricRegressor
from workbench.parametric import ModelError, ParametricModel, load_model
from workbench.parametric_boost import ParametricBoostRegressor

# A textbook law: exponential decay towards an offset, y = A exp(-t / tau) + B.
DECAY = """
import numpy as np

PARAMETERS = {"amplitude": 2.0, "tau": 1.0, "offset": 0.0}


def predict(params, data):
    t = data["t"].to_numpy()
    return params["amplitude"] * np.exp(-t / params["tau"]) + params["offset"]
"""

JACOBIAN = """

def jacobian(params, data):
    t = data["t"].to_numpy()
    e = np.exp(-t / params["tau"])
    return np.stack([e, params["amplitude"] * e * t / params["tau"] ** 2,
                     np.ones_like(t)], axis=1)[:, None, :]
"""


def _write(tmp_path, text, name="model.py"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return str(path)


def _data(n=160, seed=0, drift=0.3, missing=0.0):
    """Decay with tau drifting linearly in temp (``drift``) and, optionally, a term no
    parameter drift of the law can make: a step in t (``missing``)."""
    rng = np.random.default_rng(seed)
    X = pd.DataFrame({"t": rng.uniform(0, 3, n), "temp": rng.normal(0, 1, n),
                      "humidity": rng.normal(0, 1, n)})
    tau = 1.5 + drift * X["temp"].to_numpy()
    y = (2.5 * np.exp(-X["t"].to_numpy() / tau) + 0.1 + missing * (X["t"].to_numpy() > 1.5)
         + rng.normal(0, 0.01, n))
    return X, y


def test_recovers_a_known_drift(tmp_path):
    path = _write(tmp_path, DECAY)
    X, y = _data()
    est = ParametricBoostRegressor(model=path, features=["temp", "humidity"], huber_delta=0.05,
                                   alpha=0.01, max_steps=2, random_state=0).fit(X, y)
    assert est.choice_ == "drift" and est.note_ == ""
    assert est.selection_.selected[0] == ("tau", "temp")
    table = est.estimator_.coefficient_table().set_index(["parameter", "covariate"])
    slope = table.loc[("tau", "temp"), "coef"] / table.loc[("tau", "temp"), "covariate_sd"]
    assert slope == pytest.approx(0.3, rel=0.1)
    start_tau = 1.0
    assert start_tau + table.loc[("tau", "intercept"), "coef"] == pytest.approx(1.5, rel=0.05)
    cv = est.choices_.set_index("candidate")["cv_mae"]
    assert cv["drift"] < cv["calibrated"] < cv["prior"]


def test_falls_back_where_the_error_is_not_a_drift(tmp_path):
    path = _write(tmp_path, DECAY)
    X, y = _data(drift=0.0, missing=0.2)  # a step no drift in temp or humidity makes
    est = ParametricBoostRegressor(model=path, features=["temp", "humidity"], huber_delta=0.05,
                                   random_state=0).fit(X, y)
    cv = est.choices_.set_index("candidate")["cv_mae"]
    chosen = float(cv[est.choice_])
    assert est.choice_ != "drift"
    assert "not a drift of the parameters" in est.note_
    # never worse than the prior or the no-drift path on CV
    assert chosen <= cv["prior"] and chosen <= cv["calibrated"]


def test_finite_differences_match_the_analytic_jacobian(tmp_path):
    fd = load_model(_write(tmp_path, DECAY, "fd.py"))
    exact = load_model(_write(tmp_path, DECAY + JACOBIAN, "exact.py"))
    X, _ = _data(n=50)
    theta = np.column_stack([np.full(50, 2.3), 1.2 + 0.1 * X["temp"], np.full(50, 0.2)])
    J_fd = fd.jacobian(theta, X, 1)
    J = exact.jacobian(theta, X, 1)
    assert J.shape == J_fd.shape == (50, 1, 3)
    np.testing.assert_allclose(J_fd, J, rtol=1e-6, atol=1e-9)
    # and the fits agree
    X, y = _data()
    cov = {"tau": ["temp"]}
    a = ParametricRegressor(model=str(tmp_path / "fd.py"), covariates=cov).fit(X, y)
    b = ParametricRegressor(model=str(tmp_path / "exact.py"), covariates=cov).fit(X, y)
    np.testing.assert_allclose(a.predict(X), b.predict(X), atol=1e-5)


BAD = {
    "does not import": ("import numpy as np\nPARAMETERS = {'a': 1.0\n", "does not import"),
    "no PARAMETERS": ("def predict(params, data):\n    return data['t']\n",
                      "defines no PARAMETERS"),
    "no predict": ("PARAMETERS = {'a': 1.0}\n", "defines no predict"),
    "raises": ("PARAMETERS = {'a': 1.0}\ndef predict(params, data):\n    return 1 / 0\n",
               "predict raised ZeroDivisionError"),
    "NaN": ("import numpy as np\nPARAMETERS = {'a': 1.0}\n"
            "def predict(params, data):\n    return np.sqrt(params['a'] - data['t'].to_numpy())\n",
            "NaN or infinite"),
    "wrong shape": ("import numpy as np\nPARAMETERS = {'a': 1.0}\n"
                    "def predict(params, data):\n    return params['a'][:3]\n",
                    "predict returned shape (3,)"),
    "dead parameter": ("PARAMETERS = {'a': 1.0, 'b': 2.0}\n"
                       "def predict(params, data):\n    return params['a'] * data['t']\n",
                       "does not depend on parameter 'b'"),
    "jacobian shape": ("import numpy as np\nPARAMETERS = {'a': 1.0}\n"
                       "def predict(params, data):\n    return params['a'] * data['t']\n"
                       "def jacobian(params, data):\n    return np.ones((len(data), 2))\n",
                       "jacobian returned shape"),
    "missing column": ("PARAMETERS = {'a': 'voltage'}\n"
                       "def predict(params, data):\n    return params['a'] * data['t']\n",
                       "from column 'voltage', which the data lack"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_model_gets_one_line(tmp_path, case):
    text, expected = BAD[case]
    path = _write(tmp_path, text, f"bad_{case.replace(' ', '_')}.py")
    X, y = _data(n=30)
    with pytest.raises(ModelError) as info:
        ParametricRegressor(model=path).fit(X, y)
    message = str(info.value)
    assert expected in message
    assert "\n" not in message
    assert "bad_" in message  # names the file


def test_a_missing_file_gets_one_line(tmp_path):
    with pytest.raises(ModelError, match="not found"):
        load_model(tmp_path / "nowhere.py")


def test_model_from_functions_and_targets():
    def predict(params, data):
        t = data["t"].to_numpy()
        return np.column_stack([params["a"] * t, params["a"] + params["b"] * t])

    model = ParametricModel.from_functions({"a": 1.0, "b": 0.5}, predict)
    X = pd.DataFrame({"t": np.linspace(0, 1, 40)})
    Y = np.column_stack([1.5 * X["t"], 1.5 + 0.2 * X["t"]])
    est = ParametricRegressor(model=model, loss="squared_error").fit(X, Y)
    assert est.predict(X).shape == (40, 2)
    np.testing.assert_allclose(est.predict(X), Y, atol=1e-6)
    with pytest.raises(ModelError, match=r"expected \(40, 3\)"):
        ParametricRegressor(model=model).fit(X, np.column_stack([Y, Y[:, 0]]))


def test_same_seed_same_numbers_and_clone(tmp_path):
    path = _write(tmp_path, DECAY)
    X, y = _data(n=80)
    est = ParametricBoostRegressor(model=path, candidates={"tau": ["temp", "humidity"]},
                                   huber_delta=0.05, max_steps=1, random_state=3)
    a, b = clone(est).fit(X, y), clone(est).fit(X, y)
    np.testing.assert_array_equal(a.predict(X), b.predict(X))
    pd.testing.assert_frame_equal(a.choices_, b.choices_)
    c = clone(est).set_params(random_state=4).fit(X, y)
    assert not np.array_equal(a.choices_["cv_mae"], c.choices_["cv_mae"])  # other folds
    assert clone(est).get_params() == est.get_params()
    with pytest.raises(ValueError, match="loss"):
        clone(est).set_params(loss="nope").fit(X, y)


def test_clip_evaluates_the_drift_at_the_nearest_training_point(tmp_path):
    """out_of_bounds="clip": far outside the training covariates the corrections are the
    drift's at the covariates clipped to their training range, so every parameter's
    correction stays within its training range; "extrapolate" follows the drift."""
    path = _write(tmp_path, DECAY)
    X, y = _data()
    low, high = X["temp"].min(), X["temp"].max()
    far = X.iloc[:3].assign(temp=[20.0, -20.0, 0.0])
    fits = {how: ParametricRegressor(model=path, covariates={"tau": ["temp", "temp^2"]},
                                     huber_delta=0.05, alpha=0.01, out_of_bounds=how).fit(X, y)
            for how in ("extrapolate", "clip")}
    clip, free = fits["clip"], fits["extrapolate"]
    np.testing.assert_allclose(clip.predict(X), free.predict(X))  # training rows: unchanged
    assert clip.column_range_ == {"temp": (low, high)}
    edge = far.assign(temp=[high, low, 0.0])
    np.testing.assert_allclose(clip.corrected_parameters(far),
                               free.corrected_parameters(edge))
    train_tau = free.corrected_parameters(X)["tau"]
    tau = clip.corrected_parameters(far)["tau"]
    assert tau.between(train_tau.min() - 1e-9, train_tau.max() + 1e-9).all()
    assert abs(free.corrected_parameters(far)["tau"].iloc[0]) > train_tau.max() + 1.0
    assert ParametricRegressor().out_of_bounds == "extrapolate"


def _unit_box(n=120, seed=1):
    """Decay with tau drifting in temp, temp uniform on [0, 1] (the training box)."""
    rng = np.random.default_rng(seed)
    X = pd.DataFrame({"t": rng.uniform(0, 3, n), "temp": rng.uniform(0, 1, n)})
    tau = 1.2 + 0.6 * X["temp"].to_numpy() ** 2
    y = 2.5 * np.exp(-X["t"].to_numpy() / tau) + 0.1 + rng.normal(0, 0.01, n)
    return X, y


def test_calibrated_guard_keeps_the_calibrated_model_beyond_the_box(tmp_path):
    """out_of_bounds="calibrated": a drift fitted on temp in [0, 1] and evaluated at temp = 3
    gives the calibrated model's prediction there, and the drift's inside the box."""
    path = _write(tmp_path, DECAY)
    X, y = _unit_box()
    kw = dict(model=path, covariates={"tau": ["temp", "temp^2"]}, huber_delta=0.05,
              alpha=0.01)
    guard = ParametricRegressor(**kw, out_of_bounds="calibrated").fit(X, y)
    free = ParametricRegressor(**kw).fit(X, y)
    calibrated = ParametricRegressor(model=path, huber_delta=0.05, max_iter=0).fit(X, y)
    far = X.iloc[:4].assign(temp=[3.0, -2.0, 0.5, 1.0 + 1e-9])
    np.testing.assert_array_equal(guard.outside(far), [True, True, False, True])
    np.testing.assert_allclose(guard.predict(far.iloc[[0, 1, 3]]),
                               calibrated.predict(far.iloc[[0, 1, 3]]), rtol=1e-10)
    np.testing.assert_allclose(guard.predict(far.iloc[[2]]), free.predict(far.iloc[[2]]))
    np.testing.assert_allclose(guard.predict(X), free.predict(X))  # training rows: unchanged
    # the drift alone runs off there; the guard does not
    assert abs(free.predict(far.iloc[[0]]) - calibrated.predict(far.iloc[[0]]))[0] > 0.05
    pd.testing.assert_frame_equal(guard.calibrated_parameters(far).iloc[[0]],
                                  calibrated.corrected_parameters(far).iloc[[0]])
    assert not guard.coef_jacobian(far)[[0, 1, 3]].any()


def test_calibrated_guard_reuses_a_warm_start_only_on_the_same_rows(tmp_path):
    path = _write(tmp_path, DECAY)
    X, y = _unit_box()
    est = ParametricRegressor(model=path, covariates={"tau": ["temp"]}, huber_delta=0.05,
                              out_of_bounds="calibrated")
    cold = clone(est).fit(X, y)
    warm = clone(est).fit(X, y, coef_init=cold.coef_dict())
    np.testing.assert_array_equal(warm.calibrated_offset_, cold.calibrated_offset_)
    half = clone(est).fit(X.iloc[:60], y[:60], coef_init=cold.coef_dict())
    np.testing.assert_allclose(half.calibrated_offset_,
                               clone(est).fit(X.iloc[:60], y[:60]).calibrated_offset_)
    assert not np.allclose(half.calibrated_offset_, cold.calibrated_offset_)
    nocal = clone(est).set_params(calibrate=False).fit(X, y)  # still the calibration's
    np.testing.assert_allclose(nocal.calibrated_offset_, cold.calibrated_offset_)


def test_out_of_bounds_is_validated_and_cloned(tmp_path):
    path = _write(tmp_path, DECAY)
    X, y = _unit_box(n=60)
    for cls in (ParametricRegressor, ParametricBoostRegressor):
        est = cls(model=path, out_of_bounds="calibrated")
        assert clone(est).get_params()["out_of_bounds"] == "calibrated"
        with pytest.raises(ValueError, match="out_of_bounds.*'calibrated'"):
            clone(est).set_params(out_of_bounds="hold").fit(X, y)


# A law with a domain: y = sqrt(k) x + B is NaN for k < 0.
ROOT = """
import numpy as np

PARAMETERS = {"k": 1.0, "B": 0.0}


def predict(params, data):
    return np.sqrt(params["k"]) * data["x"].to_numpy() + params["B"]
"""


def test_rows_the_drift_takes_outside_the_domain_get_the_calibrated_model(tmp_path):
    """A drift of k in temp, fitted on temp in [0, 1], takes k below zero at temp = -3: that
    row gets the calibrated model's prediction (not NaN, not an error); the others the
    drift's. A row not finite even at the start values is one line."""
    path = _write(tmp_path, ROOT)
    rng = np.random.default_rng(0)
    X = pd.DataFrame({"x": rng.uniform(1, 2, 120), "temp": rng.uniform(0, 1, 120)})
    y = np.sqrt(0.8 + 6.0 * X["temp"].to_numpy()) * X["x"].to_numpy() + 0.1
    drift = ParametricRegressor(model=path, covariates={"k": ["temp"]}, alpha=0.0,
                                huber_delta=0.05).fit(X, y)
    calibrated = ParametricRegressor(model=path, huber_delta=0.05, max_iter=0).fit(X, y)
    new = X.iloc[:3].assign(temp=[-3.0, 0.5, 0.9])
    assert drift.corrected_parameters(new)["k"].iloc[0] < 0  # the drift leaves the domain
    np.testing.assert_array_equal(drift.outside_domain(new), [True, False, False])
    pred = drift.predict(new)
    assert np.isfinite(pred).all()
    np.testing.assert_allclose(pred[0], calibrated.predict(new.iloc[[0]])[0], rtol=1e-10)
    np.testing.assert_allclose(pred[1:], drift.predict(new.iloc[1:]))
    assert not drift.outside_domain(X).any()
    with pytest.raises(ModelError, match=r"NaN or infinite values on 1 of 2 rows even at its "
                                         r"start values \(first rows: \[0\]\)"):
        drift.predict(new.iloc[:2].assign(x=[np.nan, 1.0]))


def test_a_covariate_column_with_missing_values_is_one_line(tmp_path):
    """A covariate's column with a missing or non-numeric value: one line naming the
    parameter and the column, in fit and in predict."""
    path = _write(tmp_path, ROOT)
    rng = np.random.default_rng(0)
    X = pd.DataFrame({"x": rng.uniform(1, 2, 40), "temp": rng.uniform(0, 1, 40)})
    y = np.sqrt(0.8 + 6.0 * X["temp"].to_numpy()) * X["x"].to_numpy()
    est = ParametricRegressor(model=path, covariates={"k": ["temp*x"]})
    match = r"covariates of parameter 'k' have missing or non-numeric values \(column\(s\) " \
            r"\['temp'\]\)"
    with pytest.raises(ValueError, match=match):
        est.fit(X.assign(temp=X["temp"].where(X.index != 3)), y)
    est.fit(X, y)
    with pytest.raises(ValueError, match=match):
        est.predict(X.assign(temp=["warm"] + list(X["temp"].iloc[1:])))


def test_targets_in_small_units_can_leave_the_prior(tmp_path):
    """min_improvement is in the targets' unit, at most 1% of the prior's training MAE: a
    rate in units of 1e-9 used to keep the prior (no gain can exceed 1e-3 there)."""
    path = _write(tmp_path, "PARAMETERS = {'k': 1.0e-9, 'm': 3.0e-10}\n\n\n"
                            "def predict(params, data):\n"
                            "    return params['k'] * data['x'].to_numpy() + params['m']\n")
    rng = np.random.default_rng(3)
    X = pd.DataFrame({"x": rng.uniform(0.5, 2, 60), "z": rng.normal(size=60)})
    y = 1.2e-9 * X["x"].to_numpy() * (1 + 0.1 * X["z"].to_numpy()) + 3e-10
    est = ParametricBoostRegressor(model=path, features=["z"], max_steps=1, squares=False,
                                   products=False, loss="squared_error", alpha=0.0,
                                   random_state=0).fit(X, y)
    prior_mae = est.choices_.set_index("candidate").loc["prior", "cv_mae"]
    assert est.min_improvement_ == pytest.approx(0.01 * prior_mae)
    assert est.choice_ == "drift"
    assert np.mean(np.abs(est.predict(X) - y)) < 0.05 * prior_mae
    big = clone(est).set_params(model=path).fit(X, y * 1e12)  # the same data in units of 1e-12
    assert big.min_improvement_ == 1e-3 and big.choice_ == "drift"
def test_ridge_drift_fits_the_whole_library_with_a_cv_penalty(tmp_path):
    path = _write(tmp_path, DECAY)
    X, y = _data()
    kw = dict(model=path, features=["temp", "humidity"], huber_delta=0.05, random_state=0,
              max_steps=2, ridge_alphas=[10.0, 0.01])
    ridge = ParametricBoostRegressor(drift="ridge", **kw).fit(X, y)
    assert ridge.choice_ == "ridge_drift" and ridge.note_ == "" and ridge.selection_ is None
    assert list(ridge.choices_["candidate"]) == ["prior", "calibrated", "ridge_drift"]
    # no selection: every parameter drifts in every covariate of the pool (5 + intercept)
    assert all(len(v) == 6 for v in ridge.estimator_.covariate_names_.values())
    path_ = ridge.ridge_path_
    assert list(path_["alpha"]) == [10.0, 0.01] and path_["chosen"].sum() == 1
    assert ridge.estimator_.alpha == path_.loc[path_["chosen"], "alpha"].item()
    assert ridge.cv_mae_ == path_["cv_mae"].min()
    table = ridge.estimator_.coefficient_table().set_index(["parameter", "covariate"])
    slope = table.loc[("tau", "temp"), "coef"] / table.loc[("tau", "temp"), "covariate_sd"]
    assert slope == pytest.approx(0.3, rel=0.15)
    both = ParametricBoostRegressor(drift="both", **kw).fit(X, y)
    cv = both.choices_.set_index("candidate")["cv_mae"]
    assert list(cv.index) == ["prior", "calibrated", "drift", "ridge_drift"]
    # the same folds: each drift scores as it does alone, and CV picks between them
    assert cv["ridge_drift"] == pytest.approx(ridge.cv_mae_, rel=1e-9)
    assert both.choice_ == ("ridge_drift" if cv["drift"] - cv["ridge_drift"] > 1e-3
                            else "drift")


def test_ridge_drift_settings_are_validated(tmp_path):
    path = _write(tmp_path, DECAY)
    X, y = _data(n=40)
    with pytest.raises(ValueError, match="ridge_alphas"):
        ParametricBoostRegressor(model=path, drift="ridge", ridge_alphas=[-1.0]).fit(X, y)
    with pytest.raises(ValueError, match="drift"):
        ParametricBoostRegressor(model=path, drift="lasso").fit(X, y)
