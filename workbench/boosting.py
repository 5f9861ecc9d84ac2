"""Base boosting: gradient boosting that starts from a scientific model's prediction.

For one target::

    h(X) = prior(X) + sum_{k=1..K} coef_k * b_k(T(X[:, basis_features]))

fitted greedily (the paper's Alg. 1): at stage k the basis regressor ``b_k`` is fitted to the
pseudo-residuals of ``y`` against the current model ``h_{k-1}``, and ``coef_k`` is the exact
minimiser of ``line_loss(y, h_{k-1} + a * b_k) + penalty * |a|``. ``T`` is an optional
transform of the basis inputs; it never touches the prior term.

With ``link="log"`` the same expansion runs on the log scale, for positive quantities whose
prior is a scale or a limit (error rates, lifetimes, cross sections)::

    h(X) = prior(X) * exp(sum_{k=1..K} coef_k * b_k(T(X[:, basis_features])))

so the stages learn a relative correction; losses and line search act on ``log y``.
"""

from __future__ import annotations

import numbers
from collections import deque
from collections.abc import Iterable, Iterator
from typing import Any, Self

import numpy as np
from numpy.typing import ArrayLike
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.tree import DecisionTreeRegressor
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from .line_search import line_search
from .losses import LOSSES, Loss, get_loss

__all__ = ["LINKS", "BaseBoostRegressor", "CachedParamNames", "PriorModel",
           "check_predictions", "seed_estimator"]

#: The links between prior and target: ``"identity"`` (the stages add to the prior) and
#: ``"log"`` (they multiply it: boosting on ``log y`` from ``log prior``).
LINKS = ("identity", "log")


def seed_estimator(estimator: Any, seed: int) -> Any:
    """Set every ``random_state`` parameter of ``estimator`` (nested ones too) to ``seed``.

    Parameters
    ----------
    estimator : estimator
        A scikit-learn estimator.
    seed : int
        The seed.

    Returns
    -------
    estimator
        ``estimator``, changed in place.
    """
    keys = [k for k in estimator.get_params(deep=True)
            if k == "random_state" or k.endswith("__random_state")]
    if keys:
        estimator.set_params(**{k: int(seed) for k in keys})
    return estimator


_PARAM_NAMES: dict[type, list[str]] = {}


class CachedParamNames:
    """A mixin: scikit-learn's parameter names of the class (its ``__init__`` signature),
    introspected once per class instead of at every ``get_params``/``clone`` (on small fits
    ``inspect.signature`` is a visible share of the time)."""

    @classmethod
    def _get_param_names(cls) -> list[str]:
        names = _PARAM_NAMES.get(cls)
        if names is None:
            after: Any = super(CachedParamNames, cls)  # a BaseEstimator, later in the MRO
            names = _PARAM_NAMES[cls] = after._get_param_names()
        return list(names)


def _is_column(prior: object) -> bool:
    return isinstance(prior, (str, numbers.Integral)) and not isinstance(prior, bool)


def _column_index(key: str | int, feature_names: Iterable[str] | None, n_features: int,
                  what: str) -> int:
    if isinstance(key, str):
        if feature_names is None:
            raise ValueError(f"{what} {key!r} is a column name, but X has no column names "
                             "(pass a pandas DataFrame or use an integer index)")
        names = list(feature_names)
        if key not in names:
            raise ValueError(f"{what} {key!r} is not a column of X; columns are: {names}")
        return names.index(key)
    if not -n_features <= int(key) < n_features:
        raise ValueError(f"{what} {key!r} is out of range for X with {n_features} columns")
    return int(key) % n_features


def check_predictions(values: ArrayLike, n: int, what: str) -> np.ndarray:
    """``values`` as a finite float array of shape ``(n,)``, or a ValueError naming ``what``.

    Parameters
    ----------
    values : array-like
        Predictions, one per row (a single column is flattened).
    n : int
        The rows.
    what : str
        What made them, in the message.

    Returns
    -------
    ndarray of shape (n,)
        The values.

    Raises
    ------
    ValueError
        A wrong shape, or NaN or infinite values.
    """
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 2 and arr.shape[1] == 1:
        arr = arr[:, 0]
    if arr.shape != (n,):
        raise ValueError(f"{what} must give one value per row: expected shape ({n},), "
                         f"got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr))[:10].tolist()
        raise ValueError(f"{what} contains NaN or infinite values (rows {bad})")
    return arr


class PriorModel(CachedParamNames, RegressorMixin, BaseEstimator):
    """The incumbent: the scientific model alone, as a scikit-learn regressor.

    Parameters
    ----------
    prior : None, str, int, estimator or callable
        ``None``: a constant, the mean of the training targets (ordinary boosting's start).
        ``str``/``int``: the column of ``X`` (name or index) holding the prior prediction.
        An estimator: cloned and fitted on ``(X, y)``, like scikit-learn's ``init``; wrap an
        already fitted model in ``sklearn.frozen.FrozenEstimator`` to use it as is.
        A callable: ``prior(X)`` returns the prediction (``X`` as passed to ``fit``/``predict``).
    """

    _parameter_constraints: dict = {
        "prior": [None, str, numbers.Integral, HasMethods(["fit", "predict"]), callable],
    }

    def __init__(self, *, prior: Any = None) -> None:
        self.prior = prior

    def fit(self, X: Any, y: Any) -> Self:
        """Fit the prior: the targets' mean, the column's index, or the estimator on ``(X, y)``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : array-like of shape (n_samples,)
            The target.

        Returns
        -------
        self
            The fitted prior.
        """
        self._validate_params()
        X_raw = X
        X, y = validate_data(self, X, y, y_numeric=True, dtype=float,
                             ensure_all_finite=not callable(self.prior))
        return self._fit_validated(X_raw, X, y)

    def _fit_validated(self, X_raw: Any, X: np.ndarray, y: np.ndarray) -> Self:
        """:meth:`fit` after validation (``X``, ``y``: the validated arrays; the
        ``n_features_in_``/``feature_names_in_`` attributes already set)."""
        prior = self.prior
        if prior is None:
            self.constant_ = float(np.mean(y))
        elif _is_column(prior):
            self.column_ = _column_index(prior, getattr(self, "feature_names_in_", None),
                                         X.shape[1], "prior column")
        elif hasattr(prior, "fit") and hasattr(prior, "predict"):
            self.estimator_ = clone(prior).fit(X_raw, y)
        elif callable(prior):
            pass
        else:  # fit validated the parameter; reached by _fit_validated's callers only
            raise TypeError("prior must be None, a column name or index, an estimator or a "
                            f"callable; got {type(prior).__name__}")
        return self

    def predict(self, X: Any) -> np.ndarray:
        """Predict the prior for ``X``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The prior's predictions.
        """
        check_is_fitted(self)
        X_raw = X
        X = validate_data(self, X, reset=False, dtype=float,
                          ensure_all_finite=not callable(self.prior))
        return self._predict_validated(X_raw, X)

    def _predict_validated(self, X_raw: Any, X: np.ndarray) -> np.ndarray:
        """:meth:`predict` of an ``X`` already validated (as ``X_raw`` was given)."""
        n = X.shape[0]
        if hasattr(self, "constant_"):
            return np.full(n, self.constant_)
        if hasattr(self, "column_"):
            return check_predictions(X[:, self.column_], n, "prior column")
        if hasattr(self, "estimator_"):
            return check_predictions(self.estimator_.predict(X_raw), n, "prior estimator output")
        return check_predictions(self.prior(X_raw), n, "prior callable output")

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "n_features_in_")


class BaseBoostRegressor(CachedParamNames, RegressorMixin, BaseEstimator):
    """Base boosting for one target.

    Parameters
    ----------
    prior : None, str, int, estimator or callable, default=None
        The scientific prediction the expansion starts from; see :class:`PriorModel`.
        ``None`` starts from the mean of ``y`` (ordinary gradient boosting).
    basis : regressor, default=None
        Any scikit-learn regressor, cloned for every stage. ``None`` means
        ``DecisionTreeRegressor(max_depth=3)``.
    n_stages : int, default=1
        Number of stages ``K`` (>= 1).
    loss : str or Loss, default="squared_error"
        Loss whose negative gradient gives the pseudo-residuals; one of
        :data:`workbench.losses.LOSSES`.
    line_search_loss : str or Loss, default="absolute_error"
        Loss of the line search for each stage's coefficient.
    line_search_penalty : float, default=0.1
        L1 penalty on each coefficient in the line search.
    basis_features : list of str or int, default=None
        Columns of ``X`` fed to the basis (``None``: all columns).
    input_transform : transformer, default=None
        Applied (cloned and fitted) to the basis inputs only, never to the prior term.
    alpha : float, default=0.9
        Huber's quantile for ``delta`` and the quantile loss's level.
    random_state : int, RandomState or None, default=None
        Seeds the transform and each stage's basis (every nested ``random_state``). ``None``
        leaves the basis's own ``random_state`` values as they are.
    link : {"identity", "log"}, default="identity"
        How the stages combine with the prior: ``"identity"`` adds them; ``"log"`` boosts
        ``log y`` from ``log prior`` and predicts ``prior * exp(sum ...)`` (targets and prior
        must be positive: a value that is not is a ValueError naming its rows).
    out_of_bounds : {"extrapolate", "clip"}, default="extrapolate"
        What the stages may add for a new row, as in
        :class:`~sklearn.isotonic.IsotonicRegression`: ``"extrapolate"`` leaves the summed
        correction (on the link's scale) as the bases predict it; ``"clip"`` clips it, after
        each stage, to the range it took on the training rows (``correction_range_``). A
        tree basis never leaves that range by much; a linear or kernel basis extrapolates
        past it, which the log link turns into exponential growth (a ridge stage on the log
        scale once predicted a gate error 2,000 times the largest seen for a new device).

    Attributes
    ----------
    prior_model_ : PriorModel
        The fitted prior term.
    prior_values_ : ndarray of shape (n_samples,)
        The prior's predictions on the training rows.
    input_transform_ : transformer or None
    basis_columns_ : ndarray of int
        Indices of the basis input columns.
    estimators_ : list of regressors
        The fitted basis function of each stage.
    coefs_ : ndarray of shape (n_stages,)
        The line-search coefficient of each stage.
    train_score_ : ndarray of shape (n_stages + 1,)
        Training loss (the pseudo-residual loss) of the prior and after each stage.
    correction_range_ : ndarray of shape (n_stages, 2)
        The smallest and largest summed correction (on the link's scale) on the training
        rows after each stage: the bounds of ``out_of_bounds="clip"``.
    """

    _parameter_constraints: dict = {
        **PriorModel._parameter_constraints,
        "basis": [None, HasMethods(["fit", "predict"])],
        "n_stages": [Interval(numbers.Integral, 1, None, closed="left")],
        "loss": [StrOptions(set(LOSSES)), Loss],
        "line_search_loss": [StrOptions(set(LOSSES)), Loss],
        "line_search_penalty": [Interval(numbers.Real, 0, None, closed="left")],
        "basis_features": [None, str, numbers.Integral, "array-like"],
        "input_transform": [None, HasMethods(["fit", "transform"])],
        "alpha": [Interval(numbers.Real, 0, 1, closed="neither")],
        "random_state": ["random_state"],
        "link": [StrOptions(set(LINKS))],
        "out_of_bounds": [StrOptions({"extrapolate", "clip"})],
    }

    def __init__(self, *, prior: Any = None, basis: Any = None, n_stages: int = 1,
                 loss: str | Loss = "squared_error",
                 line_search_loss: str | Loss = "absolute_error",
                 line_search_penalty: float = 0.1, basis_features: Any = None,
                 input_transform: Any = None, alpha: float = 0.9,
                 random_state: int | np.random.RandomState | None = None,
                 link: str = "identity", out_of_bounds: str = "extrapolate") -> None:
        self.prior = prior
        self.basis = basis
        self.n_stages = n_stages
        self.loss = loss
        self.line_search_loss = line_search_loss
        self.line_search_penalty = line_search_penalty
        self.basis_features = basis_features
        self.input_transform = input_transform
        self.alpha = alpha
        self.random_state = random_state
        self.link = link
        self.out_of_bounds = out_of_bounds

    def _check_params(self) -> tuple[Loss, Loss, Any]:
        """The parameters checked against ``_parameter_constraints`` (scikit-learn's
        ``InvalidParameterError``, a ValueError and TypeError); returns the losses and the
        basis."""
        self._validate_params()
        loss = get_loss(self.loss, alpha=self.alpha)
        line_loss = get_loss(self.line_search_loss, alpha=self.alpha)
        basis = DecisionTreeRegressor(max_depth=3) if self.basis is None else self.basis
        return loss, line_loss, basis

    def _basis_columns(self, n_features: int) -> np.ndarray:
        if self.basis_features is None:
            return np.arange(n_features)
        cols = self.basis_features
        if _is_column(cols):
            cols = [cols]
        if len(cols) == 0:
            raise ValueError("basis_features is empty")
        names = getattr(self, "feature_names_in_", None)
        return np.array([_column_index(c, names, n_features, "basis feature") for c in cols])

    def _basis_inputs(self, X: np.ndarray) -> np.ndarray:
        Z = X[:, self.basis_columns_]
        if self.input_transform_ is not None:
            Z = self.input_transform_.transform(Z)
        return Z

    def fit(self, X: Any, y: Any) -> Self:
        """Fit the prior and ``n_stages`` stages on ``(X, y)``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs (the prior's column among them, for a column prior).
        y : array-like of shape (n_samples,)
            The target.

        Returns
        -------
        self
            The fitted estimator.
        """
        loss, line_loss, basis = self._check_params()
        X_raw = X
        X, y = validate_data(self, X, y, y_numeric=True, dtype=float)
        rng = check_random_state(self.random_state)
        seeds = rng.randint(np.iinfo(np.int32).max, size=self.n_stages + 1)

        # the prior on the rows validated here (validated once: the same as fitting and
        # predicting it on X_raw)
        self.prior_model_ = PriorModel(prior=self.prior)
        self.prior_model_.n_features_in_ = self.n_features_in_
        if hasattr(self, "feature_names_in_"):
            self.prior_model_.feature_names_in_ = self.feature_names_in_
        self.prior_model_._fit_validated(X_raw, X, y)
        self.prior_values_ = self.prior_model_._predict_validated(X_raw, X)
        start = self._to_link(self.prior_values_, "the prior")
        y = self._to_link(y, "the target y")
        self.basis_columns_ = self._basis_columns(X.shape[1])
        self.input_transform_ = None
        if self.input_transform is not None:
            transform = clone(self.input_transform)
            if self.random_state is not None:
                seed_estimator(transform, seeds[-1])
            self.input_transform_ = transform.fit(X[:, self.basis_columns_])
        Z = self._basis_inputs(X)

        current = start.copy()
        self.estimators_, coefs, scores, ranges = [], [], [loss(y, current)], []
        for k in range(self.n_stages):
            residual = loss.negative_gradient(y, current)
            est = clone(basis)
            if self.random_state is not None:
                seed_estimator(est, seeds[k])
            est.fit(Z, residual)
            direction = check_predictions(est.predict(Z), len(y),
                                         f"basis prediction at stage {k + 1}")
            coef = line_search(y, current, direction, line_loss, self.line_search_penalty)
            current = current + coef * direction
            self.estimators_.append(est)
            coefs.append(coef)
            scores.append(loss(y, current))
            ranges.append(((current - start).min(), (current - start).max()))
        self.coefs_ = np.asarray(coefs)
        self.correction_range_ = np.asarray(ranges, dtype=float)
        self.train_score_ = np.asarray(scores)
        return self

    def _to_link(self, values: np.ndarray, what: str) -> np.ndarray:
        """``values`` on the link's scale (``log`` for ``link="log"``, refusing values that
        are not positive)."""
        if self.link == "identity":
            return values
        bad = np.flatnonzero(values <= 0)
        if bad.size:
            raise ValueError(f"link='log' needs positive values, but {what} has {bad.size} "
                             f"value(s) <= 0 (rows {bad[:10].tolist()}); use "
                             f"link='identity' for quantities that can be 0 or negative")
        return np.log(values)

    def _from_link(self, values: np.ndarray) -> np.ndarray:
        return values if self.link == "identity" else np.exp(values)

    def predict_prior(self, X: Any) -> np.ndarray:
        """The prior term alone for ``X``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The prior's predictions.
        """
        check_is_fitted(self)
        return self.prior_model_.predict(X)

    def predict_correction(self, X: Any) -> np.ndarray:
        """What the stages add to the prior for ``X``, in the target's units: the learned
        correction, ``predict(X) - predict_prior(X)`` up to rounding (exactly 0 where every
        coefficient is 0; a stage whose coefficient is 0 is not evaluated). With the identity
        link it is ``sum_k coef_k * b_k(T(X))``; with the log link
        ``prior(X) * (exp(sum_k ...) - 1)``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The correction.
        """
        check_is_fitted(self)
        X_raw, X = X, validate_data(self, X, reset=False, dtype=float)
        out = np.zeros(X.shape[0])
        if not np.any(self.coefs_):
            return out
        Z = self._basis_inputs(X)
        for est, coef in zip(self.estimators_, self.coefs_):
            if coef != 0:
                out = out + coef * np.asarray(est.predict(Z), dtype=float).ravel()
        out = self._bounded(out, len(self.estimators_) - 1)
        if self.link == "identity":
            return out
        prior = self.prior_model_._predict_validated(X_raw, X)
        return prior * np.expm1(out)

    def staged_predict(self, X: Any) -> Iterator[np.ndarray]:
        """Yield the prediction after each stage ``k = 1..n_stages``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Yields
        ------
        ndarray of shape (n_samples,)
            The prediction after stage ``k``.
        """
        check_is_fitted(self)
        X_raw, X = X, validate_data(self, X, reset=False, dtype=float)
        prior = np.asarray(self.prior_model_._predict_validated(X_raw, X), dtype=float)
        # the log link's fit needs positive priors; a new row's may not be: there the
        # prediction is the same formula, prior * exp(correction), without its logarithm
        positive = prior > 0 if self.link == "log" else np.ones(prior.shape, dtype=bool)
        start = self._to_link(np.where(positive, prior, 1.0), "the prior")
        Z = self._basis_inputs(X)
        pred, correction = start, np.zeros(X.shape[0])
        for k, (est, coef) in enumerate(zip(self.estimators_, self.coefs_)):
            step = coef * np.asarray(est.predict(Z), dtype=float).ravel()
            correction = correction + step
            if self.out_of_bounds == "clip":
                pred = start + self._bounded(correction, k)
            else:
                pred = pred + step
            out = self._from_link(pred)
            if not positive.all():
                c = self._bounded(correction, k)[~positive]
                out[~positive] = prior[~positive] * np.exp(c)
            yield out

    def _bounded(self, correction: np.ndarray, stage: int) -> np.ndarray:
        """``correction`` (summed to ``stage``, link scale), clipped to the training rows'
        range where ``out_of_bounds="clip"``."""
        if self.out_of_bounds != "clip":
            return correction
        low, high = self.correction_range_[stage]
        return np.clip(correction, low, high)

    def predict(self, X: Any) -> np.ndarray:
        """``prior(X) + sum_k coef_k * b_k(T(X))`` (``link="log"``: ``prior(X) *
        exp(sum_k ...)``, also where a new row's prior is not positive, which the log link's
        fit refuses).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The predictions.
        """
        (pred,) = deque(self.staged_predict(X), maxlen=1)  # the last stage's (n_stages >= 1)
        return pred
