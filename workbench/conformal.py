"""Conformal prediction intervals for multi-output regressors.

:class:`ConformalRegressor` wraps any scikit-learn regressor whose ``predict`` returns one
column per target (or a 1-D array for one target) and adds :meth:`~ConformalRegressor.
predict_interval`, intervals that cover a new row's target with probability about
``1 - alpha`` per target (marginally over rows, not jointly over targets), under the one
assumption that training and new rows are exchangeable.

Four methods:

* ``"oof"`` -- the model's own out-of-fold residuals: no extra fit. A model that
  cross-validates itself to make its choices (:class:`~workbench.BaseBoostCV` and
  :class:`~workbench.BasisChoiceCV` per target, a :class:`~workbench.MultiTargetBaseBoost` of
  them, :class:`~workbench.fitted_prior.FittedPriorBoost`) keeps the out-of-fold predictions
  of what it selected (``cv_predictions_``, with ``cv_folds_``); the interval is
  ``mu(x) +- q`` around the point prediction of the model on all rows, ``q`` per target the
  ``ceil((1 - alpha)(n + 1))``-th smallest out-of-fold absolute residual, as ``"cv"`` below
  but with the residuals the fit already computed. An approximation with no finite-sample
  guarantee: the choices behind those predictions (prior or boosted, the basis, a physics
  model's covariates) were made on all rows, the held-out ones included, which makes the
  residuals slightly optimistic; the fold models saw fewer rows than the model on all rows,
  which makes them pessimistic. Its coverage is measured on simulated devices
  (``benchmarks/intervals.py``).
* ``"cv_plus"`` -- CV+ (Barber, Candes, Ramdas and Tibshirani, "Predictive inference with the
  jackknife+", Ann. Statist. 49(1), 2021; with ``cv`` = leave-one-out it is the jackknife+).
  The rows are split into K folds; the model is refitted once per fold without the fold's
  rows, and each training row ``i`` gets its out-of-fold absolute residual
  ``R_i = |y_i - mu_{-k(i)}(x_i)|``. For a new row ``x`` and ``n`` training rows::

      lower(x) = the floor(alpha (n + 1))-th smallest of  mu_{-k(i)}(x) - R_i
      upper(x) = the ceil((1 - alpha)(n + 1))-th smallest of  mu_{-k(i)}(x) + R_i

  per target. Guaranteed coverage is ``1 - 2 alpha - O(1/sqrt(n/K))``; in practice it is
  close to ``1 - alpha`` for a stable model, and above it when the fold models disagree at
  ``x`` (e.g. a per-fold choice of basis or covariates): their spread widens the interval
  beyond ``+- q``. These are the intervals of MAPIE 1.x's
  ``CrossConformalRegressor(method="plus")`` (tests/test_conformal.py checks equality).
* ``"cv"`` -- cross-conformal with the model on all rows (Vovk's cross-conformal
  predictor; MAPIE's ``method="base"``, its "CV" in Barber et al.): the same fold models
  and out-of-fold residuals as CV+, and the interval ``mu(x) +- q`` per target around the
  point prediction of ``estimator_``, ``q`` the ``ceil((1 - alpha)(n + 1))``-th smallest
  ``R_i``. No finite-sample guarantee (the model on all rows is not the one the residuals
  were measured on: it saw more rows, so ``q`` tends to be pessimistic), but the fold
  models' disagreement at ``x`` does not widen it: for models whose folds make their own
  choices (a covariate selection, a basis chosen by CV), CV+ is conservative and this is
  close to nominal. Centred on the point prediction.
* ``"split"`` -- split conformal: the model is fitted on a ``1 - calibration_fraction`` part
  of the rows, the absolute residuals on the rest give per target ``q`` = the
  ``ceil((1 - alpha)(m + 1))``-th smallest of the ``m`` calibration residuals, and the
  interval is ``mu_split(x) +- q``. Exact finite-sample coverage ``>= 1 - alpha``; one extra
  fit, but fewer rows for both the model and the calibration.

Point predictions (:meth:`~ConformalRegressor.predict`) are always those of ``estimator_``,
the estimator fitted on all rows, exactly as without the wrapper. The intervals are built from
the fold (or split) models, as the methods require: an interval need not be centred on the
point prediction, and in rare cases may not contain it.

Why not MAPIE or crepes: both take one target per estimator (MAPIE 1.x checks
``y`` with ``_check_y(y, multi_output=False)`` and rejects a 2-D ``y``; multi-output
regression is an open request, scikit-learn-contrib/MAPIE issues #97 and #437; crepes
calibrates one residual vector). The workbench's models predict all targets jointly (the
parameter-space model shares its Hamiltonian parameters across the eigenvalues), so wrapping
each target would refit the whole joint model once per target and fold (5 targets: 5 times
the work). Here the K fold models are fitted once and serve every target; the per-target
formula is MAPIE's.
"""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Any, Self

import numpy as np
import pandas as pd
import scipy.sparse as sp
from numpy.typing import ArrayLike
from sklearn.base import BaseEstimator, MetaEstimatorMixin, RegressorMixin, clone
from sklearn.model_selection import KFold, check_cv, train_test_split
from sklearn.utils import _safe_indexing, get_tags
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from .parallel import run_plans

__all__ = ["ConformalRegressor", "conformal_rank", "interval_coverage", "interval_width"]

#: ``method`` values.
METHODS = ("cv_plus", "cv", "split", "oof")
#: Test rows per block when CV+ bounds are computed (bounds the memory to about
#: ``n_train * block * n_targets`` floats).
_BLOCK = 256


def conformal_rank(n: int, alpha: float) -> int:
    """The rank ``ceil((1 - alpha)(n + 1))`` of the conformal quantile among ``n``
    calibration values (1-based); larger than ``n`` when ``n`` is too small for ``alpha``.

    Parameters
    ----------
    n : int
        The number of calibration values.
    alpha : float
        The miscoverage level.

    Returns
    -------
    int
        The rank.
    """
    # round first so that e.g. (1 - 0.1) * 20 = 18.000000000000004 is not ceiled to 19
    return int(math.ceil(round((1.0 - alpha) * (n + 1), 9)))


def min_calibration_rows(alpha: float) -> int:
    """Count the fewest calibration values with a finite conformal quantile at ``alpha``.

    Parameters
    ----------
    alpha : float
        The miscoverage, in (0, 1).

    Returns
    -------
    int
        The smallest ``n`` with ``ceil((1 - alpha) (n + 1)) <= n``.
    """
    # ceil((1 - alpha)(n + 1)) <= n  <=>  alpha (n + 1) >= 1
    n = max(1, int(math.ceil(round(1.0 / alpha - 1.0, 9))))
    while conformal_rank(n, alpha) > n:  # floating-point guard
        n += 1
    return n


def _rows(data: Any, index: ArrayLike) -> Any:
    """Rows ``index`` (positions) of an array, sparse matrix, DataFrame or Series."""
    return _safe_indexing(data, index)


def _n_rows(data: Any) -> int:
    shape = getattr(data, "shape", None)
    return int(shape[0]) if shape is not None else len(np.asarray(data))


def _as_2d(values: ArrayLike) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    return arr.reshape(-1, 1) if arr.ndim == 1 else arr


def _kth_smallest(values: np.ndarray, k: int) -> np.ndarray:
    """The ``k``-th smallest (1-based) along axis 0."""
    return np.partition(values, k - 1, axis=0)[k - 1]


def interval_coverage(y: ArrayLike, intervals: ArrayLike) -> list[float]:
    """Per target, the fraction of rows whose ``y`` lies in ``[lower, upper]`` (``intervals``
    as returned by :meth:`ConformalRegressor.predict_interval`).

    Parameters
    ----------
    y : array-like of shape (n_samples, n_targets)
        The measured values.
    intervals : array-like of shape (n_samples, n_targets, 2)
        The lower and upper bounds.

    Returns
    -------
    list of float
        The coverage per target.
    """
    y = _as_2d(y)
    iv = np.asarray(intervals, dtype=float)
    inside = (y >= iv[..., 0]) & (y <= iv[..., 1])
    return np.mean(inside, axis=0).tolist()


def interval_width(intervals: ArrayLike) -> list[float]:
    """Per target, the mean width ``upper - lower``.

    Parameters
    ----------
    intervals : array-like of shape (n_samples, n_targets, 2)
        The lower and upper bounds (:meth:`ConformalRegressor.predict_interval`).

    Returns
    -------
    list of float
        The mean width per target.
    """
    iv = np.asarray(intervals, dtype=float)
    return np.mean(iv[..., 1] - iv[..., 0], axis=0).tolist()


class ConformalRegressor(MetaEstimatorMixin, RegressorMixin, BaseEstimator):
    """Conformal prediction intervals (CV+ or split) around any multi-output regressor.

    Parameters
    ----------
    estimator : regressor
        Cloned and fitted on all rows (``estimator_``, the point predictions) and on each
        fold's (or the split's) training rows (the intervals). ``predict`` may return a 1-D
        array (one target), a 2-D array or a DataFrame with one column per target.
    method : {"cv_plus", "cv", "split", "oof"}, default="cv_plus"
        ``"oof"`` needs an estimator whose fitted form has ``cv_predictions_`` (and
        ``cv_folds_``), its own out-of-fold predictions; it fits nothing but the model on
        all rows.
    alpha : float in (0, 1), default=0.1
        Miscoverage: ``1 - alpha`` intervals (0.1: 90%).
    cv : int or CV splitter, default=5
        CV+ (and ``"cv"``) folds; an int means ``KFold(cv, shuffle=True,
        random_state=random_state)``.
    calibration_fraction : float in (0, 1), default=0.25
        The share of the rows held out for calibration (``method="split"``).
    random_state : int, RandomState or None
        The folds' shuffle (an int ``cv``) and the split.
    n_jobs : int, default=None
        Processes (``-1``: every core) for the fold models and the model on all rows when
        the estimator splits its fit into tasks (a ``_fit_plan``, as
        :class:`~workbench.MultiTargetBaseBoost` and :class:`~workbench.BaseBoostCV`): all
        of their tasks share the processes (:mod:`workbench.parallel`). Otherwise the
        models are fitted one after another, each with its own ``n_jobs``. ``None``: the
        estimator's own ``n_jobs`` parameter, if it has one. The result does not depend on
        it.

    Attributes
    ----------
    estimator_ : the estimator fitted on all rows
    estimators_ : list, the fold models (``"cv_plus"``, ``"cv"``), the one split model
        (``"split"``) or none (``"oof"``)
    fold_of_row_ : ndarray (n_rows,), per training row the index in ``estimators_`` of the
        model that did not see it (-1: a row of the split's training part); for ``"oof"``
        the estimator's ``cv_folds_``, shape ``(n_rows, n_targets)``
    residuals_ : ndarray (n_rows, n_targets), out-of-fold absolute residuals (NaN for rows
        of the split's training part)
    target_names_ : list of str, the targets in the order of the intervals' second axis (the
        columns of ``y``; ``y0, y1, ...`` for an array, the Series name for a named Series)
    n_targets_ : int
    """

    _parameter_constraints: dict = {
        "estimator": [HasMethods(["fit", "predict"])],
        "method": [StrOptions(set(METHODS))],
        "alpha": [Interval(Real, 0, 1, closed="neither")],
        "cv": ["cv_object"],
        "calibration_fraction": [Interval(Real, 0, 1, closed="neither")],
        "random_state": ["random_state"],
        "n_jobs": [Integral, None],
    }

    def __init__(self, estimator: Any = None, *, method: str = "cv_plus", alpha: float = 0.1,
                 cv: Any = 5, calibration_fraction: float = 0.25,
                 random_state: int | np.random.RandomState | None = None,
                 n_jobs: int | None = None) -> None:
        self.estimator = estimator
        self.method = method
        self.alpha = alpha
        self.cv = cv
        self.calibration_fraction = calibration_fraction
        self.random_state = random_state
        self.n_jobs = n_jobs

    # ------------------------------------------------------------------ checks
    def _check_params(self, n_rows: int) -> None:
        self._validate_params()  # each value against _parameter_constraints
        if self.method != "split" and isinstance(self.cv, Integral):
            if int(self.cv) > n_rows:
                raise ValueError(f"cv={self.cv} folds need at least {self.cv} rows; got "
                                 f"n_samples={n_rows}")

    def _splitter(self) -> Any:
        if isinstance(self.cv, Integral) and not isinstance(self.cv, bool):
            return KFold(int(self.cv), shuffle=True, random_state=self.random_state)
        return check_cv(self.cv)

    # ------------------------------------------------------------------ fit
    def fit(self, X: Any, y: Any) -> Self:
        """Fit ``estimator_`` on all rows, then the fold (or split) models, and keep the
        out-of-fold absolute residuals.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The training inputs.
        y : array-like of shape (n_samples,) or (n_samples, n_targets)
            The targets.

        Returns
        -------
        self
            The fitted wrapper.
        """
        if y is None:
            raise ValueError(f"{type(self).__name__} requires y to be passed, but the target "
                             "y is None")
        if sp.issparse(X):
            X = X.tocsr()  # row-indexable
        elif not hasattr(X, "__getitem__"):
            X = np.asarray(X)
        if not hasattr(y, "__getitem__"):
            y = np.asarray(y)
        n = _n_rows(X)
        self._check_params(n)
        if _n_rows(y) != n:
            raise ValueError(f"X has {n} rows but y has {_n_rows(y)}")
        if np.iscomplexobj(np.asarray(y)):
            raise ValueError("Complex data not supported (y)")
        Y = _as_2d(y)
        if Y.ndim != 2 or not np.all(np.isfinite(Y)):
            raise ValueError("y must be 1-D or 2-D (n_samples, n_targets) with finite values")
        if isinstance(y, pd.DataFrame):
            names = [str(c) for c in y.columns]
        elif isinstance(y, pd.Series) and y.name is not None:
            names = [str(y.name)]
        else:
            names = [f"y{j}" for j in range(Y.shape[1])]
        self.target_names_ = names
        self.n_targets_ = Y.shape[1]

        if self.method == "oof":
            return self._fit_oof(X, y, Y)
        if self.method != "split":
            splits = list(self._splitter().split(X, Y))
        else:
            train, cal = train_test_split(np.arange(n), test_size=self.calibration_fraction,
                                          random_state=self.random_state)
            splits = [(np.sort(train), np.sort(cal))]
        fold_of_row = np.full(n, -1, dtype=int)
        for k, (_, held) in enumerate(splits):
            if np.any(fold_of_row[held] >= 0):
                raise ValueError("cv must put every row in at most one validation fold "
                                 "(e.g. KFold, not ShuffleSplit or RepeatedKFold)")
            fold_of_row[held] = k
        calibrated = fold_of_row >= 0
        if self.method != "split" and not calibrated.all():
            raise ValueError(f"cv left {int((~calibrated).sum())} row(s) out of every "
                             "validation fold; CV+ and cv need each row in exactly one")
        m = int(calibrated.sum())
        if conformal_rank(m, self.alpha) > m:
            raise ValueError(f"alpha={self.alpha}: {m} calibration rows are too few for "
                             f"{1 - self.alpha:.0%} intervals (at least "
                             f"{min_calibration_rows(self.alpha)} needed)")
        # the fold models, then the model on all rows
        data = [(_rows(X, train), _rows(y, train)) for train, _ in splits] + [(X, y)]
        models = [clone(self.estimator) for _ in data]
        if all(hasattr(m, "_fit_plan") for m in models):
            jobs = self.n_jobs if self.n_jobs is not None else getattr(self.estimator,
                                                                       "n_jobs", None)
            fitted = run_plans([m._fit_plan(Xp, yp) for m, (Xp, yp) in zip(models, data)],
                               jobs)
        else:
            fitted = [m.fit(Xp, yp) for m, (Xp, yp) in zip(models, data)]
        residuals = np.full(Y.shape, np.nan)
        for model, (_, held) in zip(fitted, splits):
            residuals[held] = np.abs(Y[held] - self._predict_2d(model, _rows(X, held)))
        self.estimators_ = fitted[:-1]
        self.fold_of_row_ = fold_of_row
        self.residuals_ = residuals
        self.estimator_ = fitted[-1]
        for attr in ("n_features_in_", "feature_names_in_"):
            if hasattr(self.estimator_, attr):
                setattr(self, attr, getattr(self.estimator_, attr))
        return self

    def _fit_oof(self, X: Any, y: Any, Y: np.ndarray) -> Self:
        """``method="oof"``: the model on all rows, and its own out-of-fold residuals."""
        model = clone(self.estimator)
        if hasattr(model, "_fit_plan"):
            jobs = self.n_jobs if self.n_jobs is not None else getattr(self.estimator,
                                                                       "n_jobs", None)
            (fitted,) = run_plans([model._fit_plan(X, y)], jobs)
        else:
            fitted = model.fit(X, y)
        try:
            pred, folds = fitted.cv_predictions_, fitted.cv_folds_
        except AttributeError as exc:
            raise ValueError(f"method='oof' needs an estimator that keeps its own "
                             f"out-of-fold predictions (cv_predictions_ and cv_folds_ after "
                             f"fit, e.g. BaseBoostCV); {type(fitted).__name__}: {exc}; use "
                             f"'cv_plus', 'cv' or 'split'") from None
        pred = _as_2d(pred)
        folds = np.asarray(folds, dtype=int)
        folds = np.repeat(folds[:, None], Y.shape[1], axis=1) if folds.ndim == 1 else folds
        if pred.shape != Y.shape or folds.shape != Y.shape:
            raise ValueError(f"the estimator's out-of-fold predictions have shape "
                             f"{pred.shape} (folds {folds.shape}); expected {Y.shape}")
        residuals = np.abs(Y - pred)
        folds = np.where(np.isfinite(residuals), folds, -1)
        for j in range(Y.shape[1]):
            m = int((folds[:, j] >= 0).sum())
            if conformal_rank(m, self.alpha) > m:
                raise ValueError(f"alpha={self.alpha}: {m} out-of-fold residuals of target "
                                 f"{self.target_names_[j]} are too few for "
                                 f"{1 - self.alpha:.0%} intervals (at least "
                                 f"{min_calibration_rows(self.alpha)} needed)")
        self.estimators_ = []
        self.fold_of_row_ = folds
        self.residuals_ = residuals
        self.estimator_ = fitted
        for attr in ("n_features_in_", "feature_names_in_"):
            if hasattr(fitted, attr):
                setattr(self, attr, getattr(fitted, attr))
        return self

    def _quantiles(self) -> np.ndarray:
        """Per target, the conformal quantile of the calibrated rows' residuals."""
        folds = self.fold_of_row_
        if folds.ndim == 1:
            R = self.residuals_[folds >= 0]
            return _kth_smallest(R, conformal_rank(len(R), self.alpha))
        out = np.empty(self.n_targets_)
        for j in range(self.n_targets_):
            R = self.residuals_[folds[:, j] >= 0, j]
            out[j] = _kth_smallest(R, conformal_rank(len(R), self.alpha))
        return out

    def _predict_2d(self, model: Any, X: Any) -> np.ndarray:
        pred = _as_2d(model.predict(X))
        if pred.shape != (_n_rows(X), self.n_targets_):
            raise ValueError(f"the estimator predicted shape {pred.shape}; expected "
                             f"({_n_rows(X)}, {self.n_targets_}), one column per target")
        return pred

    # ------------------------------------------------------------------ predict
    def predict(self, X: Any) -> Any:
        """The point predictions of ``estimator_`` (same type and columns as without the
        wrapper).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray or pandas.DataFrame
            What ``estimator_.predict`` returns.
        """
        check_is_fitted(self)
        return self.estimator_.predict(X)

    def predict_interval(self, X: Any) -> np.ndarray:
        """Lower and upper bounds, shape ``(n_samples, n_targets, 2)``: ``[..., 0]`` the lower
        and ``[..., 1]`` the upper bound; targets in the order of :attr:`target_names_`
        (also for a 1-D ``y``: ``n_targets`` = 1).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples, n_targets, 2)
            The bounds.
        """
        check_is_fitted(self)
        n_new = _n_rows(X)
        out = np.empty((n_new, self.n_targets_, 2))
        if self.method in ("split", "cv", "oof"):
            q = self._quantiles()
            model = self.estimators_[0] if self.method == "split" else self.estimator_
            mu = self._predict_2d(model, X)
            out[..., 0], out[..., 1] = mu - q, mu + q
            return out
        ok = self.fold_of_row_ >= 0
        R = self.residuals_[ok]
        k = conformal_rank(len(R), self.alpha)
        preds = np.stack([self._predict_2d(m, X) for m in self.estimators_])  # (K, n, T)
        folds = self.fold_of_row_
        for start in range(0, n_new, _BLOCK):
            block = slice(start, min(start + _BLOCK, n_new))
            mu = preds[folds, block]                 # (n_train, n_block, T)
            res = R[:, None, :]
            out[block, :, 0] = -_kth_smallest(res - mu, k)
            out[block, :, 1] = _kth_smallest(mu + res, k)
        return out

    def predict_frame(self, X: Any) -> pd.DataFrame:
        """Point predictions and intervals as one frame (index of ``X`` when it has one):
        a column per target (``target_names_``), then ``<target>_lower`` and
        ``<target>_upper`` for each target.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        pandas.DataFrame
            The point predictions and the bounds.
        """
        point = _as_2d(self.predict(X))
        iv = self.predict_interval(X)
        index = X.index if isinstance(X, pd.DataFrame) else None
        columns: dict[str, np.ndarray] = {t: point[:, j] for j, t in
                                          enumerate(self.target_names_)}
        for j, t in enumerate(self.target_names_):
            columns[f"{t}_lower"] = iv[:, j, 0]
            columns[f"{t}_upper"] = iv[:, j, 1]
        return pd.DataFrame(columns, index=index)

    # ------------------------------------------------------------------ CV estimate
    def cv_coverage(self) -> tuple[list[float], list[float]]:
        """A cross-validated estimate of coverage and mean width per target, from the fit's
        own out-of-fold residuals (no refit).

        ``"cv_plus"``, ``"cv"`` and ``"oof"``: each training row is held out with its fold; its
        interval is its out-of-fold prediction (from the model that did not see it) +- the conformal
        quantile of the *other* folds' out-of-fold residuals. ``"split"``: leave-one-out over the
        calibration rows (each row against the conformal quantile of the others).

        This describes ``"cv"``'s intervals ``+- q`` (around an out-of-fold prediction, not
        the model on all rows); CV+'s own intervals on new rows are wider by the fold models'
        disagreement, so where that is large (unstable inner choices) the estimate is below
        the coverage on new rows.

        Returns
        -------
        coverage : list of float
            Per target, the share of rows inside their interval.
        width : list of float
            Per target, the intervals' mean width.
        """
        check_is_fitted(self)
        if self.fold_of_row_.ndim == 2:  # "oof": each target's own folds
            cover, width = [], []
            for j in range(self.n_targets_):
                ok = self.fold_of_row_[:, j] >= 0
                c, w = self._cv_coverage(self.residuals_[ok, j:j + 1],
                                         self.fold_of_row_[ok, j])
                cover += c
                width += w
            return cover, width
        ok = self.fold_of_row_ >= 0
        return self._cv_coverage(self.residuals_[ok], self.fold_of_row_[ok])

    def _cv_coverage(self, R: np.ndarray, folds: np.ndarray) -> tuple[list[float], list[float]]:
        covered = np.zeros(R.shape, dtype=bool)
        width = np.zeros(R.shape)
        if self.method == "split":
            order = np.sort(R, axis=0)
            k = conformal_rank(len(R) - 1, self.alpha)
            for j in range(R.shape[1]):
                if k > len(R) - 1:  # too few others for a finite quantile
                    q = np.full(len(R), np.inf)
                else:  # the k-th smallest of the others: one further where row i is below it
                    rank = np.searchsorted(order[:, j], R[:, j], side="left")
                    q = np.where(rank < k, order[k, j], order[k - 1, j])
                covered[:, j], width[:, j] = R[:, j] <= q, 2 * q
        else:
            for f in np.unique(folds):
                inside, others = folds == f, R[folds != f]
                k = conformal_rank(len(others), self.alpha)
                q = (_kth_smallest(others, k) if k <= len(others)
                     else np.full(R.shape[1], np.inf))
                covered[inside] = R[inside] <= q
                width[inside] = 2 * q
        return np.mean(covered, axis=0).tolist(), np.mean(width, axis=0).tolist()

    def __sklearn_tags__(self) -> Any:
        """Multi-output, with the wrapped estimator's input tags."""
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        if self.estimator is not None:
            tags.input_tags = get_tags(self.estimator).input_tags
        return tags

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "estimator_")
