"""A basis tuned on the rows it is fitted on: successive halving over its settings' folds."""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Any, Self

import numpy as np
from sklearn.base import RegressorMixin, clone
from sklearn.model_selection import KFold
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.metaestimators import _BaseComposition
from sklearn.utils.validation import check_is_fitted, validate_data

from .boosting import CachedParamNames

__all__ = ["HalvingChoiceCV"]

#: The errors a setting is scored by on its held-out rows.
_ERRORS = {"absolute_error": lambda r: float(np.mean(np.abs(r))),
           "squared_error": lambda r: float(np.mean(r ** 2))}


class HalvingChoiceCV(CachedParamNames, RegressorMixin, _BaseComposition):
    """A basis that tunes itself each time it is fitted: successive halving over candidate
    settings, with the folds of the rows it is given as the resource, then the winner
    refitted on all of them.

    Every candidate is scored on the first fold; the best ``1/factor`` of them (at least
    one) go on to the second fold, and so on, each ranked by its mean error over the folds
    it has run; the one left best after the last fold (or the only one left) is refitted on
    every row. With 24 candidates, ``cv=3`` and ``factor=3`` that is 24 + 8 + 3 fold fits
    and a refit: one tuned setting for about 1.5 times the fits the 24 cost as candidates
    of a 5-fold CV, and nested correctly (inside an outer CV fold it sees that fold's
    training rows only). As the basis of a :class:`~workbench.BaseBoostRegressor` it tunes
    on the stage's own pseudo-residuals; ``[model] tune = "halving"`` makes one such
    candidate of a basis's drawn settings (docs/user_guide/generic.md).

    Parameters
    ----------
    estimators : list of (str, regressor)
        The candidate settings, by name, simplest first where it matters (ties go to the
        first); each is cloned. At least one.
    cv : int, default=3
        Folds (at least 2; fewer rows than folds is a ValueError).
    factor : float, default=3
        The share kept after each fold is ``1/factor`` (more than 1).
    error : {"absolute_error", "squared_error"}, default="absolute_error"
        What a candidate is ranked by on its held-out rows.
    shuffle : bool, default=True
        Whether the rows are shuffled before they are dealt into folds.
    random_state : int, RandomState instance or None, default=None
        Seeds the folds (a :class:`~workbench.BaseBoostRegressor`'s ``random_state`` sets it,
        and every candidate's, through their nested parameters).

    Attributes
    ----------
    cv_scores_ : dict of str to float
        Each candidate's mean error over the folds it ran.
    folds_run_ : dict of str to int
        How many folds each candidate ran.
    chosen_ : str
        The name of the winner.
    estimator_ : regressor
        The winner refitted on every row.
    n_features_in_ : int
        Inputs seen in ``fit``.
    """

    _parameter_constraints: dict = {
        "estimators": [list],
        "cv": [Interval(Integral, 2, None, closed="left")],
        "factor": [Interval(Real, 1, None, closed="neither")],
        "error": [StrOptions(set(_ERRORS))],
        "shuffle": ["boolean"],
        "random_state": ["random_state"],
    }

    def __init__(self, estimators: list[tuple[str, Any]] | None = None, *, cv: int = 3,
                 factor: float = 3, error: str = "absolute_error", shuffle: bool = True,
                 random_state: Any = None) -> None:
        self.estimators = estimators
        self.cv = cv
        self.factor = factor
        self.error = error
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
        """Race the candidates over the folds of ``(X, y)`` and refit the winner on all rows.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The training rows.
        y : array-like of shape (n_samples,)
            The target.

        Returns
        -------
        HalvingChoiceCV
            The fitted chooser (``self``).
        """
        self._validate_params()
        if not self.estimators:
            raise ValueError("HalvingChoiceCV needs at least one candidate in estimators")
        names = [name for name, _ in self.estimators]
        self._validate_names(names)
        X, y = validate_data(self, X, y, y_numeric=True, dtype=float)
        if len(y) < self.cv:
            raise ValueError(f"HalvingChoiceCV: n_samples = {len(y)}, fewer than the "
                             f"cv={self.cv} folds")
        folds = KFold(self.cv, shuffle=self.shuffle,
                      random_state=self.random_state if self.shuffle else None).split(X)
        candidates, error = dict(self.estimators), _ERRORS[self.error]
        errors: dict[str, list[float]] = {name: [] for name in names}
        alive = names
        for i, (fit_rows, held) in enumerate(folds):
            for name in alive:
                model = clone(candidates[name]).fit(X[fit_rows], y[fit_rows])
                errors[name].append(error(y[held] - np.ravel(model.predict(X[held]))))
            # stable: among equal errors the first listed (the simplest) stays
            alive = sorted(alive, key=lambda n: float(np.mean(errors[n])))
            if i < self.cv - 1:
                alive = alive[:max(1, math.ceil(len(alive) / self.factor))]
            if len(alive) == 1:
                break
        self.cv_scores_ = {n: float(np.mean(e)) for n, e in errors.items()}
        self.folds_run_ = {n: len(e) for n, e in errors.items()}
        self.chosen_ = alive[0]
        self.estimator_ = clone(candidates[self.chosen_]).fit(X, y)
        return self

    def predict(self, X: Any) -> np.ndarray:
        """The winner's prediction.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The rows to predict.

        Returns
        -------
        ndarray of shape (n_samples,)
            The winner's prediction for each row.
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=float, reset=False)
        return np.asarray(self.estimator_.predict(X), dtype=float).ravel()
