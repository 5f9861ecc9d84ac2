"""Multi-target base boosting: one model per target, each with its own prior column."""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, MetaEstimatorMixin, RegressorMixin, clone
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import HasMethods
from sklearn.utils.validation import check_is_fitted

from .boosting import seed_estimator
from .parallel import Plan, Task, gather, run_plans
from .selection import BaseBoostCV

__all__ = ["MultiTargetBaseBoost", "check_targets"]


def check_targets(X: Any, Y: Any) -> tuple[np.ndarray, list[str]]:
    """``Y`` (a DataFrame, or a 2-D array whose targets are named ``y0, y1, ...``) as a float
    array with ``len(X)`` rows, and the target names.

    Parameters
    ----------
    X : array-like
        The inputs (their rows counted).
    Y : array-like of shape (n_samples, n_targets)
        The targets.

    Returns
    -------
    Y : ndarray of shape (n_samples, n_targets)
        The targets as floats.
    names : list of str
        The targets' names.
    """
    if isinstance(Y, pd.DataFrame):
        names = [str(c) for c in Y.columns]
        Y = Y.to_numpy(dtype=float)
    else:
        Y = np.asarray(Y, dtype=float)
        if Y.ndim != 2:
            raise ValueError(f"Y must be 2-D (n_samples, n_targets), got shape {Y.shape}")
        names = [f"y{j}" for j in range(Y.shape[1])]
    if len(X) != len(Y):
        raise ValueError(f"X has {len(X)} rows but Y has {len(Y)}")
    return Y, names


def _set_prior(estimator: Any, prior: Any) -> Any:
    """Set every ``prior`` parameter of ``estimator`` (nested ones too) to ``prior``."""
    keys = [k for k in estimator.get_params(deep=True) if k == "prior" or k.endswith("__prior")]
    if not keys:
        raise ValueError(f"{type(estimator).__name__} has no 'prior' parameter to set")
    return estimator.set_params(**{k: prior for k in keys})


def _fit_one(estimator: Any, X: Any, y: Any) -> Any:
    return estimator.fit(X, y)


def _fit_plan(estimator: Any, X: Any, y: Any) -> Plan:
    """A target's fit as a plan: the estimator's own (folds, refit) when it has one, else one
    task."""
    if hasattr(estimator, "_fit_plan"):
        return (yield from estimator._fit_plan(X, y))
    return (yield [Task(_fit_one, estimator, X, y)])[0]


class MultiTargetBaseBoost(MetaEstimatorMixin, RegressorMixin, BaseEstimator):
    """Fit one base-boosting model per target column; target ``j`` uses prior ``priors[j]``.

    Parameters
    ----------
    estimator : regressor, default=None
        Template for every target (``None``: ``BaseBoostCV()``), cloned per target.
    priors : list, default=None
        One prior per target (a column name or index of ``X``, an estimator or a callable),
        set on every ``prior`` parameter of that target's estimator. ``None`` keeps the
        template's prior.
    target_estimators : dict, default=None
        Per-target overrides of ``estimator``, keyed by target name or position.
    n_jobs : int, default=None
        Processes (``-1``: every core) for the targets' fits and, for estimators that split
        their fit into tasks (:class:`BaseBoostCV`, :class:`BasisChoiceCV`), for every
        target's folds and refit together (:mod:`workbench.parallel`; one BLAS/LightGBM
        thread per process). The result does not depend on it.
    random_state : int, RandomState or None, default=None
        If set, each target's estimator gets its own seed drawn from it.

    Attributes
    ----------
    estimators_ : list of fitted regressors, one per target
    target_names_ : list of str
    """

    _parameter_constraints: dict = {
        "estimator": [None, HasMethods(["fit", "predict"])],
        "priors": [None, list, tuple],
        "target_estimators": [None, dict],
        "n_jobs": [numbers.Integral, None],
        "random_state": ["random_state"],
    }

    def __init__(self, estimator: Any = None, *, priors: Sequence[Any] | None = None,
                 target_estimators: Mapping[Any, Any] | None = None,
                 n_jobs: int | None = None,
                 random_state: int | np.random.RandomState | None = None) -> None:
        self.estimator = estimator
        self.priors = priors
        self.target_estimators = target_estimators
        self.n_jobs = n_jobs
        self.random_state = random_state

    def _estimators_for(self, names: list[str]) -> list:
        n_targets = len(names)
        overrides = dict(self.target_estimators or {})
        unknown = [k for k in overrides if k not in names and k not in range(n_targets)]
        if unknown:
            raise ValueError(f"target_estimators has unknown targets {unknown}; targets are "
                             f"{names}")
        if self.priors is not None and len(self.priors) != n_targets:
            raise ValueError(f"priors has {len(self.priors)} entries but y has {n_targets} "
                             f"targets {names}: give one prior per target")
        rng = check_random_state(self.random_state)
        seeds = rng.randint(np.iinfo(np.int32).max, size=n_targets)
        template = BaseBoostCV() if self.estimator is None else self.estimator
        ests = []
        for j, name in enumerate(names):
            est = clone(overrides.get(name, overrides.get(j, template)))
            if self.priors is not None:
                _set_prior(est, self.priors[j])
            if self.random_state is not None:
                seed_estimator(est, seeds[j])
            ests.append(est)
        return ests

    def fit(self, X: Any, Y: Any) -> Self:
        """Fit each target's estimator on ``(X, Y[:, j])``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs (each target's prior column among them, for column priors).
        Y : array-like of shape (n_samples, n_targets)
            The targets (a DataFrame's column names name them).

        Returns
        -------
        self
            The fitted model.
        """
        return run_plans([self._fit_plan(X, Y)], self.n_jobs)[0]

    def _fit_plan(self, X: Any, Y: Any) -> Plan:
        """:meth:`fit` as a plan (:mod:`workbench.parallel`): every target's folds and refit
        side by side (so several such fits, e.g. conformal fold models, can share the
        worker processes)."""
        self._validate_params()
        Y, names = check_targets(X, Y)
        ests = self._estimators_for(names)
        self.estimators_ = yield from gather([_fit_plan(est, X, Y[:, j])
                                              for j, est in enumerate(ests)])
        self.target_names_ = names
        self.n_features_in_ = X.shape[1]
        if hasattr(X, "columns"):
            self.feature_names_in_ = np.asarray([str(c) for c in X.columns], dtype=object)
        return self

    def predict(self, X: Any) -> pd.DataFrame:
        """Predictions as a DataFrame with one column per target (``X``'s index if any).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        pandas.DataFrame of shape (n_samples, n_targets)
            The predictions.
        """
        check_is_fitted(self)
        pred = np.column_stack([est.predict(X) for est in self.estimators_])
        return pd.DataFrame(pred, columns=self.target_names_, index=getattr(X, "index", None))

    @property
    def selected_(self) -> list[str]:
        """Per target: ``"prior"`` or ``"boosted"`` where the estimator reports it."""
        check_is_fitted(self)
        return [getattr(est, "selected_", "boosted") for est in self.estimators_]

    @property
    def cv_predictions_(self) -> np.ndarray:
        """Out-of-fold predictions of every target's selected model on the training rows,
        shape ``(n_samples, n_targets)``, from the CV each target's estimator ran to make its
        choices (:class:`BaseBoostCV`'s ``cv_predictions_``; NaN where a row was held out by
        no fold). ``AttributeError`` when a target's estimator has none."""
        check_is_fitted(self)
        return np.column_stack([_own_cv(est, "cv_predictions_") for est in self.estimators_])

    @property
    def cv_folds_(self) -> np.ndarray:
        """Per training row and target, the fold that held the row out in that target's CV
        (-1: none), shape ``(n_samples, n_targets)``."""
        check_is_fitted(self)
        return np.column_stack([_own_cv(est, "cv_folds_") for est in self.estimators_])


def _own_cv(estimator: Any, attr: str) -> np.ndarray:
    if not hasattr(estimator, attr):
        raise AttributeError(f"{type(estimator).__name__} has no {attr} (it does not "
                             "cross-validate itself)")
    return np.asarray(getattr(estimator, attr))
