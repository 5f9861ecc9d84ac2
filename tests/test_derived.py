"""PriorDerivedInputs: the derived columns by hand, the transform in a booster and as CV
candidates of a config."""

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.preprocessing import StandardScaler

from workbench import BaseBoostRegressor, PriorDerivedInputs, make_transform
from workbench.experiment.families.stage import candidate_settings, has_candidates, make_booster


def _block():
    rng = np.random.default_rng(0)
    P = rng.uniform(1, 2, size=(30, 2))
    F = rng.normal(size=(30, 1))
    return np.hstack([P, F])


def test_columns_by_hand():
    X = _block()
    Z = PriorDerivedInputs(n_priors=2).fit_transform(X)
    p1, p2, x = X[:, 0], X[:, 1], X[:, 2]
    expected = np.column_stack([X, p1 - p2, p1 / p2, np.log(p1), np.log(p2), p1 * x, p2 * x])
    np.testing.assert_allclose(Z, expected)


def test_kinds_and_domain():
    X = _block()
    X[0, 1] = -1.0  # prior 2 not positive: no log of it; nonzero: its ratio stays
    t = PriorDerivedInputs(n_priors=2, kinds=["log", "ratios"]).fit(X)
    assert t.log_priors_ == [0] and t.ratio_pairs_ == [(0, 1)] and t.pairs_ == []
    assert t.transform(X).shape == (30, 3 + 1 + 1)
    X[1, 1] = 0.0  # a zero denominator on a training row: no ratio
    assert PriorDerivedInputs(n_priors=2, kinds=["ratios"]).fit(X).ratio_pairs_ == []
    # a new row below the training range is clipped, never NaN
    low = X[:1].copy()
    low[0, 0] = -5.0
    assert np.isfinite(t.transform(low)).all()


@pytest.mark.parametrize("params, match", [
    (dict(kinds=["gaps"]), "unknown kind 'gaps'; valid kinds are differences, ratios"),
    (dict(n_priors=4), "n_priors=4 but the input has only 3 column"),
    (dict(n_priors=0), "n_priors"),
])
def test_bad_parameters(params, match):
    with pytest.raises(ValueError, match=match):
        PriorDerivedInputs(**params).fit(_block())


def test_then_and_clone():
    X = _block()
    t = make_transform("derived", n_priors=2)
    assert isinstance(t.then, StandardScaler)
    Z = t.fit_transform(X)
    np.testing.assert_allclose(Z.mean(axis=0), 0, atol=1e-12)
    assert clone(t).get_params()["n_priors"] == 2


def test_in_a_booster_learns_a_gap():
    """A correction that is a function of the gap between two priors: the derived
    differences let a depth-1 tree stage find it where the raw inputs need many splits."""
    rng = np.random.default_rng(1)
    P = rng.uniform(0, 10, size=(200, 2))
    y = P[:, 0] + 3.0 * (P[:, 0] - P[:, 1] > 0)
    from sklearn.tree import DecisionTreeRegressor

    def fit(transform):
        return BaseBoostRegressor(prior=0, basis=DecisionTreeRegressor(max_depth=1),
                                  n_stages=1, line_search_penalty=0.0,
                                  input_transform=transform, random_state=0).fit(P, y)

    raw = np.mean(np.abs(y - fit(None).predict(P)))
    derived = np.mean(np.abs(y - fit(PriorDerivedInputs(n_priors=2)).predict(P)))
    assert derived < 0.05 < raw


def test_candidates_and_n_priors():
    settings = dict(basis="ridge", basis_params={}, n_stages=1, loss="squared_error",
                    line_search_loss="absolute_error", line_search_penalty=0.0, alpha=0.9,
                    link="identity", basis_inputs="prior+features",
                    input_transform=["standard", "derived"], input_transform_params={},
                    draws=2)
    assert has_candidates(settings)
    names = [name for name, _ in candidate_settings(settings, 0)]
    assert names == ["standard", "derived"]
    booster = make_booster(candidate_settings(settings, 0)[1][1], prior=0, inputs=[0, 1, 2],
                           n_priors=2)
    assert booster.input_transform.n_priors == 2


def test_config_list_and_unknown_name():
    from workbench.experiment.process.errors import ConfigError
    from workbench.experiment.runs.prepare import parse_config

    raw = {"name": "t", "data": {"source": "google_5q"},
           "model": {"basis": "ridge", "input_transform": ["standard", "derived"]}}
    cfg = parse_config(raw)
    assert cfg.model_for("eeig1")["input_transform"] == ["standard", "derived"]
    raw["model"]["input_transform"] = ["standard", "derive"]
    with pytest.raises(ConfigError, match="input_transform = 'derive': unknown transform; "
                                          "valid: \\['none', 'derived'"):
        parse_config(raw)
