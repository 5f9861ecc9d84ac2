"""The link between prior and target: additive (identity) or multiplicative (log), in the core
estimator and as candidates CV chooses among (config)."""

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.linear_model import Ridge

from workbench import BaseBoostRegressor
from workbench.selection import BasisChoiceCV


def _multiplicative(n=400, seed=0):
    """A positive target whose prior is off by a factor that depends on x (a rate whose limit
    the prior gives): y = prior * exp(0.8 x) * noise."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, n)
    prior = np.exp(rng.normal(0, 1.5, n))  # over four decades
    y = prior * np.exp(0.8 * x) * np.exp(rng.normal(0, 0.05, n))
    return pd.DataFrame({"x": x, "prior": prior}), y


def _booster(link):
    return BaseBoostRegressor(prior="prior", basis=Ridge(1e-3), basis_features=["x"],
                              line_search_penalty=0.0, link=link)


def test_log_link_multiplies_the_prior():
    X, y = _multiplicative()
    model = _booster("log").fit(X, y)
    # exactly prior * exp(sum of the stages), the stages fitted on log y from log prior
    stage = model.coefs_[0] * model.estimators_[0].predict(X[["x"]].to_numpy())
    np.testing.assert_allclose(model.predict(X), X["prior"] * np.exp(stage), rtol=1e-12)
    np.testing.assert_allclose(model.predict_correction(X), model.predict(X) - X["prior"],
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(model.estimators_[0].coef_ * model.coefs_[0], [0.8], atol=0.02)
    # on a quantity spread over decades the additive link cannot express a relative error
    additive = _booster("identity").fit(X, y)
    X_new, y_new = _multiplicative(seed=1)
    err = {m.link: np.mean(np.abs(m.predict(X_new) - y_new)) for m in (model, additive)}
    assert err["log"] < 0.5 * err["identity"]
    staged = list(model.staged_predict(X))
    np.testing.assert_allclose(staged[-1], model.predict(X))


def test_identity_link_is_the_default_and_unchanged():
    X, y = _multiplicative()
    default = BaseBoostRegressor(prior="prior", basis=Ridge(1e-3), basis_features=["x"])
    assert default.get_params()["link"] == "identity"
    explicit = clone(default).set_params(link="identity")
    np.testing.assert_array_equal(default.fit(X, y).predict(X), explicit.fit(X, y).predict(X))


def test_log_link_refuses_values_that_are_not_positive():
    X, y = _multiplicative(n=50)
    y = y.copy()
    y[[3, 7]] = [0.0, -1.0]
    with pytest.raises(ValueError, match=r"the target y has 2 value\(s\) <= 0 \(rows \[3, 7\]\)"):
        _booster("log").fit(X, y)
    X2, y2 = _multiplicative(n=50)
    bad = X2.copy()
    bad.loc[5, "prior"] = 0.0
    with pytest.raises(ValueError, match=r"the prior has 1 value\(s\) <= 0 \(rows \[5\]\)"):
        _booster("log").fit(bad, y2)
    with pytest.raises(ValueError, match="link"):
        _booster("logit").fit(X2, y2)


def test_log_link_predicts_a_new_rows_prior_that_is_not_positive():
    """The fit refuses priors <= 0; a new row's prior may still be one (a physics model
    computed on new data): its prediction is the same formula, prior * exp(correction), not
    an error (it used to end evaluate with a traceback)."""
    X, y = _multiplicative(n=50)
    model = _booster("log").set_params(n_stages=2).fit(X, y)
    new = X.iloc[:4].copy()
    new["prior"] = [0.0, -2.0, 3.0, 1e-300]
    pred = model.predict(new)
    factor = model.predict(new.assign(prior=1.0))  # exp(correction) on each row
    np.testing.assert_allclose(pred, new["prior"] * factor, rtol=1e-12)
    np.testing.assert_allclose(model.predict(new.iloc[2:]), pred[2:])
    staged = list(model.staged_predict(new))
    assert len(staged) == 2 and all(np.isfinite(s).all() for s in staged)
    np.testing.assert_allclose(staged[-1], pred)
    np.testing.assert_allclose(model.predict_correction(new), pred - new["prior"], atol=1e-12)


@pytest.mark.parametrize("link", ["identity", "log"])
def test_out_of_bounds_clip_keeps_a_new_rows_correction_in_the_training_range(link):
    X, y = _multiplicative()
    free = _booster(link).set_params(n_stages=2).fit(X, y)
    clipped = clone(free).set_params(out_of_bounds="clip").fit(X, y)
    # inside the training range: the same model and the same predictions
    np.testing.assert_allclose(clipped.predict(X), free.predict(X), rtol=1e-12)
    low, high = clipped.correction_range_[-1]
    assert clipped.correction_range_.shape == (2, 2) and low < 0 < high
    # far outside (x = 40 where training saw [-1, 1]): the ridge stages extrapolate linearly,
    # the log link exponentially; clipped, the correction is the training rows' largest
    far = pd.DataFrame({"x": [40.0, -40.0], "prior": [2.0, 2.0]})
    start = np.log(2.0) if link == "log" else 2.0
    expected = np.array([start + high, start + low])
    expected = np.exp(expected) if link == "log" else expected
    np.testing.assert_allclose(clipped.predict(far), expected, rtol=1e-12)
    assert np.all(np.abs(free.predict(far) - 2.0) > np.abs(expected - 2.0))
    np.testing.assert_allclose(clipped.predict_correction(far), expected - 2.0, rtol=1e-9)
    for staged, k in zip(clipped.staged_predict(far), range(2)):
        bound = clipped.correction_range_[k]
        on_link = np.log(staged) if link == "log" else staged
        assert np.all(on_link - start >= bound[0] - 1e-12)
        assert np.all(on_link - start <= bound[1] + 1e-12)
    with pytest.raises(ValueError, match="out_of_bounds"):
        clone(free).set_params(out_of_bounds="nan").fit(X, y)


def test_cv_chooses_the_link_per_target():
    X, y = _multiplicative()
    choice = BasisChoiceCV([("identity", _booster("identity")), ("log", _booster("log"))],
                           cv=5).fit(X, y)
    assert choice.selected_candidate_ == "log"


def _csv_config(tmp_path, link, y_shift=0.0):
    X, y = _multiplicative(n=120)
    frame = X.assign(y=y + y_shift)
    frame.to_csv(tmp_path / "rates.csv", index=False)
    (tmp_path / "c.toml").write_text(
        f'name = "rates"\nrandom_state = 0\n[data]\ncsv = "{tmp_path / "rates.csv"}"\n'
        'prior = ["prior"]\ntargets = ["y"]\nfeatures = ["x"]\ntest_fraction = 0.25\n'
        f'[model]\nbasis = "ridge"\nbasis_inputs = "prior+features"\nlink = {link}\n'
        'input_transform = "standard"\nline_search_penalty = 0.0\n[intervals]\n'
        'enabled = false\n')
    return tmp_path / "c.toml"


def test_config_links_are_candidates_and_the_result_says_which_won(tmp_path):
    from workbench.experiment.config import load_dataset
    from workbench.experiment.families.stage import per_target_boost
    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.prepare import load_config

    cfg = load_config(_csv_config(tmp_path, '["identity", "log"]'))
    assert cfg.model_for("y")["link"] == ["identity", "log"]
    ds = load_dataset(cfg)
    boost = per_target_boost(cfg, ds, ds.prior_names)
    assert [n for n, _ in boost.target_estimators["y"].candidates] == ["identity", "log"]
    result = evaluate(cfg)
    assert result.model.selected == ["boosted"]
    choice = result.details["candidates"]["y"]
    assert choice["chosen"] == "log"
    assert set(choice["cv_mae"]) == {"prior", "identity", "log"}
    assert choice["cv_mae"]["log"] < choice["cv_mae"]["identity"] < choice["cv_mae"]["prior"]
    assert result.to_json()["candidates"]["y"]["chosen"] == "log"
    from workbench.experiment.runs.evaluate import format_table

    assert "y: CV chose log (CV MAE" in format_table(result)
    assert result.model.test_mae[0] < 0.5 * result.prior.test_mae[0]


def test_config_log_link_on_values_that_are_not_positive(tmp_path, caplog):
    from workbench.experiment.config import ConfigError, load_dataset
    from workbench.experiment.families.stage import per_target_boost
    from workbench.experiment.runs.prepare import load_config

    cfg = load_config(_csv_config(tmp_path, '"log"', y_shift=-5.0))
    ds = load_dataset(cfg)
    with pytest.raises(ConfigError, match=r'link = "log" needs positive targets and priors; '
                                          r"on the training rows y has \d+ value"):
        per_target_boost(cfg, ds, ds.prior_names)
    cfg = load_config(_csv_config(tmp_path, '["identity", "log"]', y_shift=-5.0))
    with caplog.at_level("INFO", logger="workbench"):
        boost = per_target_boost(cfg, ds, ds.prior_names)
    assert [n for n, _ in boost.target_estimators["y"].candidates] == ["identity"]
    assert 'link "log" left out' in caplog.text
    (tmp_path / "bad.toml").write_text('[model]\nlink = "logit"\n')
    with pytest.raises(ConfigError, match="link"):
        load_config(tmp_path / "bad.toml")


def test_spline_basis_extrapolates_linearly_where_trees_stay_flat():
    """A correction linear in x, learned on x in [-1, 1]: the spline basis carries it on to
    x = 2, a tree ensemble stays at its edge value; its parameters are checked like any
    basis's (config)."""
    from workbench import make_basis

    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, 200)
    X = pd.DataFrame({"x": x, "prior": np.zeros_like(x)})
    y = 0.5 * x + rng.normal(0, 0.01, 200)
    new = pd.DataFrame({"x": [2.0], "prior": [0.0]})
    spline = BaseBoostRegressor(prior="prior", basis=make_basis("spline", alpha=1e-3),
                                basis_features=["x"], line_search_penalty=0.0).fit(X, y)
    trees = BaseBoostRegressor(prior="prior", basis=make_basis("lightgbm", n_estimators=50),
                               basis_features=["x"], line_search_penalty=0.0).fit(X, y)
    assert spline.predict(new)[0] == pytest.approx(1.0, abs=0.05)
    assert trees.predict(new)[0] < 0.6
    from workbench.experiment.config import check_boost_settings

    settings = {"basis": "spline", "basis_params": {"n_knots": 1}, "loss": "squared_error",
                "link": "identity", "input_transform": "none", "input_transform_params": {}}
    with pytest.raises(ValueError, match="n_knots"):
        check_boost_settings(settings)
