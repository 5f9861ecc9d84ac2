"""Heterogeneous stages: each stage's basis chosen by cross-validation on its own residuals."""

from __future__ import annotations

from numbers import Integral
from typing import Any, Self

import numpy as np
from sklearn.base import RegressorMixin, clone
from sklearn.model_selection import KFold, cross_val_predict
from sklearn.utils._param_validation import Interval
from sklearn.utils.metaestimators import _BaseComposition
from sklearn.utils.validation import check_is_fitted, validate_data

from .boosting import CachedParamNames

__all__ = ["StageChoiceCV"]


class StageChoiceCV(CachedParamNames, RegressorMixin, _BaseComposition):
    """A basis that chooses, each time it is fitted, the candidate regressor with the lowest
    K-fold cross-validated squared error on the rows it is given, then refits it on all of
    them.

    As the basis of a :class:`~workbench.BaseBoostRegressor` with ``n_stages > 1`` it makes the
    stages heterogeneous: stage ``k`` is fitted to the pseudo-residuals left by stages
    ``1..k-1``, so each stage's basis is chosen on its own residuals (e.g. a ridge or spline
    stage for a smooth trend, then trees for what is left). Like ``GridSearchCV`` used as an
    estimator, it is an ordinary regressor: ``clone``, ``get_params`` (``estimators`` and each
    candidate's parameters as ``<name>__<param>``) and ``set_params`` work.

    The folds are plain ``KFold`` over the rows the stage sees (a stage is given arrays, not
    the dataset's row labels, so it cannot group them); the choice of the whole model among
    others, e.g. by :class:`~workbench.selection.BasisChoiceCV`, can still use grouped folds.

    Parameters
    ----------
    estimators : list of (str, regressor)
        The candidates, by name; each is cloned. At least one.
    cv : int, default=3
        Folds of the choice (at least 2; fewer rows than folds is a ValueError).
    shuffle : bool, default=True
        Whether the rows are shuffled before they are dealt into folds.
    random_state : int, RandomState instance or None, default=None
        Seeds the folds (a :class:`~workbench.BaseBoostRegressor`'s ``random_state`` sets it,
        and every candidate's, through its nested parameters).

    Attributes
    ----------
    cv_scores_ : dict of str to float
        Each candidate's mean squared error over the held-out rows of the folds.
    chosen_ : str
        The name of the candidate with the lowest (the first of equals, in the given order).
    estimator_ : regressor
        That candidate refitted on every row.
    n_features_in_ : int
        Inputs seen in ``fit``.
    """

    _parameter_constraints: dict = {
        "estimators": [list],
        "cv": [Interval(Integral, 2, None, closed="left")],
        "shuffle": ["boolean"],
        "random_state": ["random_state"],
    }

    def __init__(self, estimators: list[tuple[str, Any]] | None = None, *, cv: int = 3,
                 shuffle: bool = True, random_state: Any = None) -> None:
        self.estimators = estimators
        self.cv = cv
        self.shuffle = shuffle
        self.random_state = random_state

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Get the parameters, the candidates' own nested as ``<name>__<param>``.

        Parameters
        ----------
        deep : bool, default=True
            Include the candidates' parameters.

        Returns
        -------
        dict
            Parameter name -> value.
        """
        return self._get_params("estimators", deep=deep)

    def set_params(self, **params: Any) -> Self:
        """Set parameters, a candidate's as ``<name>__<param>``.

        Parameters
        ----------
        **params
            Parameter name -> value.

        Returns
        -------
        self
            The estimator.
        """
        self._set_params("estimators", **params)
        return self

    def fit(self, X: Any, y: Any) -> Self:
        """Score every candidate by K-fold CV on ``(X, y)`` and refit the best on all rows.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : array-like of shape (n_samples,)
            The target.

        Returns
        -------
        StageChoiceCV
            The fitted model.
        """
        self._validate_params()
        if not self.estimators:
            raise ValueError("StageChoiceCV needs at least one candidate in estimators")
        self._validate_names([name for name, _ in self.estimators])
        X, y = validate_data(self, X, y, y_numeric=True, dtype=float)
        if len(y) < self.cv:
            raise ValueError(f"StageChoiceCV: n_samples = {len(y)}, fewer than the "
                             f"cv={self.cv} folds")
        folds = list(KFold(self.cv, shuffle=self.shuffle,
                           random_state=self.random_state if self.shuffle else None).split(X))
        self.cv_scores_ = {
            name: float(np.mean((y - cross_val_predict(candidate, X, y, cv=folds)) ** 2))
            for name, candidate in self.estimators}
        self.chosen_ = min(self.cv_scores_, key=self.cv_scores_.__getitem__)
        self.estimator_ = clone(dict(self.estimators)[self.chosen_]).fit(X, y)
        return self

    def predict(self, X: Any) -> np.ndarray:
        """The chosen candidate's prediction.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The prediction.
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=float, reset=False)
        return np.asarray(self.estimator_.predict(X), dtype=float).ravel()
