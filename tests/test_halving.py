"""A basis tuned by successive halving over its folds (HalvingChoiceCV), and ``[model] tune
= "halving"``, which makes one such candidate of a basis's drawn settings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.dummy import DummyRegressor
from sklearn.linear_model import Ridge
from sklearn.tree import DecisionTreeRegressor

from workbench import BaseBoostRegressor, HalvingChoiceCV
from workbench.experiment.config import ConfigError
from workbench.experiment.families.stage import candidate_settings, make_booster
from workbench.experiment.runs.prepare import load_config


def _step(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    X = np.random.default_rng(seed).uniform(-1, 1, size=(n, 2))
    return X, 2.0 * (X[:, 0] > 0) + 0.05 * np.random.default_rng(seed + 1).standard_normal(n)


def _trees(n: int) -> list[tuple[str, DecisionTreeRegressor]]:
    """Depth 1 (the step), then deeper trees that only fit noise, and constants that miss
    the step; listed so that the right one is neither first nor last."""
    out = [(f"mean{i}", DummyRegressor()) for i in range(n // 2)]
    out.insert(n // 4, ("depth1", DecisionTreeRegressor(max_depth=1)))
    return out + [(f"deep{d}", DecisionTreeRegressor(max_depth=d, min_samples_leaf=1))
                  for d in range(12, 12 + n - len(out))]


def test_the_race_keeps_a_third_per_fold_and_refits_the_winner() -> None:
    X, y = _step(300, 0)
    basis = HalvingChoiceCV(_trees(24), cv=3, factor=3, random_state=0).fit(X, y)
    runs = sorted(basis.folds_run_.values())
    assert runs.count(1) == 16 and runs.count(2) == 5 and runs.count(3) == 3  # 24, 8, 3
    assert basis.chosen_ == "depth1"
    assert basis.cv_scores_["depth1"] == min(s for n, s in basis.cv_scores_.items()
                                             if basis.folds_run_[n] == 3)
    refit = DecisionTreeRegressor(max_depth=1).fit(X, y)
    np.testing.assert_allclose(basis.predict(X), refit.predict(X), rtol=1e-12)
    # a race that is down to one stops there: 9 -> 3 -> 1 after the second fold
    short = HalvingChoiceCV(_trees(9), cv=3, random_state=0).fit(X, y)
    assert max(short.folds_run_.values()) == 2 and short.chosen_ == "depth1"


def test_ties_go_to_the_first_listed_and_the_error_is_chosen() -> None:
    X, y = _step(90, 1)
    same = HalvingChoiceCV([("a", Ridge()), ("b", Ridge())], random_state=0).fit(X, y)
    assert same.chosen_ == "a"
    sq = HalvingChoiceCV(_trees(6), error="squared_error", random_state=0).fit(X, y)
    ab = HalvingChoiceCV(_trees(6), random_state=0).fit(X, y)
    assert sq.cv_scores_["depth1"] < ab.cv_scores_["depth1"]  # squared errors of ~0.05 noise


def test_one_seed_reaches_the_folds_and_the_candidates() -> None:
    from workbench import make_basis

    X, y = _step(150, 2)
    basis = HalvingChoiceCV([(f"d{i}", make_basis("lightgbm", n_estimators=20 + 10 * i,
                                                  subsample=0.6, subsample_freq=1))
                             for i in range(4)])
    a = BaseBoostRegressor(basis=basis, random_state=5).fit(X, y)
    b = BaseBoostRegressor(basis=clone(basis), random_state=5).fit(X, y)
    np.testing.assert_array_equal(a.predict(X), b.predict(X))
    stage = a.estimators_[0]
    assert isinstance(stage.random_state, int)
    assert stage.get_params()["d2__random_state"] == stage.random_state


def test_bad_settings_are_named() -> None:
    X, y = _step(20, 3)
    with pytest.raises(ValueError, match="at least one candidate"):
        HalvingChoiceCV([]).fit(X, y)
    with pytest.raises(ValueError, match="unique"):
        HalvingChoiceCV([("a", Ridge()), ("a", Ridge())]).fit(X, y)
    with pytest.raises(ValueError, match="n_samples = 2, fewer than the cv=3 folds"):
        HalvingChoiceCV([("a", Ridge())]).fit(X[:2], y[:2])
    with pytest.raises(ValueError, match="factor"):
        HalvingChoiceCV([("a", Ridge())], factor=1).fit(X, y)
    with pytest.raises(ValueError, match="error"):
        HalvingChoiceCV([("a", Ridge())], error="huber").fit(X, y)


HEAD = ('basis = ["ridge", "lightgbm"]\nlink = ["identity", "log"]\ndraws = 5\n'
        'line_search_penalty = 0.0\nbasis_inputs = "prior+features"\n')
TABLE = ('[model.basis_params.lightgbm]\nn_estimators = { low = 10, high = 40, log = true }\n'
        'num_leaves = { low = 3, high = 8 }\n')


def _config(tmp_path: Path, model: str) -> Path:
    rng = np.random.default_rng(0)
    n = 120
    x = rng.uniform(1, 2, n)
    frame = pd.DataFrame({"x": x, "prior": x, "y": x + 0.3 * (x > 1.5),
                          "split": np.where(np.arange(n) < 90, "train", "test")})
    frame.to_csv(tmp_path / "d.csv", index=False)
    path = tmp_path / "c.toml"
    path.write_text('name = "c"\nrandom_state = 3\n[data]\ncsv = "d.csv"\nprior = ["prior"]\n'
                    'targets = ["y"]\nfeatures = ["x"]\nsplit_column = "split"\n'
                    f'[selection]\ncv = 3\nshuffle = true\n[model]\n{model}')
    return path


def test_tune_halving_makes_one_candidate_per_basis_and_link(tmp_path: Path) -> None:
    drawn = load_config(_config(tmp_path, HEAD + TABLE))
    tuned = load_config(_config(tmp_path, HEAD + 'tune = "halving"\n' + TABLE))
    many = candidate_settings(drawn.model_for("y"), drawn.random_state)
    few = candidate_settings(tuned.model_for("y"), tuned.random_state)
    assert [n for n, _ in few] == ["ridge/identity", "ridge/log", "lightgbm#halving/identity",
                                   "lightgbm#halving/log"]
    assert len(many) == 2 + 2 * 5
    # the one candidate races exactly the settings that were the draws
    races = [c["halving"] for n, c in few if "halving" in c]
    assert races[0] == races[1] == [c["basis_params"] for n, c in many
                                    if n.endswith("/identity") and "#" in n]
    booster = make_booster(dict(few)["lightgbm#halving/log"], "prior", ["prior", "x"])
    assert isinstance(booster.basis, HalvingChoiceCV) and booster.link == "log"
    assert [c.get_params()["n_estimators"] for _, c in booster.basis.estimators] == \
        [p["n_estimators"] for p in races[0]]


def test_a_config_with_tune_halving_evaluates(tmp_path: Path) -> None:
    from workbench.experiment.config import load_dataset
    from workbench.experiment.families.stage import per_target_boost

    cfg = load_config(_config(tmp_path, HEAD + 'tune = "halving"\n' + TABLE))
    ds = load_dataset(cfg)
    X_tr, X_te, Y_tr, Y_te = ds.split()
    model = per_target_boost(cfg, ds, ds.prior_names).fit(X_tr, Y_tr)
    est = model.estimators_[0]
    assert set(est.candidate_scores_) >= {"prior", "lightgbm#halving/identity"}
    assert np.isfinite(np.asarray(model.predict(X_te), dtype=float)).all()


def test_an_unknown_tune_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="tune") as exc:
        load_config(_config(tmp_path, HEAD + 'tune = "optuna"\n' + TABLE))
    assert len(str(exc.value).splitlines()) == 1
