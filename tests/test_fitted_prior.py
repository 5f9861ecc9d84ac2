"""Base boosting on top of a fitted physics model (workbench.fitted_prior)."""

import warnings

import numpy as np
import pandas as pd
import pytest
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.exceptions import FitFailedWarning
from sklearn.linear_model import Ridge

from workbench import BaseBoostCV, BaseBoostRegressor, MultiTargetBaseBoost
from workbench.fitted_prior import FittedPriorBoost
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.simulate import Mismatch, simulate

N = 5
ONSITE = [f"model_f{i}" for i in range(1, N + 1)]
COUPLINGS = [f"model_g{i}" for i in range(1, N)]
MEASURED = [f"measured_E{i}" for i in range(1, N + 1)]
VOLTAGES = [f"v_q{i}" for i in range(1, N + 1)] + [f"v_c{i}" for i in range(1, N)]
INPUTS = VOLTAGES + ["temperature"]
PRIORS = [f"prior_{t}" for t in MEASURED]


@pytest.fixture(scope="module")
def crosstalk():
    """A coupler-induced frequency shift (which the Hamiltonian model corrects) plus an effect
    of a variable outside the Hamiltonian ("temperature", on the third eigenvalue only) that
    only the eigenvalue-space stage can learn."""
    data = simulate(N, 260, device_seed=3, mismatch=Mismatch(coupler_frequency_shift=1.0,
                                                      noise_sd=0.05)).data
    data["temperature"] = np.random.default_rng(0).normal(size=len(data))
    data["measured_E3"] += 1.5 * data["temperature"]
    return data.iloc[:180], data.iloc[180:]


def _physics():
    return HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS)


def _boost(basis):
    booster = BaseBoostRegressor(basis=basis, basis_features=PRIORS + INPUTS,
                                 line_search_penalty=0.0)
    return MultiTargetBaseBoost(BaseBoostCV(booster, cv=5), random_state=0)


def _mae(pred, frame):
    return float(np.abs(np.asarray(pred) - frame[MEASURED].to_numpy()).mean())


def test_boosting_stage_learns_what_the_physics_model_missed(crosstalk):
    train, test = crosstalk
    model = FittedPriorBoost(_physics(), _boost(Ridge(alpha=1e-3)))
    model.fit(train, train[MEASURED])
    pred = model.predict(test)
    assert isinstance(pred, pd.DataFrame) and list(pred.columns) == MEASURED
    assert pred.index.equals(test.index)
    assert model.prior_columns_ == PRIORS
    physics_alone = model.predict_prior(test)
    assert np.allclose(physics_alone, _physics().fit(train, train[MEASURED]).predict(test))
    assert model.selected_[2] == "boosted"
    assert _mae(pred, test) < 0.9 * _mae(physics_alone, test)
    e3 = test["measured_E3"].to_numpy()
    assert np.abs(pred["measured_E3"] - e3).mean() < 0.5 * np.abs(physics_alone[:, 2] - e3).mean()
    # the stage was trained on out-of-fold prior values, not the in-sample fit
    in_sample = model.predict_prior(train)
    oof = model.oof_prior_.to_numpy()
    assert model.oof_prior_.index.equals(train.index)
    assert not np.allclose(oof, in_sample)
    y = train[MEASURED].to_numpy()
    assert np.abs(oof - y).mean() > np.abs(in_sample - y).mean()


class _Broken(RegressorMixin, BaseEstimator):
    def fit(self, X, y):
        raise RuntimeError("this basis always fails")

    def predict(self, X):
        raise RuntimeError("never fitted")


def test_failed_boosting_keeps_the_physics_model(crosstalk):
    train, test = crosstalk
    model = FittedPriorBoost(_physics(), _boost(_Broken()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitFailedWarning)
        model.fit(train, train[MEASURED])
    assert model.selected_ == ["prior"] * N
    assert np.allclose(model.predict(test).to_numpy(), model.predict_prior(test))


def test_without_boost_stage_and_params(crosstalk):
    train, test = crosstalk
    model = FittedPriorBoost(_physics(), _boost(Ridge()), boost_stage=False, cv=3)
    twin = clone(model)
    assert twin.get_params()["cv"] == 3 and twin.get_params()["boost_stage"] is False
    twin.fit(train, train[MEASURED].to_numpy())
    assert list(twin.predict(test).columns) == [f"y{j}" for j in range(N)]
    assert twin.selected_ == ["prior"] * N
    assert not hasattr(twin, "boost_")
    assert np.allclose(twin.predict(test).to_numpy(), twin.predict_prior(test))


@pytest.mark.parametrize("change, match", [
    (dict(physics=None), "'physics' parameter of FittedPriorBoost must be an object "
     "implementing 'fit' and 'predict'. Got None"),
    (dict(prior_prefix="v_"), r"X already has column\(s\) \['v_q1'"),
])
def test_bad_setups_raise(crosstalk, change, match):
    train, _ = crosstalk
    model = FittedPriorBoost(**{"physics": _physics(), "boost": _boost(Ridge()), **change})
    Y = train[MEASURED].set_axis([f"q{i}" for i in range(1, N + 1)], axis=1)
    with pytest.raises(ValueError, match=match):
        model.fit(train, Y)


def test_fallback_keeps_the_control_prediction_where_the_physics_model_does_not_help():
    """Per target: the physics model where its out-of-fold MAE beats the control column's,
    the control column elsewhere (predictions and the stage's prior alike)."""
    from sklearn.linear_model import LinearRegression

    rng = np.random.default_rng(0)
    n = 200
    x = rng.uniform(-1, 1, n)
    control = np.column_stack([3 * x, 2 * np.sin(3 * x)])
    # target 0: the control misses 0.5 * x**2 (a physics model in x and x**2 captures it);
    # target 1: the control is exact but for noise, and the physics model cannot represent it
    Y = control + np.column_stack([0.5 * x ** 2, np.zeros(n)]) + 0.05 * rng.standard_normal((n, 2))
    X = pd.DataFrame({"x": x, "x2": x ** 2, "c0": control[:, 0], "c1": control[:, 1]})

    class Physics(LinearRegression):  # a multi-output model fitted on all columns but c*
        def fit(self, X, Y):
            return super().fit(X[["x", "x2"]], Y)

        def predict(self, X):
            return super().predict(X[["x", "x2"]])

    model = FittedPriorBoost(Physics(), boost_stage=False, fallback=["c0", "c1"], cv=5)
    model.fit(X, Y)
    assert model.physics_selected_.tolist() == [True, False]
    pred = model.predict(X).to_numpy()
    np.testing.assert_allclose(pred[:, 1], X["c1"])
    assert np.abs(pred[:, 0] - Y[:, 0]).mean() < np.abs(control[:, 0] - Y[:, 0]).mean()
    without = FittedPriorBoost(Physics(), boost_stage=False).fit(X, Y)
    assert without.physics_selected_.all()


def test_the_stage_chooses_its_prior_per_target_between_physics_and_alternative():
    """``alternative``: the stage is fitted on both models' out-of-fold priors and each
    target keeps the one it scores the lower CV MAE on (target 0 the physics model, which
    captures a curvature the stage's basis cannot learn; target 1 the alternative, exact
    but for what the stage learns); the final stage is refitted on that mixed prior, and
    the choice is the one the stage's own CV made (stage_cv_mae_)."""
    from sklearn.linear_model import LinearRegression

    class Columns(RegressorMixin, BaseEstimator):  # the control program's columns
        def fit(self, X, Y):
            self.fitted_ = True
            return self

        def predict(self, X):
            return X[["c0", "c1"]].to_numpy()

    class Physics(LinearRegression):  # linear in x and x**2, blind to the rest
        def fit(self, X, Y):
            return super().fit(X[["x", "x2"]], Y)

        def predict(self, X):
            return super().predict(X[["x", "x2"]])

    rng = np.random.default_rng(1)
    n = 300
    x, z = rng.uniform(-1, 1, n), rng.normal(size=n)
    control = np.column_stack([3 * x, 2 * np.sin(3 * x)])
    Y = (control + np.column_stack([0.5 * x ** 2, np.zeros(n)]) + np.outer(z, [1.0, 1.0])
         + 0.02 * rng.standard_normal((n, 2)))
    X = pd.DataFrame({"x": x, "x2": x ** 2, "z": z, "c0": control[:, 0], "c1": control[:, 1]})
    priors = ["prior_y0", "prior_y1"]
    booster = BaseBoostRegressor(basis=Ridge(alpha=1e-3), basis_features=["z"],
                                 line_search_penalty=0.0)
    stage = MultiTargetBaseBoost(BaseBoostCV(booster, cv=5), random_state=0)
    Yf = pd.DataFrame(Y, columns=["y0", "y1"])
    train, test = np.arange(200), np.arange(200, n)
    model = FittedPriorBoost(Physics(), stage, alternative=Columns(), cv=5)
    model.fit(X.iloc[train], Yf.iloc[train])
    assert model.prior_columns_ == priors
    assert model.alternative_selected_.tolist() == [False, True]
    cv = model.stage_cv_mae_
    assert list(cv.index) == ["y0", "y1"]
    assert cv.loc["y0", "physics"] < cv.loc["y0", "alternative"]
    assert cv.loc["y1", "alternative"] <= cv.loc["y1", "physics"]
    prior = model.predict_prior(X.iloc[test])
    np.testing.assert_allclose(prior[:, 1], X["c1"].iloc[test])
    np.testing.assert_allclose(prior[:, 0], model.physics_.predict(X.iloc[test])[:, 0])
    np.testing.assert_allclose(model.oof_prior_["prior_y1"], X["c1"].iloc[train])

    def test_mae(m):
        return np.abs(m.predict(X.iloc[test]).to_numpy() - Y[test]).mean(axis=0)

    alone = FittedPriorBoost(Physics(), clone(stage), cv=5).fit(X.iloc[train], Yf.iloc[train])
    mixed, physics_only = test_mae(model), test_mae(alone)
    assert mixed[0] == pytest.approx(physics_only[0], rel=0.2)
    assert mixed[1] < 0.5 * physics_only[1]
    # the same physics model as its own alternative: one stage, nothing switched
    same = FittedPriorBoost(Physics(), clone(stage), alternative=Physics(), cv=5)
    same.fit(X.iloc[train], Yf.iloc[train])
    assert not same.alternative_selected_.any()
    np.testing.assert_allclose(same.predict(X.iloc[test]), alone.predict(X.iloc[test]))
    with pytest.raises(ValueError, match="alternative and fallback"):
        FittedPriorBoost(Physics(), clone(stage), alternative=Columns(),
                         fallback=["c0", "c1"]).fit(X, Yf)
    # several by name: each its stage; the columns' prior still wins target 1, a model
    # as blind as the physics one (x only) wins nothing; its stage's CV is recorded
    class Linear(Physics):
        def fit(self, X, Y):
            return LinearRegression.fit(self, X[["x"]], Y)

        def predict(self, X):
            return LinearRegression.predict(self, X[["x"]])

    named = FittedPriorBoost(Physics(), clone(stage), cv=5,
                             alternative={"linear": Linear(), "columns": Columns()})
    named.fit(X.iloc[train], Yf.iloc[train])
    assert list(named.stage_cv_mae_.columns) == ["physics", "linear", "columns"]
    assert named.prior_choice_.tolist() == ["physics", "columns"]
    assert list(named.alternatives_) == ["linear", "columns"]
    np.testing.assert_allclose(named.predict(X.iloc[test]), model.predict(X.iloc[test]))
    with pytest.raises(ValueError, match='"physics" names the physics model'):
        FittedPriorBoost(Physics(), clone(stage), alternative={"physics": Columns()}).fit(X, Yf)
    with pytest.raises(ValueError, match="other_candidates_.*Physics has none"):
        FittedPriorBoost(Physics(), clone(stage), alternative="candidates").fit(X, Yf)


def test_the_mean_of_the_stages_is_kept_where_its_cv_is_lowest(caplog):
    """``stage_mean``: two priors with independent errors the stage cannot learn; each
    stage learns the shared effect of z, and the mean of the two stages halves the rest:
    its CV MAE (the mean of their CV predictions) is the lowest, so it is kept, and
    predict, predict_prior and cv_predictions_ are the means."""
    class Column(RegressorMixin, BaseEstimator):
        def __init__(self, column="a"):
            self.column = column

        def fit(self, X, Y):
            self.fitted_ = True
            return self

        def predict(self, X):
            return X[[self.column]].to_numpy()

    rng = np.random.default_rng(3)
    n = 400
    truth, z = rng.normal(size=n), rng.normal(size=n)
    X = pd.DataFrame({"a": truth + 0.3 * rng.standard_normal(n),
                      "b": truth + 0.3 * rng.standard_normal(n), "z": z})
    Y = pd.DataFrame({"y": truth + z})
    booster = BaseBoostRegressor(basis=Ridge(alpha=1e-3), basis_features=["z"],
                                 line_search_penalty=0.0)
    stage = MultiTargetBaseBoost(BaseBoostCV(booster, cv=5), random_state=0)
    train, test = np.arange(300), np.arange(300, n)
    with caplog.at_level("INFO", logger="workbench"):
        model = FittedPriorBoost(Column("a"), stage, alternative={"b": Column("b")}, cv=5,
                                 stage_mean=True, verbose=True).fit(X.iloc[train], Y.iloc[train])
    line = next(r.getMessage() for r in caplog.records if "on each prior" in r.getMessage())
    assert "the physics model" in line and " b " in line and "(kept)" in line.split("mean")[-1]
    cv = model.stage_cv_mae_.loc["y"]
    assert list(cv.index) == ["physics", "b", "mean"]
    assert model.prior_choice_.tolist() == ["mean"] and cv["mean"] < 0.85 * min(cv["physics"],
                                                                                 cv["b"])
    assert list(model.stages_) == ["physics", "b"] and model.selected_ == ["boosted"]
    assert np.mean(np.abs(Y.iloc[train].to_numpy() - model.cv_predictions_)) == pytest.approx(
        cv["mean"])
    Xt = X.iloc[test]
    each = [s.predict(model._with_prior(Xt, Xt[[c]].to_numpy())).to_numpy()
            for s, c in zip(model.stages_.values(), ["a", "b"], strict=True)]
    np.testing.assert_allclose(model.predict(Xt).to_numpy(), np.mean(each, axis=0))
    np.testing.assert_allclose(model.predict_prior(Xt), Xt[["a", "b"]].mean(axis=1).to_numpy()
                               .reshape(-1, 1))
    err = np.abs(model.predict(Xt).to_numpy() - Y.iloc[test].to_numpy()).mean()
    assert err < 0.85 * min(np.abs(e - Y.iloc[test].to_numpy()).mean() for e in each)
    # without it, a single prior's stage, as before
    single = clone(model).set_params(stage_mean=False).fit(X.iloc[train], Y.iloc[train])
    assert "mean" not in single.stage_cv_mae_ and not single.stages_


def test_out_of_fold_refits_only_when_something_uses_them(crosstalk, monkeypatch):
    """Without a stage or a fallback, cv_predictions=False fits the physics model once (no
    fold refits) and has no out-of-fold predictions; the default keeps them."""
    train, test = crosstalk
    fits = []
    original = HamiltonianParameterRegressor.fit

    def counting(self, X, y, coef_init=None):
        fits.append(coef_init is not None)
        return original(self, X, y, coef_init=coef_init)

    monkeypatch.setattr(HamiltonianParameterRegressor, "fit", counting)
    lean = FittedPriorBoost(_physics(), boost_stage=False, cv_predictions=False, cv=3)
    lean.fit(train, train[MEASURED])
    assert fits == [False]  # the fit on all rows, cold
    assert not hasattr(lean, "oof_prior_")
    with pytest.raises(AttributeError, match="cv_predictions=False"):
        _ = lean.cv_predictions_
    fits.clear()
    full = FittedPriorBoost(_physics(), boost_stage=False, cv=3).fit(train, train[MEASURED])
    # the fold refits start from the fit on all rows (coef_init)
    assert fits == [False, True, True, True]
    assert full.cv_predictions_.shape == (len(train), N)
    np.testing.assert_allclose(lean.predict(test), full.predict(test))


def test_fold_refits_give_the_same_numbers_on_several_processes(crosstalk):
    train, _ = crosstalk
    one = FittedPriorBoost(_physics(), boost_stage=False, cv=3, n_jobs=1)
    two = clone(one).set_params(n_jobs=2)
    a = one.fit(train, train[MEASURED]).cv_predictions_
    b = two.fit(train, train[MEASURED]).cv_predictions_
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(one.cv_folds_, two.cv_folds_)
    # warm starts end where cold starts do, to the fit's tolerance (here within 0.003, a
    # fraction of the noise sd 0.05)
    cold = np.empty_like(a)
    for k in range(3):
        rows = one.prior_folds_ == k
        model = _physics().fit(train[~rows], train[MEASURED].to_numpy()[~rows])
        cold[rows] = model.predict(train[rows])
    np.testing.assert_allclose(a, cold, atol=0.01)


def test_a_model_pickled_before_the_alternative_and_verbose_keeps_working():
    """A FittedPriorBoost pickled by an earlier release (no ``alternative``, ``verbose``,
    ``alternatives_``) unpickles with their defaults: get_params, clone, repr and predict;
    one with a single fitted ``alternative_`` gets it by name."""
    import pickle

    from sklearn.linear_model import LinearRegression

    rng = np.random.default_rng(0)
    X = pd.DataFrame({"x": rng.normal(size=40)})
    Y = np.column_stack([2 * X["x"], -X["x"]]) + 0.1 * rng.normal(size=(40, 2))
    model = FittedPriorBoost(LinearRegression(), boost_stage=False, cv=3).fit(X, Y)
    old = pickle.loads(pickle.dumps(model))
    for name in ("alternative", "stage_mean", "verbose", "alternatives_", "prior_choice_",
                 "stages_", "alternative_selected_", "stage_cv_mae_"):
        old.__dict__.pop(name, None)
    back = pickle.loads(pickle.dumps(old))
    assert back.get_params()["alternative"] is None and back.get_params()["verbose"] is False
    assert "FittedPriorBoost" in repr(back) and clone(back).verbose is False
    np.testing.assert_allclose(back.predict(X), model.predict(X))
    assert back.prior_choice_.tolist() == ["physics", "physics"]
    # fitted by the release whose one alternative was ``alternative_``: kept per target
    stage = MultiTargetBaseBoost(BaseBoostCV(BaseBoostRegressor(
        basis=Ridge(), line_search_penalty=0.0), cv=3), random_state=0)
    staged = FittedPriorBoost(LinearRegression(), stage, alternative=LinearRegression(), cv=3)
    staged.fit(X, Y)
    former = pickle.loads(pickle.dumps(staged))
    former.__dict__["alternative_"] = former.__dict__.pop("alternatives_").get("alternative")
    former.__dict__["alternative_selected_"] = np.array([False, True])
    del former.__dict__["prior_choice_"]
    back = pickle.loads(pickle.dumps(former))
    assert back.prior_choice_.tolist() == ["physics", "alternative"]
    assert list(back.alternatives_) == ["alternative"]
    assert back.predict(X).shape == (40, 2)
