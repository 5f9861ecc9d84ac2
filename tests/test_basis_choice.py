"""BasisChoiceCV: the basis family of a boosting stage chosen by CV, the prior kept unless a
candidate beats it; wired through ``[model] basis = [...]``."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone

from workbench.bases import make_basis
from workbench.boosting import BaseBoostRegressor
from workbench.selection import BaseBoostCV, BasisChoiceCV


def _data(kind: str, n: int = 240, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2, 2, size=(n, 2))
    prior = 3 * x[:, 0]
    if kind == "linear":
        missed = 0.8 * x[:, 1]
    elif kind == "step":
        missed = 1.5 * (x[:, 1] > 0.3)
    else:
        missed = np.zeros(n)
    y = prior + missed + 0.05 * rng.standard_normal(n)
    X = pd.DataFrame({"prior": prior, "x0": x[:, 0], "x1": x[:, 1]})
    return X, y


def _candidates():
    def booster(name, **params):
        return BaseBoostRegressor(prior="prior", basis=make_basis(name, **params),
                                  basis_features=["x0", "x1"], n_stages=1,
                                  line_search_penalty=0.0)
    return [("ridge", booster("ridge", alpha=1e-3)),
            ("lightgbm", booster("lightgbm", n_estimators=60, min_child_samples=5))]


@pytest.mark.parametrize("kind, expected", [("linear", "ridge"), ("step", "lightgbm"),
                                            ("none", None)])
def test_the_basis_that_captures_what_the_prior_misses_wins(kind, expected):
    X, y = _data(kind)
    model = BasisChoiceCV(_candidates(), cv=5, random_state=0).fit(X, y)
    assert model.selected_candidate_ == expected
    assert model.selected_ == ("prior" if expected is None else "boosted")
    # the prior is a candidate too, listed first (the simplest)
    assert list(model.candidate_scores_) == ["prior", "ridge", "lightgbm"]
    np.testing.assert_array_equal(model.candidate_scores_["prior"], model.cv_scores_prior_)
    assert model.best_candidate_ == (expected or "prior")
    if expected is not None:  # the winner's scores are the ones reported
        best = model.candidate_scores_[expected].mean()
        assert best == max(s.mean() for s in model.candidate_scores_.values())
        assert model.cv_score_ == pytest.approx(best)
        assert np.isfinite(model.cv_predictions_).all()
    assert model.predict(X).shape == (len(X),)


def test_same_as_basebooostcv_with_one_candidate_and_seeded():
    X, y = _data("step", seed=1)
    cand = dict(_candidates())["lightgbm"]
    one = BasisChoiceCV([("lightgbm", cand)], cv=4, random_state=3).fit(X, y)
    ref = BaseBoostCV(cand, cv=4, random_state=3).fit(X, y)
    np.testing.assert_array_equal(one.cv_scores_boosted_, ref.cv_scores_boosted_)
    np.testing.assert_array_equal(one.predict(X), ref.predict(X))
    again = clone(one).fit(X, y)
    np.testing.assert_array_equal(again.predict(X), one.predict(X))


def test_a_failing_candidate_is_never_chosen():
    X, y = _data("linear")
    broken = BaseBoostRegressor(prior="prior", basis=make_basis("ridge"),
                                basis_features=["no_such_column"])
    model = BasisChoiceCV([("broken", broken), *_candidates()], cv=3).fit(X, y)
    assert model.selected_candidate_ == "ridge"
    with pytest.raises(ValueError, match="non-empty list"):
        BasisChoiceCV([]).fit(X, y)


def test_nested_params_like_a_pipeline():
    model = BasisChoiceCV(_candidates())
    params = model.get_params(deep=True)
    assert params["ridge__prior"] == "prior" and "lightgbm__basis__n_estimators" in params
    model.set_params(ridge__prior="x0", lightgbm__prior="x0")
    assert all(c.prior == "x0" for _, c in model.candidates)
    assert clone(model).get_params()["ridge__prior"] == "x0"


def test_config_list_of_bases(tmp_path):
    from workbench.experiment.config import ConfigError
    from workbench.experiment.runs.prepare import load_config

    path = tmp_path / "c.toml"
    path.write_text('[model]\nbasis = ["ridge", "lightgbm"]\n'
                    '[model.basis_params.lightgbm]\nn_estimators = 50\n')
    cfg = load_config(path)
    assert cfg.model_for("eeig1")["basis"] == ["ridge", "lightgbm"]
    path.write_text('[model]\nbasis = ["ridge", "lightgbm"]\n'
                    '[model.basis_params.lightgbm]\nn_estimators = 0\n')
    with pytest.raises(ConfigError, match="n_estimators"):
        load_config(path)
    path.write_text('[model]\nbasis = ["ridge", "bogus"]\n')
    with pytest.raises(ConfigError, match="bogus"):
        load_config(path)


def test_config_builds_a_basis_choice_per_target(tmp_path, google_5q):
    from workbench.experiment.runs.prepare import load_config

    path = tmp_path / "c.toml"
    path.write_text('[model]\nbasis = ["ridge", "kernel_ridge"]\ninput_transform = "standard"\n')
    cfg = load_config(path)
    model = cfg.family.build(cfg, google_5q)
    est = model.target_estimators["eeig1"]
    assert isinstance(est, BasisChoiceCV)
    assert [n for n, _ in est.candidates] == ["ridge", "kernel_ridge"]
    assert dict(est.candidates)["ridge"].prior == "peig1"


def test_a_boosted_stage_whose_coefficients_are_all_zero_is_reported_as_the_prior():
    """BaseBoostCV chose boosting by CV, but the refit's line search set every stage's
    coefficient to 0: the model is the prior exactly, and the results say so."""
    from types import SimpleNamespace

    from workbench.experiment.families.stage import stage_scores

    def fitted(selected, coefs):
        return SimpleNamespace(selected_=selected, cv_score_=-1.0,
                               cv_predictions_=np.zeros(4), cv_predictions_prior_=np.zeros(4),
                               cv_scores_prior_=np.ones(2), cv_scores_boosted_=np.ones(2),
                               best_estimator_=SimpleNamespace(coefs_=np.asarray(coefs)))

    cvs = [fitted("boosted", [0.0, 0.0, 0.0]), fitted("boosted", [0.0, 0.4]),
           fitted("prior", [])]
    s = stage_scores(cvs, np.zeros((4, 3)))
    assert s["selected"] == ["prior", "boosted", "prior"]
    assert s["coefs"] == [[0.0, 0.0, 0.0], [0.0, 0.4], []]  # the coefficients stay visible


def _mixed(n=300, seed=0):
    """A correction with a part in x1 and a part in x0, for candidates that see one input
    each (:func:`_halves`): neither has it all, their mean has half of each."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2, 2, size=(n, 2))
    prior = 3 * x[:, 0]
    y = prior + 0.8 * x[:, 1] + 1.2 * (x[:, 0] > 0.5) + 0.05 * rng.standard_normal(n)
    return pd.DataFrame({"prior": prior, "x0": x[:, 0], "x1": x[:, 1]}), y


def _halves():
    def booster(name, column, **params):
        return BaseBoostRegressor(prior="prior", basis=make_basis(name, **params),
                                  basis_features=[column], line_search_penalty=0.0)
    return [("ridge_x1", booster("ridge", "x1", alpha=1e-3)),
            ("trees_x0", booster("lightgbm", "x0", n_estimators=60, min_child_samples=5))]


def test_the_mean_of_the_best_candidates_wins_where_cv_says_it_helps():
    from workbench.selection import CandidateMean

    X, y = _mixed()
    single = BasisChoiceCV(_halves(), cv=5, random_state=0).fit(X, y)
    model = BasisChoiceCV(_halves(), cv=5, random_state=0, ensemble=2).fit(X, y)
    assert model.selected_candidate_ == "mean of 2"
    assert isinstance(model.estimator_, CandidateMean)
    assert list(model.candidate_scores_) == ["prior", "ridge_x1", "trees_x0", "mean of 2"]
    # scored on the shared folds from the members' out-of-fold predictions
    np.testing.assert_allclose(model.cv_score_, model.candidate_scores_["mean of 2"].mean())
    assert model.cv_score_ > single.cv_score_
    assert all(np.isfinite(model.cv_predictions_))
    # every candidate's out-of-fold predictions are kept; the mean's are their mean
    assert set(model.candidate_predictions_) == {"ridge_x1", "trees_x0"}
    np.testing.assert_allclose(
        model.cv_predictions_, np.mean(list(model.candidate_predictions_.values()), axis=0))
    # the refit is the mean of the members refitted on all rows
    mean = model.best_estimator_
    np.testing.assert_allclose(
        mean.predict(X), np.mean([m.predict(X) for m in mean.members_], axis=0))
    np.testing.assert_allclose(mean.predict_correction(X), mean.predict(X) - X["prior"],
                               atol=1e-9)
    assert len(mean.coefs_) == 2
    # where one candidate has it all, the mean does not win
    X, y = _data("linear")
    alone = BasisChoiceCV(_candidates(), cv=5, random_state=0, ensemble=2).fit(X, y)
    assert alone.selected_candidate_ == "ridge"
    assert "mean of 2" in alone.candidate_scores_
    with pytest.raises(ValueError, match="scoring name"):
        BasisChoiceCV(_candidates(), cv=5, ensemble=2,
                      scoring=lambda est, X, y: 0.0).fit(X, y)


def test_the_mean_of_candidates_has_their_prior():
    """``find_prior`` of a CandidateMean is its members' common prior (equal, not the same
    object: a clone copies it), so its learning curve and a BaseBoostCV of it find their
    incumbent; members with different priors, or none, are an error."""
    from sklearn.model_selection import KFold

    from workbench.curves import augmented_learning_curve
    from workbench.selection import CandidateMean, find_prior

    X, y = _mixed(n=120)
    mean = clone(CandidateMean(_halves()))
    assert find_prior(mean) == "prior"
    folds = KFold(5)
    curve = augmented_learning_curve(mean, X, y, train_sizes=[40, 96], cv=folds,
                                     random_state=0)
    assert np.isfinite(curve.cv_error).all() and not curve.fit_errors
    # the incumbent is the prior alone: its error is the prior column's on each fold
    prior_mae = [np.mean(np.abs(y[test] - X["prior"].to_numpy()[test]))
                 for _, test in folds.split(X)]
    np.testing.assert_allclose(curve.incumbent_error, [prior_mae] * 2)
    members = _halves()
    members[1][1].set_params(prior="x0")
    with pytest.raises(ValueError, match=r"CandidateMean \(2 different nested 'prior'"):
        find_prior(CandidateMean(members))
    with pytest.raises(ValueError, match=r"CandidateMean \(no nested 'prior'"):
        find_prior(CandidateMean([("a", make_basis("ridge"))]))
