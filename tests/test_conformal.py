"""ConformalRegressor: coverage on synthetic data, shapes, parameter checks, scikit-learn
conventions, and equality with MAPIE's CV+ on a single target."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.linear_model import LinearRegression, Ridge
from sklearn.model_selection import KFold, ShuffleSplit
from sklearn.utils.estimator_checks import parametrize_with_checks

from workbench.conformal import (
    ConformalRegressor,
    conformal_rank,
    interval_coverage,
    interval_width,
)


def _data(seed: int, n: int, n_targets: int = 2, noise=(1.0, 3.0)):
    """Two linear targets with different noise levels (so their widths differ)."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 3))
    coefs = np.array([[1.0, 0.0], [2.0, 1.0], [3.0, 0.0]])[:, :n_targets]
    return X, X @ coefs + rng.normal(size=(n, n_targets)) * np.asarray(noise[:n_targets])


@parametrize_with_checks([ConformalRegressor(Ridge(), cv=3),
                          ConformalRegressor(Ridge(), method="split", alpha=0.3,
                                             calibration_fraction=0.5)])
def test_sklearn_compatible(estimator, check):
    check(estimator)


@pytest.mark.parametrize("method", ["cv_plus", "cv", "split"])
def test_coverage_near_nominal_over_seeds(method):
    """90% intervals: over 20 seeds (100 training rows, 1000 new rows each) the average
    coverage of each target is within 0.87-0.95 (the split's exact expected coverage with
    25 calibration rows is 24/26 = 0.923), and the noisier target gets the wider interval."""
    cover, width = [], []
    for seed in range(20):
        X, Y = _data(seed, 1100)
        model = ConformalRegressor(LinearRegression(), method=method, alpha=0.1,
                                   random_state=seed).fit(X[:100], Y[:100])
        iv = model.predict_interval(X[100:])
        cover.append(interval_coverage(Y[100:], iv))
        width.append(interval_width(iv))
    cover = np.mean(cover, axis=0)
    assert np.all((cover > 0.87) & (cover < 0.95)), cover
    w = np.mean(width, axis=0)
    # noise sd 1 and 3: the 90% interval of a Gaussian is about 2 * 1.645 * sd
    assert 2.9 < w[0] < 4.5 and 8.8 < w[1] < 13.5, w


def test_higher_level_gives_wider_intervals_and_more_coverage():
    X, Y = _data(0, 1100)
    iv = {a: ConformalRegressor(LinearRegression(), alpha=a, random_state=0)
          .fit(X[:200], Y[:200]).predict_interval(X[200:]) for a in (0.05, 0.2)}
    assert np.all(np.asarray(interval_width(iv[0.05])) > interval_width(iv[0.2]))
    assert np.all(np.asarray(interval_coverage(Y[200:], iv[0.05]))
                  > interval_coverage(Y[200:], iv[0.2]))


def test_cv_coverage_estimate_is_near_nominal():
    """The fit's own cross-validated coverage (no refit) is near 1 - alpha, and its width
    near the width of the intervals on new rows."""
    X, Y = _data(3, 1400)
    for method in ("cv_plus", "split"):
        model = ConformalRegressor(LinearRegression(), method=method,
                                   random_state=0).fit(X[:400], Y[:400])
        cover, width = model.cv_coverage()
        assert np.all(np.abs(np.asarray(cover) - 0.9) < 0.04), (method, cover)
        new = interval_width(model.predict_interval(X[400:]))
        assert np.allclose(width, new, rtol=0.15), (method, width, new)


def test_split_cv_coverage_is_leave_one_out_over_the_calibration_rows():
    X, Y = _data(1, 120, n_targets=1)
    model = ConformalRegressor(LinearRegression(), method="split", alpha=0.2,
                               random_state=0).fit(X, Y[:, 0])
    R = model.residuals_[model.fold_of_row_ >= 0, 0]
    k = conformal_rank(len(R) - 1, 0.2)
    covered, widths = [], []
    for i in range(len(R)):
        q = np.sort(np.delete(R, i))[k - 1]
        covered.append(R[i] <= q)
        widths.append(2 * q)
    cover, width = model.cv_coverage()
    assert cover == pytest.approx([np.mean(covered)])
    assert width == pytest.approx([np.mean(widths)])


def test_cv_is_the_full_model_plus_minus_the_residual_quantile():
    """method="cv": the model on all rows +- the ceil((1-alpha)(n+1))-th smallest out-of-fold
    residual per target (the same folds and residuals as CV+); the CV estimate is CV+'s."""
    X, Y = _data(4, 70)
    cv = KFold(5, shuffle=True, random_state=2)
    model = ConformalRegressor(Ridge(), method="cv", cv=cv, alpha=0.2).fit(X[:50], Y[:50])
    plus = ConformalRegressor(Ridge(), cv=cv, alpha=0.2).fit(X[:50], Y[:50])
    np.testing.assert_array_equal(model.residuals_, plus.residuals_)
    assert model.cv_coverage() == plus.cv_coverage()
    r = np.zeros((50, 2))
    for train, val in cv.split(X[:50]):
        r[val] = np.abs(Y[:50][val] - Ridge().fit(X[:50][train], Y[:50][train]).predict(
            X[:50][val]))
    q = np.sort(r, axis=0)[int(np.ceil(0.8 * 51)) - 1]
    mu = Ridge().fit(X[:50], Y[:50]).predict(X[50:])
    iv = model.predict_interval(X[50:])
    np.testing.assert_allclose(iv[..., 0], mu - q, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(iv[..., 1], mu + q, rtol=1e-12, atol=1e-12)


def test_cv_plus_matches_the_formula_by_hand():
    """Lower bound: the floor(alpha (n+1))-th smallest of mu_{-k(i)}(x) - R_i; upper: the
    ceil((1-alpha)(n+1))-th smallest of mu_{-k(i)}(x) + R_i (Barber et al. 2021)."""
    X, Y = _data(2, 60)
    cv = KFold(4, shuffle=True, random_state=1)
    model = ConformalRegressor(Ridge(), cv=cv, alpha=0.15).fit(X[:45], Y[:45])
    iv = model.predict_interval(X[45:])
    n = 45
    for j in range(2):
        for row in range(15):
            lo, hi = [], []
            for train, val in cv.split(X[:45]):
                fold = Ridge().fit(X[:45][train], Y[:45][train])
                mu = fold.predict(X[45 + row:46 + row])[0, j]
                r = np.abs(Y[:45][val, j] - fold.predict(X[:45][val])[:, j])
                lo += list(mu - r)
                hi += list(mu + r)
            lower = np.sort(lo)[int(np.floor(0.15 * (n + 1))) - 1]
            upper = np.sort(hi)[int(np.ceil(0.85 * (n + 1))) - 1]
            assert iv[row, j] == pytest.approx([lower, upper], rel=1e-12, abs=1e-12)


def test_equals_mapie_cross_conformal_plus_on_one_target():
    mapie = pytest.importorskip("mapie.regression")
    X, Y = _data(4, 130, n_targets=1)
    X_train, y_train, X_new = X[:100], Y[:100, 0], X[100:]
    cv = KFold(5, shuffle=True, random_state=0)
    for alpha in (0.1, 0.25):
        ours = ConformalRegressor(Ridge(alpha=2.0), cv=cv, alpha=alpha).fit(X_train, y_train)
        theirs = mapie.CrossConformalRegressor(Ridge(alpha=2.0), confidence_level=1 - alpha,
                                               cv=cv, method="plus")
        _, intervals = theirs.fit_conformalize(X_train, y_train).predict_interval(X_new)
        iv = ours.predict_interval(X_new)
        np.testing.assert_allclose(iv[:, 0, 0], intervals[:, 0, 0], rtol=1e-12, atol=1e-10)
        np.testing.assert_allclose(iv[:, 0, 1], intervals[:, 1, 0], rtol=1e-12, atol=1e-10)


def test_shapes_names_and_point_predictions_unchanged():
    X, Y = _data(5, 80)
    frame = pd.DataFrame(X, columns=["a", "b", "c"], index=[f"r{i}" for i in range(80)])
    Yf = pd.DataFrame(Y, columns=["E1", "E2"], index=frame.index)
    model = ConformalRegressor(LinearRegression(), cv=4, random_state=0).fit(frame, Yf)
    assert model.target_names_ == ["E1", "E2"] and model.n_targets_ == 2
    assert model.predict_interval(frame.iloc[:7]).shape == (7, 2, 2)
    direct = LinearRegression().fit(frame, Yf).predict(frame)
    np.testing.assert_array_equal(model.predict(frame), direct)
    out = model.predict_frame(frame.iloc[:3])
    assert list(out.columns) == ["E1", "E2", "E1_lower", "E1_upper", "E2_lower", "E2_upper"]
    assert list(out.index) == ["r0", "r1", "r2"]
    assert np.all(out["E1_lower"] <= out["E1_upper"])
    one = ConformalRegressor(LinearRegression(), cv=4).fit(X, pd.Series(Y[:, 0], name="E"))
    assert one.predict_interval(X[:5]).shape == (5, 1, 2) and one.target_names_ == ["E"]
    assert one.predict(X[:5]).shape == (5,)
    assert ConformalRegressor(Ridge(), cv=3).fit(X, Y).target_names_ == ["y0", "y1"]


def test_same_seed_same_intervals():
    X, Y = _data(6, 90)
    a, b = (ConformalRegressor(Ridge(), random_state=7).fit(X, Y).predict_interval(X[:9])
            for _ in range(2))
    np.testing.assert_array_equal(a, b)
    c = ConformalRegressor(Ridge(), random_state=8).fit(X, Y).predict_interval(X[:9])
    assert not np.array_equal(a, c)


def test_clone_and_get_params():
    model = ConformalRegressor(Ridge(alpha=3.0), method="split", alpha=0.2,
                               calibration_fraction=0.3, random_state=1)
    copy = clone(model)
    assert copy.get_params(deep=False) == {**model.get_params(deep=False),
                                           "estimator": copy.estimator}
    assert copy.get_params()["estimator__alpha"] == 3.0
    copy.set_params(estimator__alpha=5.0, alpha=0.05)
    assert copy.estimator.alpha == 5.0 and copy.alpha == 0.05 and model.alpha == 0.2


@pytest.mark.parametrize("params, pattern", [
    ({"alpha": 0}, r"'alpha' parameter of ConformalRegressor must be a float in the range "
                 r"\(0\.0, 1\.0\)\. Got 0 instead"),
    ({"alpha": 1.0}, "'alpha' parameter .* Got 1.0"),
    ({"alpha": -0.1}, "'alpha' parameter .* Got -0.1"),
    ({"alpha": "0.1"}, "'alpha' parameter .* Got '0.1'"),
    ({"alpha": True}, "'alpha' parameter .* Got True"),
    ({"method": "jackknife"}, r"'method' parameter of ConformalRegressor must be a str among "
                             r"\{('(cv_plus|cv|split|oof)'(, )?){4}\}\. Got 'jackknife'"),
    ({"method": "split", "calibration_fraction": 1.5},
     r"'calibration_fraction' parameter .* range \(0\.0, 1\.0\)\. Got 1.5"),
    ({"cv": 1}, r"'cv' parameter of ConformalRegressor must be an int in the range \[2, inf\)"),
    ({"estimator": None}, "'estimator' parameter .* implementing 'fit' and 'predict'. Got None"),
    ({"alpha": 0.01}, r"alpha=0.01: 60 calibration rows are too few for 99% intervals "
                      r"\(at least 99 needed\)"),
    ({"cv": ShuffleSplit(3, random_state=0)}, "at most one validation fold"),
])
def test_bad_parameters_raise_one_clear_error(params, pattern):
    X, Y = _data(7, 60)
    with pytest.raises(ValueError, match=pattern):
        ConformalRegressor(**{"estimator": Ridge(), **params}).fit(X, Y)


def test_conformal_rank_is_exact_at_integer_levels():
    assert conformal_rank(19, 0.1) == 18  # (0.9 * 20 = 18.000000000000004 in floating point)
    assert conformal_rank(95, 0.1) == 87
    assert conformal_rank(8, 0.1) == 9  # > 8: too few rows


class _Opaque(RegressorMixin, BaseEstimator):
    """``estimator`` behind a plain ``fit``: no ``_fit_plan`` to run as tasks."""

    def __init__(self, estimator=None):
        self.estimator = estimator

    def fit(self, X, Y):
        self.model_ = clone(self.estimator).fit(X, Y)
        return self

    def predict(self, X):
        return self.model_.predict(X)


def test_fold_models_as_plans_give_the_sequential_numbers():
    """With an estimator that splits its fit into tasks (MultiTargetBaseBoost of
    BaseBoostCV), the fold models and the model on all rows run as plans on shared worker
    processes: the same intervals and point predictions as fitting them one by one, for
    any n_jobs."""
    from workbench import BaseBoostCV, BaseBoostRegressor, MultiTargetBaseBoost

    X, Y = _data(3, 80)
    X = np.column_stack([X, X @ np.array([[1.0, 0.5], [2.0, 1.0], [3.0, 0.0]]) * 0.9])
    booster = BaseBoostCV(BaseBoostRegressor(basis=Ridge(alpha=1.0), n_stages=1), cv=3)
    multi = MultiTargetBaseBoost(booster, priors=[3, 4], random_state=0)

    opaque = _Opaque(multi)  # the same model without its plan: fitted one by one
    assert not hasattr(opaque, "_fit_plan")
    ref = ConformalRegressor(opaque, random_state=1).fit(X, Y)
    for n_jobs in (1, 2):
        got = ConformalRegressor(multi, random_state=1, n_jobs=n_jobs).fit(X, Y)
        np.testing.assert_array_equal(got.predict_interval(X[:10]),
                                      ref.predict_interval(X[:10]))
        np.testing.assert_array_equal(got.residuals_, ref.residuals_)
        np.testing.assert_array_equal(np.asarray(got.predict(X[:10])),
                                      np.asarray(ref.predict(X[:10])))
        assert ([m.selected_ for m in got.estimators_]
                == [m.model_.selected_ for m in ref.estimators_])


# ---------------------------------------------------------------------- method="oof"

def _boost_cv(cv=5):
    """A BaseBoostCV from the mean (prior=None) with a ridge basis: it keeps out-of-fold
    predictions of what it selected."""
    from workbench import BaseBoostCV, BaseBoostRegressor

    return BaseBoostCV(BaseBoostRegressor(prior=None, basis=Ridge(alpha=1.0), n_stages=1,
                                          line_search_penalty=0.0), cv=cv)


def test_oof_is_the_model_plus_minus_its_own_out_of_fold_residual_quantile():
    """method="oof": one fit (the model on all rows, whose predictions are unchanged), and
    per target mu(x) +- the ceil((1-alpha)(n+1))-th smallest |y - cv_predictions_|."""
    X, Y = _data(3, 80, n_targets=1)
    y = Y[:, 0]
    model = ConformalRegressor(_boost_cv(), method="oof", alpha=0.2).fit(X[:60], y[:60])
    plain = clone(_boost_cv()).fit(X[:60], y[:60])
    np.testing.assert_array_equal(model.predict(X[60:]), plain.predict(X[60:]))
    assert model.estimators_ == []
    R = np.sort(np.abs(y[:60] - plain.cv_predictions_))
    q = R[conformal_rank(60, 0.2) - 1]
    iv = model.predict_interval(X[60:])
    np.testing.assert_allclose(iv[:, 0, 0], plain.predict(X[60:]) - q)
    np.testing.assert_allclose(iv[:, 0, 1], plain.predict(X[60:]) + q)
    np.testing.assert_array_equal(model.fold_of_row_[:, 0], plain.cv_folds_)


def test_oof_coverage_near_nominal_over_seeds():
    """90% "oof" intervals of a multi-target BaseBoostCV: over 20 seeds (100 training rows,
    1000 new rows each) the average coverage of each target is within 0.87-0.95, each target
    with its own quantile, and the CV estimate is near nominal too."""
    from workbench import MultiTargetBaseBoost

    cover, cv_cover = [], []
    for seed in range(20):
        X, Y = _data(seed, 1100)
        model = ConformalRegressor(MultiTargetBaseBoost(_boost_cv()), method="oof",
                                   alpha=0.1).fit(X[:100], Y[:100])
        cover.append(interval_coverage(Y[100:], model.predict_interval(X[100:])))
        cv_cover.append(model.cv_coverage()[0])
    cover, cv_cover = np.mean(cover, axis=0), np.mean(cv_cover, axis=0)
    assert np.all((cover > 0.87) & (cover < 0.95)), cover
    assert np.all((cv_cover > 0.85) & (cv_cover < 0.95)), cv_cover


def test_oof_needs_a_model_with_its_own_out_of_fold_predictions():
    X, Y = _data(0, 60)
    with pytest.raises(ValueError, match=r"method='oof' needs an estimator that keeps its own "
                                         r"out-of-fold predictions.*Ridge"):
        ConformalRegressor(Ridge(), method="oof").fit(X, Y)
