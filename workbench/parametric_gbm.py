"""Boosting in a user's model's own parameter space, with any scikit-learn regressor.

:class:`ParameterSpaceBoostRegressor` fits ``y ~ f(theta(x); x)`` for a user's model ``f``
(:mod:`workbench.parametric`) with ``theta(x) = theta_0(x) + nu sum_m rho_m h_m(x)``: the
start ``theta_0`` is the calibrated model (or a linear drift,
:class:`~workbench.param_regressor.ParametricRegressor`), and every round ``m`` fits one
regressor per boosted parameter, a clone of ``estimator``, to that parameter's
pseudo-residuals, the negative gradient of the loss with respect to the parameter on each
row, ``g_ip = sum_t J_itp psi(r_it)`` (``J`` the model's Jacobian, ``psi`` the loss's
derivative). ``step="newton"`` fits ``g_ip / h_ip`` with sample weights
``h_ip = sum_t w_it J_itp^2`` (the Gauss-Newton curvature, ``w`` the loss's IRLS weights: the
second-order boosting of LightGBM and XGBoost, done per parameter);
``step="gradient"`` fits ``g_ip / mean_i h_ip`` unweighted (for regressors without
``sample_weight``). A line search over the joint step ``rho_m`` (the robust loss) and the
shrinkage ``nu`` (``learning_rate``) follow; ``update="greedy"`` moves only the parameter
whose step lowers the loss most in each round.

:func:`workbench.parametric_boost.boost_candidate` scores such a template by CV on given
folds, choosing the number of rounds from the folds' staged predictions
(:class:`~workbench.parametric_boost.ParametricBoostRegressor`'s ``boost`` candidate).
"""

from __future__ import annotations

import numbers
from collections import deque
from collections.abc import Iterator
from typing import Any, Self

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.tree import DecisionTreeRegressor
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, has_fit_parameter

from .bases import basis_names, make_basis
from .param_engine import PARAM_LOSSES
from .param_regressor import (
    OUT_OF_BOUNDS,
    ParametricRegressor,
    _as_frame,
    _predict_rows,
    _targets,
    _trial,
)
from .parametric import ParametricModel, check_model, resolve_model, restrict

__all__ = ["ParameterSpaceBoostRegressor", "make_regressor"]

_MODEL = [None, str, HasMethods(["predict", "jacobian", "start"])]


def make_regressor(name: str, params: dict[str, Any] | None = None) -> Any:
    """The per-parameter regressor ``name``: ``"tree"`` (scikit-learn's
    ``DecisionTreeRegressor``, default ``max_depth=3``) or a basis of
    :data:`workbench.bases.BASES` (``"lightgbm"``, ``"ridge"``, ...), with ``params``.

    Parameters
    ----------
    name : str
        ``"tree"`` or a basis name.
    params : dict, optional
        The regressor's settings.

    Returns
    -------
    estimator
        An unfitted scikit-learn regressor.

    Raises
    ------
    ValueError
        For an unknown name (the message lists the valid ones).
    """
    params = dict(params or {})
    if name == "tree":
        return DecisionTreeRegressor(**{"max_depth": 3, **params})
    if name not in basis_names():
        raise ValueError(f"unknown parameter-space regressor {name!r}; valid names are: "
                         f"{', '.join(['tree', *basis_names()])}")
    return make_basis(name, **params)


def _frame(est: BaseEstimator, X: Any, reset: bool) -> pd.DataFrame:
    return _as_frame(est, X, reset)  # the same input rules as the family's


def _loss(loss: str, r: np.ndarray, delta: float) -> float:
    return float(PARAM_LOSSES[loss](r, delta)[0].sum())


class ParameterSpaceBoostRegressor(RegressorMixin, BaseEstimator):
    """A user's model whose parameters are boosted by any scikit-learn regressor.

    Parameters
    ----------
    model : str or ParametricModel
        The path of a model file (:func:`~workbench.parametric.load_model`) or a model.
    estimator : regressor, default=None
        The regressor cloned for every parameter and round (None: a
        ``DecisionTreeRegressor(max_depth=3)``); its ``random_state``, if any, is set from
        ``random_state``.
    init : ParametricRegressor or "drift", default=None
        The start ``theta_0`` (fitted on the same rows; e.g. a linear drift); None: the
        calibrated model (``ParametricRegressor(max_iter=0)`` with this ``loss``);
        ``"drift"``: the linear drift a choice selects
        (:func:`~workbench.parametric_boost.boost_candidate` replaces it).
    parameters : list of str, default=None
        The parameters boosted (None: all).
    features : list of str, default=None
        The columns the regressors see (None: every numeric column that is no parameter's
        column).
    n_estimators : int, default=100
        Boosting rounds.
    learning_rate : float, default=0.1
        The shrinkage ``nu`` of every line-searched step.
    step : {"newton", "gradient"}, default="newton"
        The pseudo-residuals' form (above); a regressor without ``sample_weight`` takes
        ``"gradient"`` steps.
    update : {"joint", "greedy"}, default="joint"
        Every boosted parameter in each round (one joint line search), or only the one
        whose step lowers the loss most.
    subsample : float, default=1.0
        The fraction of rows each round's regressors see (stochastic boosting).
    loss : {"squared_error", "absolute_error", "huber"}, default="huber"
    huber_delta : float, default=1.0
        Huber's threshold (targets' units).
    out_of_bounds : {"extrapolate", "clip", "calibrated"}, default="extrapolate"
        What a new row with a feature beyond its training range gets: the regressors'
        predictions there (``"extrapolate"``: trees predict their edge leaves' values, so the
        parameters' steps are those at the edge, applied where the model's own variables
        have moved on); the features clipped to their training range (``"clip"``); or the
        calibrated model's parameters, no drift and no boosted steps (``"calibrated"``:
        ``init_``'s calibration). ``"clip"`` and ``"calibrated"`` are also set on the start
        (a :class:`~workbench.param_regressor.ParametricRegressor`).
    random_state : int, default=None
        Seeds the subsamples and the regressors.

    Attributes
    ----------
    init_ : ParametricRegressor
        The fitted start.
    calibration_ : DataFrame
        ``init_``'s calibration.
    parameter_names_ : list of str
    features_ : list of str
    estimators_ : list of dict of str -> regressor
        Each round's fitted regressors by parameter.
    steps_ : ndarray
        Each round's ``nu * rho_m``.
    train_loss_ : ndarray
        The loss before and after each round.
    n_iter_ : int
        Rounds fitted.
    n_targets_ : int
    feature_range_ : ndarray of shape (2, n_features)
        The training rows' minimum and maximum of each of :attr:`features_`.
    """

    _parameter_constraints: dict = {
        "model": _MODEL,
        "estimator": [None, HasMethods(["fit", "predict"])],
        "init": [None, StrOptions({"drift"}), HasMethods(["fit", "corrected_parameters"])],
        "parameters": [None, list, tuple],
        "features": [None, list, tuple],
        "n_estimators": [Interval(numbers.Integral, 0, None, closed="left")],
        "learning_rate": [Interval(numbers.Real, 0, 1, closed="right")],
        "step": [StrOptions({"newton", "gradient"})],
        "update": [StrOptions({"joint", "greedy"})],
        "subsample": [Interval(numbers.Real, 0, 1, closed="right")],
        "loss": [StrOptions(set(PARAM_LOSSES))],
        "huber_delta": [Interval(numbers.Real, 0, None, closed="neither")],
        "out_of_bounds": [StrOptions(set(OUT_OF_BOUNDS))],
        "random_state": [None, numbers.Integral],
    }

    def __init__(self, *, model: str | ParametricModel | None = None, estimator: Any = None,
                 init: Any = None, parameters: list[str] | None = None,
                 features: list[str] | None = None, n_estimators: int = 100,
                 learning_rate: float = 0.1, step: str = "newton", update: str = "joint",
                 subsample: float = 1.0, loss: str = "huber", huber_delta: float = 1.0,
                 out_of_bounds: str = "extrapolate", random_state: int | None = None) -> None:
        self.model = model
        self.estimator = estimator
        self.init = init
        self.parameters = parameters
        self.features = features
        self.n_estimators = n_estimators
        self.learning_rate = learning_rate
        self.step = step
        self.update = update
        self.subsample = subsample
        self.loss = loss
        self.huber_delta = huber_delta
        self.out_of_bounds = out_of_bounds
        self.random_state = random_state

    # ------------------------------------------------------------------ fitting
    def _start(self, X: pd.DataFrame, Y: np.ndarray) -> Any:
        if isinstance(self.init, str):
            raise ValueError("init='drift' is the drift a ParametricBoostRegressor selects; "
                             "alone, pass a ParametricRegressor with covariates")
        init = (ParametricRegressor(max_iter=0) if self.init is None else clone(self.init))
        init.set_params(model=self.model, loss=self.loss, huber_delta=self.huber_delta)
        if self.out_of_bounds != "extrapolate" and "out_of_bounds" in init.get_params():
            init.set_params(out_of_bounds=self.out_of_bounds)
        return init.fit(X, Y)

    def _inputs(self, X: pd.DataFrame, fitting: bool = False) -> np.ndarray:
        """The regressors' inputs: the features, by name (a frame's columns read as str),
        clipped to their training range with ``out_of_bounds="clip"`` (new rows)."""
        columns = {str(c): c for c in X.columns}
        Z = X[[columns[c] for c in self.features_]].to_numpy(dtype=float)
        if self.out_of_bounds == "clip" and not fitting:
            Z = np.clip(Z, *self.feature_range_)
        return Z

    def _outside(self, Z: np.ndarray) -> np.ndarray:
        """The rows with a feature beyond its training range."""
        low, high = self.feature_range_
        return ~np.all((Z >= low) & (Z <= high), axis=1)

    def fit(self, X: Any, y: Any) -> Self:
        """Start from ``init``, then boost the parameters ``n_estimators`` rounds.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            The rows (the user's model's data columns).
        y : array-like of shape (n_samples,) or (n_samples, n_targets)
            The measured targets.

        Returns
        -------
        self
            The fitted estimator.
        """
        self._validate_params()
        if self.model is None:
            raise ValueError("ParameterSpaceBoostRegressor needs a model: a model file's "
                             "path or a ParametricModel")
        X = _frame(self, X, reset=True)
        Y = _targets(y)
        if len(Y) != len(X):
            raise ValueError(f"X has {len(X)} rows and y {len(Y)}")
        self._y_1d = np.asarray(y).ndim == 1
        full = resolve_model(self.model)
        self.n_targets_ = T = Y.shape[1]
        optional = set(getattr(full, "optional", ()))
        # the optional parameters (held at their start) enter only through the init's drift
        model = restrict(full, [p for p in full.names if p not in optional])
        check_model(model, X, T, model.start(X))  # one line per way the model is unusable
        used = {v for v in full.parameters.values() if isinstance(v, str)}
        self.features_ = (list(self.features) if self.features is not None else
                          [str(c) for c in X.columns if str(c) not in used
                           and pd.api.types.is_numeric_dtype(X[c])])
        names = {str(c) for c in X.columns}  # a frame's columns by name, as str
        missing = [c for c in self.features_ if c not in names]
        if missing or not self.features_:
            raise ValueError(f"features {missing or '[]'} are not columns of X; columns are "
                             f"{[str(c) for c in X.columns]}")
        Z = self._inputs(X, fitting=True)
        if not np.all(np.isfinite(Z)):
            raise ValueError(f"the features {self.features_} have missing or non-finite values")
        self.feature_range_ = np.stack([Z.min(axis=0), Z.max(axis=0)])
        self.init_ = self._start(X, Y)
        model = restrict(full, getattr(self.init_, "parameter_names_", model.names))
        self.parameter_names_ = model.names
        boosted = list(self.parameters) if self.parameters is not None else model.names
        unknown = [p for p in boosted if p not in model.names]
        if unknown:
            raise ValueError(f"parameters names unknown parameter(s) {unknown}; the model's "
                             f"parameters are {model.names}")
        self._boosted = [model.names.index(p) for p in boosted]
        if self.out_of_bounds == "calibrated" and not hasattr(self.init_, "calibrated_parameters"):
            raise ValueError("out_of_bounds='calibrated' needs an init with "
                             "calibrated_parameters (a ParametricRegressor), got "
                             f"{type(self.init_).__name__}")
        self.calibration_ = self.init_.calibration_
        theta = self.init_.corrected_parameters(X).to_numpy(dtype=float)
        base = DecisionTreeRegressor(max_depth=3) if self.estimator is None else self.estimator
        self._weighted = self.step == "newton" and has_fit_parameter(base, "sample_weight")
        rng = np.random.default_rng(self.random_state)
        self.estimators_: list[dict[str, Any]] = []
        steps: list[float] = []
        r = Y - model.predict(theta, X, T)
        history = [_loss(self.loss, r, self.huber_delta)]
        for _ in range(self.n_estimators):
            seed = int(rng.integers(2**31 - 1))
            rows = (np.sort(rng.choice(len(X), max(2, int(round(self.subsample * len(X)))),
                                       replace=False)) if self.subsample < 1 else None)
            fits, D = self._round(model, X, Z, theta, r, base, seed, rows)
            moved = self._line_search(model, X, Y, theta, D, fits)
            if moved is None:
                break
            rho, fits, D = moved
            theta = theta + self.learning_rate * rho * D
            r = Y - model.predict(theta, X, T)
            self.estimators_.append(fits)
            steps.append(self.learning_rate * rho)
            history.append(_loss(self.loss, r, self.huber_delta))
        self.steps_ = np.asarray(steps)
        self.train_loss_ = np.asarray(history)
        self.n_iter_ = len(steps)
        return self

    def _round(self, model: ParametricModel, X: pd.DataFrame, Z: np.ndarray, theta: np.ndarray,
               r: np.ndarray, base: Any, seed: int,
               rows: np.ndarray | None) -> tuple[dict[str, Any], np.ndarray]:
        """One regressor per boosted parameter fitted to its pseudo-residuals; their
        predictions on every row (zero for the parameters not boosted)."""
        J = model.jacobian(theta, X, r.shape[1])
        w = PARAM_LOSSES[self.loss](r, self.huber_delta)[1]
        g = np.einsum("ntp,nt->np", J, w * r)
        h = np.einsum("ntp,nt->np", J ** 2, w)
        D = np.zeros_like(theta)
        fits: dict[str, Any] = {}
        sub = slice(None) if rows is None else rows
        for j in self._boosted:
            if self._weighted:
                ok = h[:, j] > 1e-12 * max(float(h[:, j].max()), np.finfo(float).tiny)
                target = np.where(ok, g[:, j] / np.where(ok, h[:, j], 1.0), 0.0)
                kw = {"sample_weight": np.where(ok, h[:, j], 0.0)[sub]}
            else:
                target = g[:, j] / max(float(h[:, j].mean()), np.finfo(float).tiny)
                kw = {}
            if not np.any(target[sub]):
                continue
            reg = clone(base)
            if "random_state" in reg.get_params():
                reg.set_params(random_state=seed)
            reg.fit(Z[sub], target[sub], **kw)
            fits[self.parameter_names_[j]] = reg
            D[:, j] = reg.predict(Z)
        return fits, D

    def _line_search(self, model: ParametricModel, X: pd.DataFrame, Y: np.ndarray,
                     theta: np.ndarray, D: np.ndarray,
                     fits: dict[str, Any]) -> tuple[float, dict[str, Any], np.ndarray] | None:
        """The step ``rho`` in [0, 2] minimising the loss along ``D`` (greedy: along the best
        single parameter's column); None where no step lowers it."""
        def objective(rho: float, d: np.ndarray) -> float:
            value = _trial(model, theta + self.learning_rate * rho * d, X, Y.shape[1])
            if value is None:
                return np.inf
            with np.errstate(over="ignore"):  # a trial far off: an infinite loss
                return _loss(self.loss, Y - value, self.huber_delta)

        now = objective(0.0, D)
        options = ([(name, self.parameter_names_.index(name)) for name in fits]
                   if self.update == "greedy" else [(None, -1)])
        best: tuple[float, float, str | None] = (now, 0.0, None)
        for name, j in options:
            d = D if name is None else np.where(np.arange(D.shape[1]) == j, D, 0.0)
            found = minimize_scalar(objective, bounds=(0.0, 2.0), args=(d,), method="bounded",
                                    options={"xatol": 1e-2})
            if found.fun < best[0]:
                best = (float(found.fun), float(found.x), name)
        if best[1] <= 0.0 or not fits:
            return None
        if best[2] is None:
            return best[1], fits, D
        j = self.parameter_names_.index(best[2])
        return best[1], {best[2]: fits[best[2]]}, np.where(np.arange(D.shape[1]) == j, D, 0.0)

    # ------------------------------------------------------------------ results
    def _staged_theta(self, X: pd.DataFrame) -> Iterator[np.ndarray]:
        check_is_fitted(self)
        theta = self.init_.corrected_parameters(X).to_numpy(dtype=float, copy=True)
        Z = self._inputs(X)
        held = np.zeros(len(X), dtype=bool)
        if self.out_of_bounds == "calibrated":  # beyond the box: the calibrated model
            held = self._outside(Z)
            if held.any():
                theta[held] = self.init_.calibrated_parameters(X).to_numpy(dtype=float)[held]
        yield theta
        for fits, step in zip(self.estimators_, self.steps_):
            D = np.zeros_like(theta)
            for name, reg in fits.items():
                D[:, self.parameter_names_.index(name)] = reg.predict(Z)
            D[held] = 0.0
            theta = theta + step * D
            yield theta

    def _out(self, theta: np.ndarray, X: pd.DataFrame) -> np.ndarray:
        """The model at ``theta``; rows where it is not finite (the boosted parameters left
        the model's domain) get the start model's prediction (:attr:`init_`'s)."""
        out = _predict_rows(restrict(resolve_model(self.model), self.parameter_names_), theta, X,
                            self.n_targets_)
        bad = np.flatnonzero(~np.isfinite(out).all(axis=1))
        if bad.size:
            out[bad] = np.reshape(self.init_.predict(X.iloc[bad]), (bad.size, -1))
        return out[:, 0] if self._y_1d else out

    def staged_predict(self, X: Any) -> Iterator[np.ndarray]:
        """The prediction after 0, 1, ..., ``n_iter_`` rounds.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            The rows (the user's model's data columns).

        Yields
        ------
        ndarray
            The prediction after each round, shaped as :meth:`predict`'s.
        """
        X = _frame(self, X, reset=False)
        for theta in self._staged_theta(X):
            yield self._out(theta, X)

    def _corrected(self, X: pd.DataFrame) -> np.ndarray:
        return deque(self._staged_theta(X), maxlen=1)[0]

    def predict(self, X: Any) -> np.ndarray:
        """The model at the boosted parameters.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            The rows (the user's model's data columns).

        Returns
        -------
        ndarray
            ``(rows,)`` if fitted on one-dimensional ``y``, else ``(rows, targets)``.
        """
        X = _frame(self, X, reset=False)
        return self._out(self._corrected(X), X)

    def corrected_parameters(self, X: Any) -> pd.DataFrame:
        """The boosted parameters per row.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            The rows (the user's model's data columns).

        Returns
        -------
        DataFrame
            One column per parameter, indexed like ``X``.
        """
        X = _frame(self, X, reset=False)
        return pd.DataFrame(self._corrected(X), columns=self.parameter_names_, index=X.index)

    def start_parameters(self, X: Any) -> pd.DataFrame:
        """The model's start values per row (the prior's parameters).

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            The rows (the user's model's data columns).

        Returns
        -------
        DataFrame
            One column per parameter, indexed like ``X``.
        """
        check_is_fitted(self)
        return self.init_.start_parameters(_frame(self, X, reset=False))

    def coefficient_table(self) -> pd.DataFrame:
        """The start's linear coefficients (``init_``'s: the calibrated offsets, or the
        drift's); the boosted part has none.

        Returns
        -------
        DataFrame
            ``init_``'s coefficient table.
        """
        return self.init_.coefficient_table()

    def __sklearn_tags__(self) -> Any:
        """Multi-output: one column per target of the user's model."""
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True  # one column per target of the user's model
        return tags

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "estimators_")

