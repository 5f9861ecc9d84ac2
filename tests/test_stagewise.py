"""Heterogeneous stages: StageChoiceCV chooses each stage's basis by CV on its residuals."""

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.linear_model import Ridge
from sklearn.tree import DecisionTreeRegressor

from workbench import BaseBoostRegressor, StageChoiceCV, make_basis


def _trend_and_step(n, seed):
    """A linear trend in x0 plus a step in x1: a line for the first, a split for the second."""
    X = np.random.default_rng(seed).uniform(-1, 1, size=(n, 2))
    return X, 3 * X[:, 0] + 2 * (X[:, 1] > 0)


def _candidates():
    return [("ridge", Ridge(alpha=1e-6)), ("tree", DecisionTreeRegressor(max_depth=1))]


def test_each_stage_chooses_its_basis_on_its_own_residuals():
    X, y = _trend_and_step(300, 0)
    X_new, y_new = _trend_and_step(300, 1)
    model = BaseBoostRegressor(basis=StageChoiceCV(_candidates()), n_stages=2,
                               line_search_loss="squared_error", line_search_penalty=0.0,
                               random_state=0).fit(X, y)
    first, second = model.estimators_
    # the line takes the trend first (and part of the step); a split takes what is left
    assert first.chosen_ == "ridge" and second.chosen_ == "tree"
    for stage in model.estimators_:
        assert stage.chosen_ == min(stage.cv_scores_, key=stage.cv_scores_.get)
        assert set(stage.cv_scores_) == {"ridge", "tree"}
    # the mixed stages beat either basis repeated, on new rows
    errors = {}
    for name, basis in [("mixed", StageChoiceCV(_candidates())), *_candidates()]:
        fitted = BaseBoostRegressor(basis=basis, n_stages=2, line_search_loss="squared_error",
                                    line_search_penalty=0.0, random_state=0).fit(X, y)
        errors[name] = np.mean((fitted.predict(X_new) - y_new) ** 2)
    assert errors["mixed"] < min(errors["ridge"], errors["tree"])


def test_one_seed_reaches_the_folds_and_the_candidates():
    X, y = _trend_and_step(120, 2)
    basis = StageChoiceCV([("ridge", Ridge()),
                           ("lightgbm", make_basis("lightgbm", n_estimators=20,
                                                   subsample=0.7, subsample_freq=1))])
    a = BaseBoostRegressor(basis=basis, n_stages=2, random_state=4).fit(X, y)
    b = BaseBoostRegressor(basis=clone(basis), n_stages=2, random_state=4).fit(X, y)
    np.testing.assert_array_equal(a.predict(X), b.predict(X))
    for stage in a.estimators_:
        assert isinstance(stage.random_state, int)
        assert stage.get_params()["lightgbm__random_state"] == stage.random_state


def test_bad_candidates_and_too_few_rows_are_named():
    X, y = _trend_and_step(20, 3)
    with pytest.raises(ValueError, match="at least one candidate"):
        StageChoiceCV([]).fit(X, y)
    with pytest.raises(ValueError, match="unique"):
        StageChoiceCV([("a", Ridge()), ("a", Ridge())]).fit(X, y)
    with pytest.raises(ValueError, match="n_samples = 2, fewer than the cv=3 folds"):
        StageChoiceCV(_candidates()).fit(X[:2], y[:2])


def test_the_registry_builds_it_with_nested_parameters():
    basis = make_basis("stagewise", candidates=["ridge", "lightgbm"], cv=4,
                       lightgbm__num_leaves=7)
    assert isinstance(basis, StageChoiceCV) and basis.cv == 4
    assert [name for name, _ in basis.estimators] == ["ridge", "lightgbm"]
    assert basis.get_params()["lightgbm__num_leaves"] == 7
    with pytest.raises(ValueError, match="unknown basis 'nope'; valid names are: .*ridge"):
        make_basis("stagewise", candidates=["ridge", "nope"])
    with pytest.raises(ValueError, match="cannot be stagewise"):
        make_basis("stagewise", candidates=["stagewise"])
    with pytest.raises(ValueError, match="Invalid parameter"):
        make_basis("stagewise", candidates=["ridge"], lightgbm__num_leaves=7)


def test_a_config_of_heterogeneous_stages_reports_each_stage_choice(tmp_path):
    """``basis = "stagewise"`` with ``n_stages = 2`` in a config: the candidates' settings
    nested (a range drawn like any basis's), and ``evaluate`` reports the basis each stage
    chose per target."""
    from workbench.experiment.families.stage import candidate_settings
    from workbench.experiment.runs.evaluate import evaluate, format_table
    from workbench.experiment.runs.prepare import load_config

    X, y = _trend_and_step(160, 5)
    frame = pd.DataFrame({"x0": X[:, 0], "x1": X[:, 1], "prior": np.zeros(160), "y": y,
                          "split": np.where(np.arange(160) < 120, "train", "test")})
    frame.to_csv(tmp_path / "d.csv", index=False)
    (tmp_path / "c.toml").write_text(
        'name = "c"\nrandom_state = 0\n[data]\ncsv = "d.csv"\nprior = ["prior"]\n'
        'targets = ["y"]\nfeatures = ["x0", "x1"]\nsplit_column = "split"\n'
        '[model]\nbasis = "stagewise"\nn_stages = 2\nbasis_inputs = "prior+features"\n'
        'line_search_penalty = 0.0\ndraws = 2\n[model.basis_params]\n'
        'candidates = ["ridge", "lightgbm"]\nlightgbm__n_estimators = { low = 10, high = 40 }\n'
        '[selection]\ncv = 3\nshuffle = true\n')
    cfg = load_config(tmp_path / "c.toml")
    names = [name for name, _ in candidate_settings(cfg.model_for("y"), cfg.random_state)]
    assert names == ["stagewise#00", "stagewise#01"]
    result = evaluate(cfg)
    chosen = result.details["stages"]["y"]  # one name per stage of the selected candidate
    assert len(chosen) == 2 and set(chosen) <= {"ridge", "lightgbm"}
    assert (f"y: each stage's basis by CV on its residuals: {' > '.join(chosen)}"
            in format_table(result))
