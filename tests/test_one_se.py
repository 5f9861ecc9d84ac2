"""The one-standard-error rule (``rule="one_se"``, ``[selection] rule``): the simplest model
within one standard error of the paired fold differences from the best, the prior first; the
family's order of complexity; and the lines ``evaluate`` prints about the prior."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.utils._param_validation import InvalidParameterError

from workbench.bases import make_basis
from workbench.boosting import BaseBoostRegressor
from workbench.selection import BaseBoostCV, BasisChoiceCV, choose, paired_standard_error

PRIOR = np.array([-1.0, -2.0, -3.0, -1.5])  # fold scores (negative MAE): hard and easy folds
SMALL = PRIOR + [0.3, -0.1, 0.2, -0.1]  # a gain of 0.075 that the folds cannot tell from noise
CLEAR = PRIOR + [0.5, 0.6, 0.55, 0.5]  # a gain of 0.5375, far above its noise


def test_paired_standard_error_by_hand() -> None:
    # d = a - b = [1, 1, 3]: mean 5/3; deviations -2/3, -2/3, 4/3; sample variance
    # (4/9 + 4/9 + 16/9) / 2 = 4/3; standard error sqrt(4/3) / sqrt(3) = 2/3
    assert paired_standard_error([1.0, 2.0, 4.0], [0.0, 1.0, 1.0]) == pytest.approx(2 / 3)
    # SMALL - PRIOR = [0.3, -0.1, 0.2, -0.1]: mean 0.075, squared deviations 0.050625,
    # 0.030625, 0.015625, 0.030625, variance 0.1275 / 3 = 0.0425, SE sqrt(0.0425) / 2
    assert paired_standard_error(SMALL, PRIOR) == pytest.approx(np.sqrt(0.0425) / 2)
    assert paired_standard_error(SMALL, PRIOR) == paired_standard_error(PRIOR, SMALL)
    # what both models share (a hard fold is hard for both) cancels: no noise left
    assert paired_standard_error(PRIOR + 0.1, PRIOR) == pytest.approx(0.0, abs=1e-12)
    assert paired_standard_error([1.0], [0.0]) == 0.0  # one fold: no spread to measure


def test_a_gain_within_noise_keeps_the_prior_a_clear_gain_wins() -> None:
    assert np.mean(SMALL - PRIOR) <= paired_standard_error(SMALL, PRIOR)  # the premise
    assert choose({"prior": PRIOR, "small": SMALL}) == "small"
    assert choose({"prior": PRIOR, "small": SMALL}, "one_se") == "prior"
    assert choose({"prior": PRIOR, "clear": CLEAR}, "one_se") == "clear"
    # the simplest within noise of the best, not the best: CLEAR is within noise of BEST
    best = CLEAR + [0.1, -0.05, 0.1, -0.05]
    scores = {"prior": PRIOR, "small": SMALL, "clear": CLEAR, "mean of 2": best}
    assert choose(scores) == "mean of 2"
    assert choose(scores, "one_se") == "clear"


def test_prior_se_guards_the_prior_only() -> None:
    # within noise of the prior: the prior; clearly better: the best, not the simplest
    # candidate within noise of it (as one_se would take)
    assert choose({"prior": PRIOR, "small": SMALL}, "prior_se") == "prior"
    best = CLEAR + [0.1, -0.05, 0.1, -0.05]
    scores = {"prior": PRIOR, "small": SMALL, "clear": CLEAR, "mean of 2": best}
    assert choose(scores, "prior_se") == "mean of 2"
    assert choose(scores, "one_se") == "clear"
    # the prior best of all: the prior
    assert choose({"prior": CLEAR, "a": PRIOR}, "prior_se") == "prior"


def test_ties_go_to_the_simplest() -> None:
    for rule in ("best", "one_se", "prior_se"):
        assert choose({"prior": PRIOR, "a": PRIOR.copy()}, rule) == "prior"
        assert choose({"prior": PRIOR, "a": CLEAR, "b": CLEAR.copy()}, rule) == "a"
        assert choose({"prior": PRIOR, "b": CLEAR.copy(), "a": CLEAR}, rule) == "b"
    with pytest.raises(ValueError, match="valid rules are: best, one_se, prior_se"):
        choose({"prior": PRIOR}, "1se")


def _data(slope: float, seed: int, n: int = 120) -> tuple[pd.DataFrame, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2, 2, size=(n, 2))
    prior = 3 * x[:, 0]
    y = prior + slope * x[:, 1] + 0.3 * rng.standard_normal(n)
    return pd.DataFrame({"prior": prior, "x0": x[:, 0], "x1": x[:, 1]}), y


def _candidates() -> list[tuple[str, BaseBoostRegressor]]:
    def booster(name, **params):
        return BaseBoostRegressor(prior="prior", basis=make_basis(name, **params),
                                  basis_features=["x0", "x1"], n_stages=1,
                                  line_search_penalty=0.0)
    return [("ridge", booster("ridge", alpha=1e-3)),
            ("lightgbm", booster("lightgbm", n_estimators=60, min_child_samples=5))]


def test_basis_choice_keeps_the_prior_when_the_best_is_within_noise() -> None:
    X, y = _data(slope=0.03, seed=2)  # a correction too small for 120 rows to show
    best = BasisChoiceCV(_candidates(), cv=5, random_state=0).fit(X, y)
    one_se = BasisChoiceCV(_candidates(), cv=5, random_state=0, rule="one_se").fit(X, y)
    scores = best.candidate_scores_
    gain = np.mean(scores["ridge"] - scores["prior"])
    assert best.best_candidate_ == one_se.best_candidate_ == "ridge" and gain > 0
    assert gain <= paired_standard_error(scores["ridge"], scores["prior"])  # the premise
    assert best.selected_candidate_ == "ridge"
    assert one_se.selected_ == "prior" and one_se.selected_candidate_ is None
    np.testing.assert_allclose(one_se.predict(X), X["prior"])
    assert one_se.cv_score_ == pytest.approx(scores["prior"].mean())
    # the same folds, the same scores: only the rule differs
    for name in scores:
        np.testing.assert_array_equal(scores[name], one_se.candidate_scores_[name])


@pytest.mark.parametrize("kind", ["linear", "step"])
def test_basis_choice_takes_a_candidate_that_clearly_wins(kind: str) -> None:
    X, y = _data(slope=0.0, seed=0, n=240)
    y = y + (0.8 * X["x1"] if kind == "linear" else 1.5 * (X["x1"] > 0.3)).to_numpy()
    model = BasisChoiceCV(_candidates(), cv=5, random_state=0, rule="one_se").fit(X, y)
    # linear: both bases fit it, ridge is listed first (simpler); a step needs the trees
    assert model.selected_candidate_ == ("ridge" if kind == "linear" else "lightgbm")
    s = model.candidate_scores_
    chosen = s[model.selected_candidate_]
    assert np.mean(chosen - s["prior"]) > paired_standard_error(chosen, s["prior"])


def test_identical_candidates_the_first_listed_wins_and_seeds_repeat() -> None:
    X, y = _data(slope=0.8, seed=1)
    ridge = dict(_candidates())["ridge"]
    model = BasisChoiceCV([("a", ridge), ("b", clone(ridge))], cv=4, rule="one_se",
                          random_state=3).fit(X, y)
    assert model.selected_candidate_ == "a"
    again = clone(model).fit(X, y)
    assert again.selected_candidate_ == "a"
    np.testing.assert_array_equal(again.predict(X), model.predict(X))
    trees = BasisChoiceCV(_candidates(), cv=4, rule="one_se", random_state=3)
    a, b = clone(trees).fit(X, y), clone(trees).fit(X, y)
    assert a.selected_candidate_ == b.selected_candidate_
    for name in a.candidate_scores_:
        np.testing.assert_array_equal(a.candidate_scores_[name], b.candidate_scores_[name])


def test_the_mean_of_k_is_the_most_complex() -> None:
    X, y = _data(slope=0.8, seed=1, n=200)
    model = BasisChoiceCV(_candidates(), cv=5, random_state=0, ensemble=2,
                          rule="one_se").fit(X, y)
    assert list(model.candidate_scores_) == ["prior", "ridge", "lightgbm", "mean of 2"]
    assert model.selected_candidate_ == choose(
        {n: s for n, s in model.candidate_scores_.items()}, "one_se")


def test_single_candidate_base_boost_cv_follows_the_rule() -> None:
    X, y = _data(slope=0.03, seed=2)
    booster = dict(_candidates())["ridge"]
    best = BaseBoostCV(booster, cv=5, random_state=0).fit(X, y)
    one_se = BaseBoostCV(booster, cv=5, random_state=0, rule="one_se").fit(X, y)
    assert best.selected_ == "boosted" and one_se.selected_ == "prior"


@pytest.mark.parametrize("rule", ["bogus", "1se", "", None, 1])
def test_bad_rules_are_refused_by_the_parameter_validation(rule) -> None:
    X, y = _data(slope=0.8, seed=1)
    for est in (BasisChoiceCV(_candidates(), rule=rule), BaseBoostCV(rule=rule)):
        with pytest.raises(InvalidParameterError, match="'rule' parameter"):
            est.fit(X, y)


def test_a_candidate_may_not_be_called_prior() -> None:
    X, y = _data(slope=0.8, seed=1)
    with pytest.raises(ValueError, match="'prior' names the prior alone"):
        BasisChoiceCV([("prior", dict(_candidates())["ridge"])]).fit(X, y)


def test_the_family_lists_candidates_simplest_first() -> None:
    from workbench.experiment.families.choices import SIZE_PARAMS, by_complexity
    from workbench.experiment.families.stage import candidate_settings

    settings = dict(basis=["ridge", "lightgbm"], basis_params={"ridge": {}, "lightgbm": {
        "n_estimators": {"low": 10, "high": 400, "log": True},
        "num_leaves": {"low": 4, "high": 63, "log": True}}},
        n_stages=1, loss="squared_error", line_search_loss="absolute_error",
        line_search_penalty=0.0, alpha=0.9, link=["log", "identity"],
        basis_inputs="prior+features", input_transform="standard",
        input_transform_params={}, draws=6)
    listed = candidate_settings(settings, 0)
    ordered = by_complexity(listed, settings)
    assert sorted(n for n, _ in ordered) == sorted(n for n, _ in listed)
    keys = [(c["basis"], c["link"]) for _, c in ordered]
    # ridge before lightgbm; within each, the identity link first even if listed second
    assert keys == [("ridge", "identity"), ("ridge", "log"),
                    *[("lightgbm", "identity")] * 6, *[("lightgbm", "log")] * 6]
    for link in ("identity", "log"):
        sizes = [np.prod([c["basis_params"][k] for k in SIZE_PARAMS]) for _, c in ordered
                 if c["basis"] == "lightgbm" and c["link"] == link]
        assert sizes == sorted(sizes) and len(set(sizes)) > 1


def test_the_config_rule_reaches_the_estimators(tmp_path, google_5q) -> None:
    from workbench.experiment.config import ConfigError
    from workbench.experiment.runs.prepare import load_config

    path = tmp_path / "c.toml"
    path.write_text('[model]\nbasis = ["ridge", "kernel_ridge"]\ninput_transform = "standard"\n'
                    '[selection]\nrule = "one_se"\n')
    cfg = load_config(path)
    assert cfg.family.build(cfg, google_5q).target_estimators["eeig1"].rule == "one_se"
    path.write_text('[model]\nbasis = "ridge"\n')
    cfg = load_config(path)
    assert cfg.selection.rule == "best"  # the default: configs without the key keep theirs
    assert cfg.family.build(cfg, google_5q).target_estimators["eeig1"].rule == "best"
    path.write_text('[selection]\nrule = "simplest"\n')
    with pytest.raises(ConfigError, match="selection.rule = 'simplest'.*'one_se'"):
        load_config(path)


def _result(candidates: dict, selected: list[str], targets: list[str]) -> SimpleNamespace:
    return SimpleNamespace(details={"candidates": candidates}, targets=targets,
                           model=SimpleNamespace(selected=selected,
                                                 extra={"cv_mae_boosted": [0.9] * 3}),
                           prior=SimpleNamespace(cv_mae=[0.81] * 3))


def test_the_lines_about_the_prior() -> None:
    from workbench.experiment.runs.evaluate import choice_lines

    mae = {"prior": 0.81, "ridge": 0.80, "lightgbm#00": 0.9, "mean of 2": float("nan")}
    kept = {"chosen": "prior", "best": "ridge", "rule": "one_se", "cv_mae": mae,
            "se_vs_prior": {"best": 0.03, "chosen": 0.0}}
    lines = choice_lines(_result({"eeig3": kept}, ["prior", "prior"], ["eeig3", "eeig4"]))
    assert lines == ["eeig3: keeps the prior (CV MAE 0.81 vs best candidate ridge 0.8 +- "
                     "0.03: within noise)",
                     "eeig4: keeps the prior (CV MAE 0.81 vs boosted 0.9)"]
    noisy = {**kept, "chosen": "ridge", "rule": "best",
             "se_vs_prior": {"best": 0.03, "chosen": 0.03}}
    lines = choice_lines(_result({"t": noisy}, ["boosted"], ["t"]))
    assert lines[0].startswith("t: CV chose ridge (CV MAE 0.8; prior 0.81); lowest CV MAE")
    assert lines[1] == ("t: its CV gain over the prior is within noise (CV MAE 0.8 vs prior "
                        "0.81 +- 0.03)")
    clear = {**noisy, "se_vs_prior": {"best": 0.003, "chosen": 0.003}}
    assert len(choice_lines(_result({"t": clear}, ["boosted"], ["t"]))) == 1
    simpler = {**noisy, "chosen": "lightgbm#00", "rule": "one_se"}
    assert "the simplest within one SE of the best, ridge 0.8" in \
        choice_lines(_result({"t": simpler}, ["boosted"], ["t"]))[0]
    best_is_prior = {**kept, "best": "prior", "cv_mae": {"prior": 0.7, "ridge": 0.8}}
    assert choice_lines(_result({"t": best_is_prior}, ["prior"], ["t"])) == [
        "t: keeps the prior (CV MAE 0.7; best candidate ridge 0.8)"]
