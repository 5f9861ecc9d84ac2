"""Boosting in a user's model's parameter space (workbench.parametric_gbm), and its place
among ParametricBoostRegressor's candidates and in the config."""

import json

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.linear_model import Ridge
from sklearn.tree import DecisionTreeRegressor

from workbench.experiment.cli import main
from workbench.parametric import ParametricModel
from workbench.parametric_boost import ParametricBoostRegressor
from workbench.parametric_gbm import ParameterSpaceBoostRegressor, make_regressor

PARAMETERS = {"amplitude": 2.0, "tau": 1.0, "offset": 0.0}


def _predict(params, data):
    t = data["t"].to_numpy()
    return params["amplitude"] * np.exp(-t / params["tau"]) + params["offset"]


MODEL = ParametricModel.from_functions(PARAMETERS, _predict)


def _data(n=200, seed=0, step=0.0, missing=0.0):
    """Decay whose lifetime jumps with temp (``step``: no linear drift follows it) and,
    optionally, a term no parameter drift in temp or humidity makes: a step in t."""
    rng = np.random.default_rng(seed)
    X = pd.DataFrame({"t": rng.uniform(0, 3, n), "temp": rng.normal(0, 1, n),
                      "humidity": rng.normal(0, 1, n)})
    t, temp = X["t"].to_numpy(), X["temp"].to_numpy()
    tau = 1.5 + step * np.where(np.abs(temp) < 0.7, 1.0, -1.0)
    y = 2.5 * np.exp(-t / tau) + 0.1 + missing * (t > 1.5) + rng.normal(0, 0.01, n)
    return X, y


FEATURES = ["temp", "humidity"]


def _choice(**kw):
    return ParametricBoostRegressor(
        model=MODEL, features=FEATURES, huber_delta=0.05, max_steps=2, random_state=0,
        boost=ParameterSpaceBoostRegressor(features=FEATURES, n_estimators=80, **kw))


def test_boosting_in_parameter_space_wins_where_the_drift_is_not_linear():
    X, y = _data(step=0.4)
    est = _choice().fit(X, y)
    cv = est.choices_.set_index("candidate")["cv_mae"]
    assert list(cv.index) == ["prior", "calibrated", "drift", "boost"]
    assert est.choice_ == "boost" and est.note_ == ""
    assert cv["boost"] < 0.5 * min(cv["drift"], cv["calibrated"])
    booster = est.estimator_
    assert 0 < booster.n_iter_ <= 80 and booster.n_estimators == booster.n_iter_
    # the lifetime it learned follows the jump in temp
    tau = booster.corrected_parameters(X)["tau"]
    inside = np.abs(X["temp"]) < 0.5
    outside = np.abs(X["temp"]) > 1.0
    assert 0.3 < tau[inside].mean() - tau[outside].mean() < 1.0  # the true jump: 0.8
    assert np.all(np.diff(booster.train_loss_) <= 1e-12)  # every round lowers the loss
    staged = list(booster.staged_predict(X))
    assert len(staged) == booster.n_iter_ + 1
    np.testing.assert_allclose(staged[-1], booster.predict(X))


def test_the_candidates_not_chosen_are_kept_unfitted_for_the_stage():
    """``other_candidates_``: every candidate CV scored but did not choose, simplest first,
    with its own choices made (the drift's covariates, the boost's rounds); a boost of 0
    rounds is its start model and is left out."""
    X, y = _data(step=0.4)
    est = _choice().fit(X, y)
    others = est.other_candidates_
    assert est.choice_ == "boost" and list(others) == ["calibrated", "drift"]
    assert others["drift"].covariates == est.selection_.covariates
    assert not hasattr(others["drift"], "coef_")  # unfitted
    X, y = _data(n=120)  # no drift to find: the boost stops at once
    idle = _choice().set_params(boost=ParameterSpaceBoostRegressor(
        features=FEATURES, n_estimators=0)).fit(X, y)
    assert "boost" in set(idle.choices_["candidate"]) and "boost" not in idle.other_candidates_


def test_cv_falls_back_where_the_error_is_not_in_the_parameters():
    X, y = _data(missing=0.2)  # a step in t: no parameter moved by temp or humidity makes it
    est = _choice().fit(X, y)
    cv = est.choices_.set_index("candidate")["cv_mae"]
    assert est.choice_ in ("prior", "calibrated")
    assert "not a drift of the parameters" in est.note_
    assert cv[est.choice_] <= cv.min() + est.min_improvement  # never worse than the others


def test_a_boost_from_the_drift_starts_from_the_calibration_when_nothing_is_selected():
    # init="drift" with a selection that takes no covariate (the acentric factors' inner
    # omega_hot split): the boost starts from the calibrated model instead of raising
    X, y = _data(step=0.4, n=120)
    est = ParametricBoostRegressor(
        model=MODEL, features=FEATURES, huber_delta=0.05, max_steps=0, random_state=0,
        boost=ParameterSpaceBoostRegressor(features=FEATURES, n_estimators=20,
                                           init="drift")).fit(X, y)
    assert est.selection_ is not None and est.selection_.covariates == {}
    cv = est.choices_.set_index("candidate")["cv_mae"]
    assert est.choice_ == "boost" and cv["boost"] < cv["calibrated"]
    start = est.estimator_.init_
    assert start.max_iter == 0 and not getattr(start, "covariates", None)  # the calibration


@pytest.mark.parametrize("kw", [dict(step="gradient"), dict(update="greedy"),
                                dict(estimator=Ridge(alpha=1.0)),
                                dict(parameters=["tau"], subsample=0.7)])
def test_variants_lower_the_training_loss(kw):
    X, y = _data(step=0.4, n=120)
    est = ParameterSpaceBoostRegressor(model=MODEL, features=FEATURES, n_estimators=15,
                                       huber_delta=0.05, random_state=0, **kw).fit(X, y)
    linear = isinstance(kw.get("estimator"), Ridge)  # a line cannot follow the jump well
    assert est.n_iter_ > 0 and est.train_loss_[-1] < (1.0 if linear else 0.7) * est.train_loss_[0]
    assert np.all(np.diff(est.train_loss_) <= 1e-12)
    if "parameters" in kw:  # only tau moves away from the calibration
        moved = est.corrected_parameters(X) - est.init_.corrected_parameters(X)
        assert moved["tau"].abs().max() > 0 and not moved[["amplitude", "offset"]].any().any()
    if kw.get("update") == "greedy":
        assert all(len(fits) == 1 for fits in est.estimators_)


def test_same_seed_same_numbers_clone_and_params():
    X, y = _data(step=0.4, n=120)
    est = ParameterSpaceBoostRegressor(model=MODEL, features=FEATURES, n_estimators=10,
                                       subsample=0.6, random_state=3,
                                       estimator=DecisionTreeRegressor(max_features=1))
    a, b = clone(est).fit(X, y), clone(est).fit(X, y)
    np.testing.assert_array_equal(a.predict(X), b.predict(X))
    c = clone(est).set_params(random_state=4).fit(X, y)
    assert not np.array_equal(a.predict(X), c.predict(X))  # other subsamples and trees
    assert clone(est).get_params()["subsample"] == 0.6
    assert set(est.get_params()) >= {"model", "estimator", "init", "n_estimators",
                                     "learning_rate", "step", "update", "random_state"}
    chooser = _choice(subsample=0.6)
    p, q = clone(chooser).fit(X, y), clone(chooser).fit(X, y)
    pd.testing.assert_frame_equal(p.choices_, q.choices_)
    np.testing.assert_array_equal(p.predict(X), q.predict(X))


@pytest.mark.parametrize("kw, message", [
    (dict(parameters=["nope"]), r"unknown parameter\(s\) \['nope'\]"),
    (dict(features=["pressure"]), r"features \['pressure'\] are not columns of X"),
    (dict(init="drift"), "init='drift' is the drift a ParametricBoostRegressor selects"),
    (dict(step="sideways"), "'step' parameter"),
    (dict(learning_rate=0.0), "'learning_rate' parameter"),
    (dict(model=None), "needs a model"),
])
def test_bad_input_is_one_line(kw, message):
    X, y = _data(n=40)
    est = ParameterSpaceBoostRegressor(**{"model": MODEL, "features": FEATURES,
                                          "n_estimators": 2, **kw})
    with pytest.raises(ValueError, match=message) as info:
        est.fit(X, y)
    assert "\n" not in str(info.value)


def test_an_unknown_regressor_lists_the_valid_names():
    with pytest.raises(ValueError, match="unknown parameter-space regressor 'forest'") as info:
        make_regressor("forest")
    assert "tree" in str(info.value) and "lightgbm" in str(info.value)
    assert make_regressor("tree").max_depth == 3
    assert make_regressor("tree", {"max_depth": 5}).max_depth == 5


def test_the_config_table_makes_the_candidate(tmp_path, capsys):
    X, y = _data(step=0.4, n=120)
    X.assign(y=y).to_csv(tmp_path / "decay.csv", index=False)
    model = tmp_path / "decay.py"
    model.write_text("import numpy as np\n\nPARAMETERS = {'amplitude': 2.0, 'tau': 1.0, "
                     "'offset': 0.0}\n\n\ndef predict(params, data):\n    t = data['t']."
                     "to_numpy()\n    return params['amplitude'] * np.exp(-t / params['tau'])"
                     " + params['offset']\n")
    config = tmp_path / "decay.toml"
    assert main(["init", str(tmp_path / "decay.csv"), "--model", str(model), "--target", "y",
                 "--out", str(config)]) == 0
    base = config.read_text()
    config.write_text(base + '\n[model.parametric.boost]\nregressor = "tree"\nrounds = 40\n'
                      'start = "drift"\n')
    out = tmp_path / "result.json"
    # no --out: its figures (the learning curve refits the boosted model at 3 sizes x 5
    # folds) were most of this test's CPU; the candidates compared are the JSON's choices,
    # the rows choices.csv is written from (its writing: test_parametric_family.py)
    assert main(["evaluate", str(config), "--no-track", "--json", str(out), "--jobs", "1",
                 "--set", "model.parametric.max_steps=1",
                 "--set", "model.parametric.boost_stage=false"]) == 0
    result = json.loads(out.read_text())
    assert result["parametric"]["choice"] == "boost"
    assert result["model"]["selected"] == ["parametric:boost"]
    choices = result["parametric"]["choices"]
    assert [c["candidate"] for c in choices] == ["prior", "calibrated", "drift", "boost"]
    config.write_text(base + '\n[model.parametric.boost]\nregressor = "forest"\n')
    capsys.readouterr()
    assert main(["evaluate", str(config), "--no-track", "--jobs", "1"]) != 0
    err = capsys.readouterr().err
    assert "unknown parameter-space regressor 'forest'" in err and "tree" in err


def test_calibrated_guard_stops_the_boosted_steps_beyond_the_box():
    """out_of_bounds="calibrated": beyond the features' training range the boosted model
    gives the calibrated model's parameters (no drift, no boosted steps), inside it the
    same as without the guard; "clip" clips the regressors' inputs."""
    from workbench.param_regressor import ParametricRegressor

    X, y = _data(step=0.3)
    init = ParametricRegressor(covariates={"tau": ["temp"]})
    kw = dict(model=MODEL, features=FEATURES, init=init, n_estimators=20, huber_delta=0.05,
              random_state=0)
    guard = ParameterSpaceBoostRegressor(**kw, out_of_bounds="calibrated").fit(X, y)
    free = ParameterSpaceBoostRegressor(**kw).fit(X, y)
    calibrated = ParametricRegressor(model=MODEL, huber_delta=0.05, max_iter=0).fit(X, y)
    far = X.iloc[:3].assign(temp=[X["temp"].max() + 3.0, 0.1, 0.0],
                            humidity=[0.0, X["humidity"].min() - 1.0, 0.0])
    np.testing.assert_allclose(guard.predict(far.iloc[:2]), calibrated.predict(far.iloc[:2]),
                               rtol=1e-10)
    assert np.abs(free.predict(far.iloc[:2]) - guard.predict(far.iloc[:2])).max() > 1e-3
    np.testing.assert_allclose(guard.predict(X), free.predict(X))
    np.testing.assert_allclose(guard.predict(far.iloc[2:]), free.predict(far.iloc[2:]))
    staged = list(guard.staged_predict(far.iloc[:2]))
    np.testing.assert_allclose(staged[0], staged[-1])  # no boosted step beyond the box
    clip = ParameterSpaceBoostRegressor(**kw, out_of_bounds="clip").fit(X, y)
    edge = far.assign(temp=far["temp"].clip(X["temp"].min(), X["temp"].max()),
                      humidity=far["humidity"].clip(X["humidity"].min(), X["humidity"].max()))
    np.testing.assert_allclose(clip.corrected_parameters(far).to_numpy(),
                               clip.corrected_parameters(edge).to_numpy())
    with pytest.raises(ValueError, match="out_of_bounds"):
        clone(guard).set_params(out_of_bounds="hold").fit(X, y)
    assert clone(guard).get_params()["out_of_bounds"] == "calibrated"
