"""BaseBoostCV (prior vs boosted on the same folds; failures never win) and MultiTargetBaseBoost."""

import warnings

import numpy as np
import pandas as pd
import pytest
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.dummy import DummyRegressor
from sklearn.exceptions import FitFailedWarning
from sklearn.linear_model import Ridge
from sklearn.model_selection import KFold
from sklearn.neural_network import MLPRegressor

from workbench import BaseBoostCV, BaseBoostRegressor, MultiTargetBaseBoost, PriorModel, make_basis


class FailingRegressor(RegressorMixin, BaseEstimator):
    def fit(self, X, y):
        raise RuntimeError("basis exploded")

    def predict(self, X):  # pragma: no cover
        raise RuntimeError("never fitted")


class FailsOnSmallData(RegressorMixin, BaseEstimator):
    """Fits on folds of 80 rows but fails on the full 100: a failed refit."""

    def fit(self, X, y):
        if len(X) > 90:
            raise RuntimeError("too many rows")
        self.m_ = Ridge().fit(X, y)
        return self

    def predict(self, X):
        return self.m_.predict(X)


@pytest.fixture
def data():
    rng = np.random.RandomState(0)
    X = rng.normal(size=(100, 3))
    y = 2 * X[:, 0] + X[:, 1] + 0.1 * rng.normal(size=100)
    X[:, 2] = y + 1.0 * X[:, 0] + 0.2 * rng.normal(size=100)  # a prior that misses 1.0 * x0
    return X, y


def test_helpful_basis_is_selected(data):
    X, y = data
    cv = BaseBoostCV(BaseBoostRegressor(prior=2, basis=Ridge())).fit(X, y)
    assert cv.selected_ == "boosted"
    assert cv.cv_scores_prior_.shape == cv.cv_scores_boosted_.shape == (5,)
    assert cv.cv_scores_boosted_.mean() > cv.cv_scores_prior_.mean()
    assert isinstance(cv.best_estimator_, BaseBoostRegressor)
    np.testing.assert_allclose(cv.predict(X), cv.best_estimator_.predict(X))


def test_useless_basis_leaves_the_prior(data):
    X, y = data
    est = BaseBoostRegressor(prior=2, basis=DummyRegressor(strategy="constant", constant=0.0))
    cv = BaseBoostCV(est).fit(X, y)
    assert cv.selected_ == "prior"  # a tie goes to the prior
    np.testing.assert_array_equal(cv.cv_scores_prior_, cv.cv_scores_boosted_)
    np.testing.assert_array_equal(cv.predict(X), X[:, 2])
    assert isinstance(cv.best_estimator_, PriorModel)


def test_failing_basis_never_wins(data):
    X, y = data
    with pytest.warns(FitFailedWarning, match="5 of 5 candidate fits failed.*basis exploded"):
        cv = BaseBoostCV(BaseBoostRegressor(prior=2, basis=FailingRegressor())).fit(X, y)
    assert cv.selected_ == "prior"
    assert np.all(np.isnan(cv.cv_scores_boosted_))
    assert np.all(np.isfinite(cv.cv_scores_prior_))
    assert len(cv.fit_errors_) == 5
    np.testing.assert_array_equal(cv.predict(X), X[:, 2])


def test_failed_refit_falls_back_to_the_prior(data):
    X, y = data
    with pytest.warns(FitFailedWarning, match="refitting the candidate on all rows failed"):
        cv = BaseBoostCV(BaseBoostRegressor(prior=2, basis=FailsOnSmallData())).fit(X, y)
    assert cv.selected_ == "prior"
    np.testing.assert_array_equal(cv.predict(X), X[:, 2])


def test_prior_and_candidate_scored_on_the_same_folds(data):
    X, y = data
    folds = list(KFold(4).split(X))
    cv = BaseBoostCV(BaseBoostRegressor(prior=2, basis=Ridge()), cv=folds).fit(X, y)
    expected_prior = [-np.mean(np.abs(y[te] - X[te, 2])) for _, te in folds]
    np.testing.assert_allclose(cv.cv_scores_prior_, expected_prior)
    expected_boosted = [
        -np.mean(np.abs(y[te] - BaseBoostRegressor(prior=2, basis=Ridge()).fit(X[tr], y[tr])
                        .predict(X[te])))
        for tr, te in folds]
    np.testing.assert_allclose(cv.cv_scores_boosted_, expected_boosted)


def test_out_of_fold_predictions_of_both_models(data):
    X, y = data
    folds = list(KFold(4).split(X))
    cv = BaseBoostCV(BaseBoostRegressor(prior=2, basis=Ridge()), cv=folds).fit(X, y)
    expected = np.empty_like(y)
    for tr, te in folds:
        expected[te] = BaseBoostRegressor(prior=2, basis=Ridge()).fit(X[tr], y[tr]).predict(X[te])
    np.testing.assert_allclose(cv.cv_predictions_boosted_, expected)
    np.testing.assert_array_equal(cv.cv_predictions_prior_, X[:, 2])
    assert cv.selected_ == "boosted" and cv.cv_predictions_ is cv.cv_predictions_boosted_
    # the fold scores are the MAE of these predictions, fold by fold
    np.testing.assert_allclose(
        cv.cv_scores_boosted_, [-np.mean(np.abs(y[te] - expected[te])) for _, te in folds])
    with pytest.warns(FitFailedWarning):
        failed = BaseBoostCV(BaseBoostRegressor(prior=2, basis=FailingRegressor())).fit(X, y)
    assert np.all(np.isnan(failed.cv_predictions_boosted_))
    assert failed.cv_predictions_ is failed.cv_predictions_prior_


def test_refit_false_scores_only(data):
    X, y = data
    cv = BaseBoostCV(BaseBoostRegressor(prior=2, basis=Ridge()), refit=False).fit(X, y)
    assert cv.selected_ == "boosted" and not hasattr(cv, "best_estimator_")
    with pytest.raises(AttributeError, match="refit=False"):
        cv.predict(X)


def test_seeded_cv_is_repeatable(data):
    X, y = data
    mlp = MLPRegressor(hidden_layer_sizes=(4,), solver="lbfgs", max_iter=100)

    def run(seed):
        return BaseBoostCV(BaseBoostRegressor(prior=2, basis=mlp), random_state=seed).fit(X, y)

    a, b = run(3), run(3)
    np.testing.assert_array_equal(a.cv_scores_boosted_, b.cv_scores_boosted_)
    np.testing.assert_array_equal(a.predict(X), b.predict(X))


def test_incumbent_requires_a_prior():
    with pytest.raises(ValueError, match="cannot find the prior of Ridge.*pass incumbent="):
        BaseBoostCV(Ridge()).fit(np.ones((10, 2)), np.arange(10.0))


@pytest.fixture
def multi():
    rng = np.random.RandomState(1)
    V = rng.normal(size=(80, 2))
    Y = pd.DataFrame({"t1": V[:, 0] + V[:, 1], "t2": V[:, 0] - 2 * V[:, 1]})
    X = pd.DataFrame({"v1": V[:, 0], "v2": V[:, 1],
                      "p1": Y["t1"] + 0.5 * V[:, 0], "p2": Y["t2"] - 0.5 * V[:, 1]})
    return X, Y


def test_multitarget_maps_targets_to_prior_columns(multi):
    X, Y = multi
    model = MultiTargetBaseBoost(BaseBoostCV(BaseBoostRegressor(basis=Ridge())),
                                 priors=["p1", "p2"]).fit(X, Y)
    pred = model.predict(X)
    assert isinstance(pred, pd.DataFrame) and list(pred.columns) == ["t1", "t2"]
    assert pred.index.equals(X.index)
    assert [e.best_estimator_.prior for e in model.estimators_] == ["p1", "p2"]
    assert model.selected_ == ["boosted", "boosted"]
    for col, prior in (("t1", "p1"), ("t2", "p2")):
        assert np.mean(np.abs(pred[col] - Y[col])) < np.mean(np.abs(X[prior] - Y[col]))


def test_multitarget_per_target_override(multi):
    X, Y = multi
    useless = BaseBoostCV(BaseBoostRegressor(basis=DummyRegressor(strategy="constant",
                                                                  constant=0.0)))
    model = MultiTargetBaseBoost(BaseBoostCV(BaseBoostRegressor(basis=Ridge())),
                                 priors=["p1", "p2"], target_estimators={"t2": useless})
    model.fit(X, Y)
    assert model.selected_ == ["boosted", "prior"]
    np.testing.assert_array_equal(model.predict(X)["t2"], X["p2"])


def test_multitarget_errors(multi):
    X, Y = multi
    with pytest.raises(ValueError, match=r"priors has 1 entries but y has 2 targets"):
        MultiTargetBaseBoost(priors=["p1"]).fit(X, Y)
    with pytest.raises(ValueError, match=r"unknown targets \['t9'\]"):
        MultiTargetBaseBoost(priors=["p1", "p2"], target_estimators={"t9": Ridge()}).fit(X, Y)
    with pytest.raises(ValueError, match="X has 80 rows but Y has 79"):
        MultiTargetBaseBoost(priors=["p1", "p2"]).fit(X, Y.iloc[:79])
    with pytest.raises(ValueError, match="Ridge has no 'prior' parameter"):
        MultiTargetBaseBoost(Ridge(), priors=["p1", "p2"]).fit(X, Y)


def test_multitarget_parallel_equals_serial(multi):
    X, Y = multi
    base = BaseBoostCV(BaseBoostRegressor(basis=make_basis("mlp", hidden_layer_sizes=[3],
                                                           max_iter=100)))
    serial = MultiTargetBaseBoost(base, priors=["p1", "p2"], random_state=0).fit(X, Y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parallel = MultiTargetBaseBoost(base, priors=["p1", "p2"], random_state=0,
                                        n_jobs=2).fit(X, Y)
    pd.testing.assert_frame_equal(serial.predict(X), parallel.predict(X))


def test_fold_callback_sees_each_fold_and_can_stop_the_fit(data):
    X, y = data
    seen = []
    cv = BaseBoostCV(BaseBoostRegressor(prior=2, basis=Ridge()), cv=4)
    cv.fit(X, y, fold_callback=lambda i, p, b: seen.append((i, p, b)))
    assert [s[0] for s in seen] == [0, 1, 2, 3]
    np.testing.assert_array_equal([s[1] for s in seen], cv.cv_scores_prior_)
    np.testing.assert_array_equal([s[2] for s in seen], cv.cv_scores_boosted_)

    class Stop(Exception):
        pass

    def stop_after_two(i, p, b):
        if i == 1:
            raise Stop

    with pytest.raises(Stop):
        BaseBoostCV(BaseBoostRegressor(prior=2, basis=Ridge()), cv=4).fit(
            X, y, fold_callback=stop_after_two)
