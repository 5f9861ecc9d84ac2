"""Physics-derived basis inputs: what a physicist would hand a regressor besides the raw
columns.

:class:`PriorDerivedInputs` is an input transform for
:class:`~workbench.BaseBoostRegressor` (``input_transform``): its input is the basis input
block, whose first ``n_priors`` columns are prior predictions and the rest features; it
returns that block with the priors' pairwise differences and ratios, the log of each prior
that is positive on every training row, and the product of each prior with each feature.
Trees split on one input at a time, so a gap between two levels or a rate relative to a
limit is hard for them to learn from a hundred rows; given as a column, one split finds it.
"""

from __future__ import annotations

from itertools import combinations
from numbers import Integral
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin, clone
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

__all__ = ["DERIVED_KINDS", "PriorDerivedInputs"]

#: The kinds of derived column, in the order they are appended.
DERIVED_KINDS = ("differences", "ratios", "log", "interactions")


class PriorDerivedInputs(TransformerMixin, BaseEstimator):
    """Append differences, ratios and logs of the priors and prior x feature products.

    Parameters
    ----------
    n_priors : int, default=1
        How many leading columns of the input are prior predictions; the rest are features.
    kinds : list of str, default=None
        Which derived columns to append, among ``"differences"`` (``p_i - p_j``, ``i < j``),
        ``"ratios"`` (``p_i / p_j``, ``i < j``, where ``p_j`` is nonzero on every training
        row), ``"log"`` (``log p_i``, where ``p_i`` is positive on every training row) and
        ``"interactions"`` (``p_i * x_k`` for each feature ``x_k``). ``None``: all four.
    then : transformer, default=None
        Fitted on the augmented block and applied after it (e.g. ``StandardScaler()``).

    Attributes
    ----------
    n_features_in_ : int
        Columns seen in ``fit``.
    pairs_ : list of tuple of int
        The prior pairs ``(i, j)`` whose differences are appended.
    ratio_pairs_ : list of tuple of int
        The pairs whose ratios are appended.
    log_priors_ : list of int
        The priors whose logs are appended.
    interactions_ : bool
        Whether the prior x feature products are appended.
    log_floor_ : ndarray
        Per logged prior, a tenth of its smallest training value: values at or below it are
        clipped to it before the log, so a new row never gives a NaN.
    then_ : transformer or None
        The fitted ``then``.
    """

    _parameter_constraints: dict = {
        "n_priors": [Interval(Integral, 1, None, closed="left")],
        "kinds": [None, list, tuple],
        "then": [None, HasMethods(["fit", "transform"])],
    }

    def __init__(self, *, n_priors: int = 1, kinds: list[str] | tuple[str, ...] | None = None,
                 then: Any = None) -> None:
        self.n_priors = n_priors
        self.kinds = kinds
        self.then = then

    def _kinds(self) -> tuple[str, ...]:
        kinds = DERIVED_KINDS if self.kinds is None else tuple(self.kinds)
        check = StrOptions(set(DERIVED_KINDS))
        for kind in kinds:
            if not check.is_satisfied_by(kind):
                raise ValueError(f"kinds: unknown kind {kind!r}; valid kinds are "
                                 f"{', '.join(DERIVED_KINDS)}")
        return kinds

    def fit(self, X: Any, y: Any = None) -> PriorDerivedInputs:
        """Choose the derived columns on ``X`` (and fit ``then``); returns ``self``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The basis inputs, priors first.
        y : None
            Ignored.

        Returns
        -------
        PriorDerivedInputs
            The fitted transformer.
        """
        self._validate_params()
        X = validate_data(self, X, dtype=float)
        kinds = self._kinds()
        if self.n_priors > X.shape[1]:
            raise ValueError(f"n_priors={self.n_priors} but the input has only "
                             f"{X.shape[1]} column(s)")
        P = X[:, :self.n_priors]
        pairs = list(combinations(range(self.n_priors), 2))
        self.pairs_ = pairs if "differences" in kinds else []
        self.ratio_pairs_ = ([(i, j) for i, j in pairs if np.all(P[:, j] != 0)]
                             if "ratios" in kinds else [])
        self.log_priors_ = ([i for i in range(self.n_priors) if np.all(P[:, i] > 0)]
                            if "log" in kinds else [])
        self.log_floor_ = np.array([P[:, i].min() / 10 for i in self.log_priors_])
        self.interactions_ = "interactions" in kinds
        self.then_ = None
        if self.then is not None:
            self.then_ = clone(self.then).fit(self._augment(X))
        return self

    def _augment(self, X: np.ndarray) -> np.ndarray:
        P, F = X[:, :self.n_priors], X[:, self.n_priors:]
        parts = [X]
        parts += [P[:, [i]] - P[:, [j]] for i, j in self.pairs_]
        for i, j in self.ratio_pairs_:
            ratio = np.divide(P[:, i], P[:, j], out=np.zeros(len(X)), where=P[:, j] != 0)
            parts.append(ratio[:, None])
        for i, floor in zip(self.log_priors_, self.log_floor_):
            parts.append(np.log(np.maximum(P[:, [i]], floor)))
        if self.interactions_ and F.shape[1]:
            parts += [P[:, [i]] * F for i in range(self.n_priors)]
        return np.hstack(parts)

    def transform(self, X: Any) -> np.ndarray:
        """The input block with the derived columns appended (then ``then`` applied).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The basis inputs, priors first.

        Returns
        -------
        ndarray of shape (n_samples, n_features + n_derived)
            ``X``'s columns, then the derived ones (``then`` applied).
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=float, reset=False)
        Z = self._augment(X)
        return Z if self.then_ is None else self.then_.transform(Z)
