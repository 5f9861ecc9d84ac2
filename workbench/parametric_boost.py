"""Any physics model, corrected in its own parameter space.

:class:`ParametricRegressor` fits ``y ~ f(theta(x); x)`` for a user's model ``f``
(:mod:`workbench.parametric`): ``theta_p(x) = start_p(x) + delta_p(x)`` with
``delta_p(x) = phi_p(x) . c_p`` linear in standardised covariates (an intercept, the
calibration offset, and the covariates it is given). It first calibrates the intercepts
globally (Kennedy and O'Hagan's calibration: :func:`scipy.optimize.least_squares` with a
robust loss), then fits every coefficient by the parameter-space engine the Hamiltonian
family uses too (:class:`workbench.param_engine.DriftRegressor`: the same normal equations,
IRLS and Newton weights, ridge and L1 penalties), with the model's Jacobian or central finite
differences. The model may be a model object, e.g.
:class:`workbench.hamiltonian.HamiltonianModel` (the Hamiltonian family's physics, with its
Hellmann-Feynman Jacobian).

:class:`ParametricBoostRegressor` chooses by cross-validation on the rows it is given among
the prior (the model at its start values), the calibrated model (no drift) and linear
drifts whose covariates forward selection picks (:mod:`workbench.param_select`'s engine).
"""

from __future__ import annotations

import hashlib
import numbers
import os
import time
from collections.abc import Callable, Sequence
from itertools import combinations
from typing import Any, Self

import numpy as np
import pandas as pd
from scipy.optimize import least_squares
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from ._covariates import column, term, variable
from ._progress import Progress
from .parallel import effective_n_jobs
from .param_engine import PARAM_LOSSES, SOLVERS, DriftRegressor
from .param_engine import drift as _drift
from .param_select import (
    SELECTION_METHODS,
    SelectionResult,
    _cv_splits,
    _fit_splits,
    _linearised_select,
    _refit_select,
    _sliced,
)
from .parametric import (
    ModelError,
    ParametricModel,
    check_model,
    resolve_model,
    restrict,
)

__all__ = ["ParametricBoostRegressor", "ParametricRegressor", "boost_candidate", "covariate_pool",
           "ridge_drift"]

#: ``out_of_bounds``: what a new row beyond the training rows gets.
OUT_OF_BOUNDS = ("extrapolate", "clip", "calibrated")

#: scipy's robust losses for the calibration, by the regressor's ``loss``.
_SCIPY_LOSS = {"squared_error": "linear", "absolute_error": "soft_l1", "huber": "huber"}

_MODEL = [str, os.PathLike, HasMethods(["predict", "jacobian", "start"])]




def covariate_pool(features: Sequence[str], parameters: Sequence[str], *, squares: bool = True,
                   products: bool = True) -> dict[str, list[str]]:
    """Return every parameter's candidate covariates.

    The features, their squares and their pairwise products (each standardised when fitted).

    Parameters
    ----------
    features : sequence of str
        The columns.
    parameters : sequence of str
        The model's parameters.
    squares, products : bool, default=True
        Whether to add the squares, the pairwise products.

    Returns
    -------
    dict of str -> list of str
        The same candidates for every parameter.
    """
    f = list(features)
    names = f + ([f"{a}^2" for a in f] if squares else []) + (
        [f"{a}*{b}" for a, b in combinations(f, 2)] if products else [])
    return {p: list(names) for p in parameters}



def _targets(y: Any) -> np.ndarray:
    if y is None:
        raise ValueError("this regressor requires y to be passed, but the target y is None")
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or not np.all(np.isfinite(y)):
        raise ValueError("y must be finite, of shape (rows,) or (rows, targets)")
    return y


def _as_frame(est: BaseEstimator, X: Any, reset: bool) -> pd.DataFrame:
    """``X`` as a DataFrame: a frame as is (columns by name), an array checked by
    scikit-learn (columns ``x0``, ``x1``, ...); sets the fitted input attributes on
    ``reset``."""
    if isinstance(X, pd.DataFrame):
        if len(X) == 0:
            raise ValueError("X has no rows")
        if reset:
            est.n_features_in_ = X.shape[1]
            est.feature_names_in_ = np.asarray([str(c) for c in X.columns], dtype=object)
        return X
    values = validate_data(est, X, reset=reset, dtype="numeric")
    return pd.DataFrame(values, columns=[f"x{j}" for j in range(values.shape[1])])


def _trial(model: ParametricModel, theta: np.ndarray, X: pd.DataFrame,
           n_targets: int) -> np.ndarray | None:
    """The model at trial parameters, or None where it fails there (NaN, an error): a trial
    step may leave the model's domain (a negative lifetime) where its start did not."""
    try:
        with np.errstate(all="ignore"):
            return model.predict(theta, X, n_targets)
    except ModelError:
        return None


def _predict_rows(model: Any, theta: np.ndarray, X: pd.DataFrame,
                 n_targets: int) -> np.ndarray:
    """``model``'s prediction at ``theta``, NaN or infinite where it returns them
    (:meth:`~workbench.parametric.ParametricModel.predict_rows`; a model object without
    that method, such as a spectrum that is always finite, through its ``predict``)."""
    rows = getattr(model, "predict_rows", None)
    return np.array((rows or model.predict)(theta, X, n_targets), dtype=float)


def _fingerprint(X: pd.DataFrame, Y: np.ndarray) -> str:
    """A digest of the rows a fit sees (a warm start's calibration is reused only on the
    same rows)."""
    digest = hashlib.blake2b(pd.util.hash_pandas_object(X, index=False).to_numpy().tobytes(),
                             digest_size=16)
    digest.update(np.ascontiguousarray(Y, dtype=float).tobytes())
    return digest.hexdigest()


class _WarmStart(dict):
    """:meth:`ParametricRegressor.coef_dict`: the coefficients, and the fit's calibration
    with the digest of its rows and its parameters' names (``out_of_bounds="calibrated"``
    reuses it on the same rows and parameters instead of calibrating again)."""

    calibration: tuple[str, tuple[str, ...], np.ndarray] | None = None


class ParametricRegressor(DriftRegressor):
    """A user's physics model with parameters calibrated and drifting linearly in covariates.

    ``predict(X) = f(start(X) + delta(X); X)``, ``delta_p(x) = c_p0 + sum_k c_pk z_pk(x)``:
    ``z_pk`` the covariates of ``covariates[p]`` (a column, a product ``a*b`` of two columns
    (each factor centred), a difference ``a-b``, a geometric mean ``sqrt|a*b|``, optionally to
    a power ``^k`` after centring; standardised with the training rows' mean and sd). The
    coefficients are in the parameter's units per covariate sd. A model's optional parameters
    (the model file's ``OPTIONAL``; a Hamiltonian's parasitic couplings) are fitted only where
    ``covariates`` names them (``["intercept"]``: the offset alone); the others stay at their
    start values, outside :attr:`parameter_names_`.

    ``fit`` calibrates the intercepts ``c_p0`` first (``calibrate``: robust least squares
    over the training rows, the loss matching ``loss``), then minimises ``sum rho(y - f) +
    alpha / 2 ||c||^2 + alpha_l1 ||c||_1`` (intercepts unpenalised) by Gauss-Newton with IRLS
    weights and step halving, as
    :class:`~workbench.param_boost.HamiltonianParameterRegressor` does.

    Parameters
    ----------
    model : str or ParametricModel
        The path of a model file (:func:`~workbench.parametric.load_model`) or a model.
    covariates : dict of str -> list of str, default=None
        Each parameter's covariates (None or a parameter left out: intercept only, the
        calibrated model; an optional parameter left out or given none is held at its
        start).
    calibrate : bool, default=True
        Start from the robust global calibration of the intercepts (else from 0).
    alpha, alpha_l1 : float, default=1.0, 0.0
        Ridge and L1 penalties of the non-intercept coefficients.
    loss : {"squared_error", "absolute_error", "huber"}, default="huber"
    huber_delta : float, default=1.0
        Huber's threshold (targets' units); also the calibration's ``f_scale``.
    max_iter : int, default=20
        Gauss-Newton iterations (0: the calibrated model, or the start values without
        ``calibrate``).
    tol : float, default=1e-6
        Relative decrease of the objective below which iteration stops.
    out_of_bounds : {"extrapolate", "clip", "calibrated"}, default="extrapolate"
        What a new row outside the box the training rows span (any covariate's column,
        product or difference beyond its training range) gets. ``"extrapolate"``: the
        drift's corrections there. ``"clip"``: the columns the covariates are made of are
        clipped to their training range, so its corrections are the drift's at the nearest
        point of the training rows' box. ``"calibrated"``: the calibrated model's
        parameters (no drift): the drift's corrections compensate each other through the
        model's own variables (a nucleus' mass number), which keep changing beyond the box
        where clipped or clamped corrections no longer do; the calibrated parameters are the
        one set fitted to all training rows at once. Rows inside the box are unchanged.
    solver : {"newton", "irls"}, default="newton"
        The Gauss-Newton weights near the optimum (:func:`~workbench.param_engine.gauss_newton`):
        the loss's curvature once an iteration gains less than 10 %, stopping where such a
        step finds no decrease, or IRLS weights throughout (the Hamiltonian family's
        default: with ``calibrate=False`` and the Hamiltonian model object this is
        :class:`~workbench.param_boost.HamiltonianParameterRegressor`'s fit).

    Attributes
    ----------
    parameter_names_ : list of str
        The parameters fitted (the optional ones only where ``covariates`` names them).
    covariate_names_ : dict of str -> list of str
        Each parameter's covariates, ``"intercept"`` first.
    calibration_ : DataFrame
        Per parameter its start (a value or a column's name) and the calibrated offset.
    n_iter_ : int
    train_loss_ : ndarray
    n_targets_ : int
    column_range_ : dict of str -> (float, float)
        The training range of every column the covariates are made of.
    variable_range_ : dict of str -> (float, float)
        The training range of every covariate's column, product or difference (the box).
    calibrated_offset_ : ndarray of shape (n_parameters,)
        With ``out_of_bounds="calibrated"``: the calibration's offsets on the training rows
        (computed even with ``calibrate=False``), the parameters a row outside the box gets.
    """

    _parameter_constraints: dict = {
        "model": _MODEL,
        "covariates": [None, dict],
        "calibrate": ["boolean"],
        "alpha": [Interval(numbers.Real, 0, None, closed="left")],
        "alpha_l1": [Interval(numbers.Real, 0, None, closed="left")],
        "loss": [StrOptions(set(PARAM_LOSSES))],
        "huber_delta": [Interval(numbers.Real, 0, None, closed="neither")],
        "max_iter": [Interval(numbers.Integral, 0, None, closed="left")],
        "tol": [Interval(numbers.Real, 0, None, closed="left")],
        "out_of_bounds": [StrOptions(set(OUT_OF_BOUNDS))],
        "solver": [StrOptions(set(SOLVERS))],
    }

    def __init__(self, *, model: str | ParametricModel | None = None,
                 covariates: dict[str, list[str]] | None = None, calibrate: bool = True,
                 alpha: float = 1.0, alpha_l1: float = 0.0, loss: str = "huber",
                 huber_delta: float = 1.0, max_iter: int = 20, tol: float = 1e-6,
                 out_of_bounds: str = "extrapolate", solver: str = "newton") -> None:
        self.model = model
        self.covariates = covariates
        self.calibrate = calibrate
        self.alpha = alpha
        self.alpha_l1 = alpha_l1
        self.loss = loss
        self.huber_delta = huber_delta
        self.max_iter = max_iter
        self.tol = tol
        self.out_of_bounds = out_of_bounds
        self.solver = solver

    # ------------------------------------------------------------------ design
    def _values(self, X: pd.DataFrame, name: str) -> np.ndarray:
        var = variable(name, self._columns)
        assert var is not None
        if len(var) == 1:
            values = column(X, name)
            if self.out_of_bounds == "clip" and name in self.column_range_:
                values = np.clip(values, *self.column_range_[name])
            return values
        return self._combined(var, self._values(X, var[1]), self._values(X, var[2]))

    def _combined(self, var: tuple[str, ...], va: np.ndarray, vb: np.ndarray) -> np.ndarray:
        """The variable ``var`` (:func:`workbench._covariates.variable`'s) of two columns."""
        op, a, b = var
        if op == "-":
            return va - vb
        if op == "gm":
            return np.sqrt(np.abs(va * vb))
        return (va - self.factor_mean_[a]) * (vb - self.factor_mean_[b])

    def _design(self, X: pd.DataFrame, fitting: bool) -> list[np.ndarray]:
        n = len(X)
        if fitting:
            self.column_range_ = {}
            columns = {c for ts in self.terms_.values() for v, _ in ts
                       for c in (variable(v, self._columns) or ())[-2:] if c in self._columns}
            for c in sorted(columns):
                values = self._values(X, c)
                self.column_range_[c] = (float(np.nanmin(values)), float(np.nanmax(values)))
            self.factor_mean_ = {}
            for ts in self.terms_.values():
                for v, _ in ts:
                    var = variable(v, self._columns)
                    if var and var[0] == "*":
                        for f in var[1:]:
                            self.factor_mean_[f] = float(self._values(X, f).mean())
            self.var_mean_, self.col_mean_, self.col_scale_ = {}, {}, {}
            self.variable_range_: dict[str, tuple[float, float]] = {}
        cache: dict[str, np.ndarray] = {}
        phis = []
        for p in self.parameter_names_:
            cols = []
            for v, k in self.terms_[p]:
                if v not in cache:
                    cache[v] = self._values(X, v)
                    if fitting:
                        self.var_mean_[v] = float(cache[v].mean())
                        self.variable_range_[v] = (float(np.min(cache[v])),
                                                   float(np.max(cache[v])))
                cols.append((cache[v] - self.var_mean_[v]) ** k)
            raw = np.column_stack(cols) if cols else np.empty((n, 0))
            if not np.all(np.isfinite(raw)):
                raise ValueError(f"the covariates of parameter {p!r} have missing or "
                                 "non-numeric values")
            if fitting:
                sd = raw.std(axis=0)
                self.col_mean_[p] = raw.mean(axis=0)
                self.col_scale_[p] = np.where(sd > 0, sd, 1.0)
            phis.append(np.column_stack([np.ones(n),
                                         (raw - self.col_mean_[p]) / self.col_scale_[p]]))
        return phis

    def _setup(self, X: Any, y: Any) -> tuple[ParametricModel, np.ndarray, np.ndarray,
                                              list[np.ndarray]]:
        full = resolve_model(self.model)
        Y = _targets(y)
        self._y_1d = np.asarray(y).ndim == 1
        if len(Y) != len(X):
            raise ValueError(f"X has {len(X)} rows and y {len(Y)}")
        covariates = self.covariates or {}
        unknown = [p for p in covariates if p not in full.parameters]
        if unknown:
            raise ValueError(f"covariates name unknown parameter(s) {unknown}; the model's "
                             f"parameters are {full.names}")
        # an optional parameter is fitted only where its covariates are named
        optional = set(getattr(full, "optional", ()))
        model = restrict(full, [p for p in full.names if p not in optional or covariates.get(p)])
        self.parameter_names_ = model.names
        self._columns = {str(c) for c in X.columns}
        # "intercept": the parameter's offset alone (an optional parameter's way in)
        named = {p: [c for c in dict.fromkeys(covariates.get(p, [])) if c != "intercept"]
                 for p in model.names}
        self.terms_ = {p: [term(c, self._columns) for c in named[p]] for p in model.names}
        self.covariate_names_ = {p: ["intercept", *named[p]] for p in model.names}
        self.n_targets_ = Y.shape[1]
        start = model.start(X)
        phis = self._design(X, fitting=True)
        self._layout(phis)
        self._index = [(p, c) for p in model.names for c in self.covariate_names_[p]]
        return model, start, Y, phis

    def _calibrate(self, model: ParametricModel, X: pd.DataFrame, start: np.ndarray,
                   Y: np.ndarray) -> np.ndarray:
        """Robust global offsets of the parameters (the calibration)."""
        T = Y.shape[1]

        def resid(b: np.ndarray) -> np.ndarray:
            value = _trial(model, start + b, X, T)  # NaN outside the model's domain:
            return np.full(Y.size, np.nan) if value is None else (value - Y).ravel()

        def jac(b: np.ndarray) -> np.ndarray:
            return model.jacobian(start + b, X, T).reshape(-1, len(b))

        fit = least_squares(resid, np.zeros(start.shape[1]), jac=jac,
                            loss=_SCIPY_LOSS[self.loss], f_scale=float(self.huber_delta),
                            x_scale="jac", max_nfev=50 * start.shape[1])
        return fit.x

    def fit(self, X: pd.DataFrame, y: Any, coef_init: Any = None) -> Self:
        """Calibrate, then fit the corrections' coefficients on ``X`` and ``y``.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.
        y : array-like of shape (n_samples,) or (n_samples, n_targets)
            The measured targets.
        coef_init : dict, default=None
            Starting coefficients keyed by (parameter, covariate) (another fit's
            :meth:`coef_dict`); then the calibration is skipped (a warm start). With
            ``out_of_bounds="calibrated"`` a :meth:`coef_dict` of a fit on the same rows
            also hands over its calibration; on other rows it is computed again.

        Returns
        -------
        self
            The fitted model.
        """
        self._validate_params()
        X = _as_frame(self, X, reset=True)
        model, start, Y, phis = self._setup(X, y)
        check_model(model, X, Y.shape[1], start)  # one line per way the model is unusable
        penalty = self._penalty()
        c = self._coef_start(coef_init, self._index)
        if coef_init is None and self.calibrate:
            c[[s.start for s in self._slices]] = self._calibrate(model, X, start, Y)
        if self.out_of_bounds == "calibrated":
            self.calibrated_offset_ = self._held(model, X, start, Y, c, coef_init)
        self.calibration_ = pd.DataFrame({
            "parameter": model.names,
            "start": [v if isinstance(v, str) else float(v)
                      for v in (model.parameters[p] for p in model.names)],
            "offset": c[[s.start for s in self._slices]]})
        # "newton": Newton weights once close to the optimum, stopping where a step finds no
        # decrease; "irls": IRLS weights throughout
        self._fit_drift(model, X, start, Y, phis, c, penalty, solver=self.solver,
                        irls_fallback=False)
        return self

    def _held(self, model: ParametricModel, X: pd.DataFrame, start: np.ndarray, Y: np.ndarray,
              c: np.ndarray, coef_init: Any) -> np.ndarray:
        """The calibrated offsets a row outside the box gets: this fit's calibration, a warm
        start's from the same rows, or a calibration computed for it."""
        self._rows_digest = _fingerprint(X, Y)
        if coef_init is None and self.calibrate:
            return c[[s.start for s in self._slices]].copy()
        handed = getattr(coef_init, "calibration", None)
        # the same rows and parameters (an optional parameter brought in changes the set)
        if (handed is not None and len(handed) == 3 and handed[0] == self._rows_digest
                and tuple(handed[1]) == tuple(model.names)):
            return np.asarray(handed[2], dtype=float).copy()
        return self._calibrate(model, X, start, Y)

    def coef_dict(self) -> dict[tuple[str, str], float]:
        """``{(parameter, covariate): coefficient}`` (a cheap ``coef_init``); with
        ``out_of_bounds="calibrated"`` it also carries the calibration for a fit on the
        same rows.

        Returns
        -------
        dict
            ``(parameter, covariate)`` -> coefficient.
        """
        out = _WarmStart(super().coef_dict())
        if hasattr(self, "calibrated_offset_") and hasattr(self, "_rows_digest"):
            out.calibration = (self._rows_digest, tuple(self.parameter_names_),
                               self.calibrated_offset_)
        return out

    def outside(self, X: pd.DataFrame) -> np.ndarray:
        """Tell which rows lie outside the box the training rows span.

        Outside: any covariate's column, product or difference beyond its training range
        (:attr:`variable_range_`); a model without covariates has no box.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        ndarray of bool, shape (n_samples,)
            True where the row lies outside the training rows' box.
        """
        check_is_fitted(self)
        X = _as_frame(self, X, reset=False)
        out = np.zeros(len(X), dtype=bool)
        for v, (low, high) in self.variable_range_.items():
            var = variable(v, self._columns)
            assert var is not None
            values = (column(X, v) if len(var) == 1 else
                      self._combined(var, *(column(X, f) for f in var[1:])))
            out |= ~((values >= low) & (values <= high))
        return out

    def calibrated_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """The calibrated model's parameters per row, ``start(X) + calibrated_offset_``
        (``out_of_bounds="calibrated"`` only).

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        pandas.DataFrame
            One column per parameter, indexed as ``X``.
        """
        check_is_fitted(self, "calibrated_offset_")
        X = _as_frame(self, X, reset=False)
        return pd.DataFrame(self._physics().start(X) + self.calibrated_offset_,
                            columns=self.parameter_names_, index=X.index)

    # ------------------------------------------------------------------ results
    def _corrected(self, X: Any) -> np.ndarray:
        """``start + drift`` per row; with ``out_of_bounds="calibrated"`` the calibrated
        parameters on the rows outside the box."""
        data, start, phis = self._rows(X)
        theta = start + _drift(phis, self._coef)
        if self.out_of_bounds == "calibrated":
            out = self.outside(data)
            theta[out] = start[out] + self.calibrated_offset_
        return theta

    def coef_jacobian(self, X: pd.DataFrame) -> np.ndarray:
        """``d predict(X)[j, k] / d coef[d]`` at the fitted coefficients (zero on the rows
        the guard gives the calibrated parameters).

        Parameters
        ----------
        X : DataFrame
            The rows.

        Returns
        -------
        ndarray of shape (rows, targets, coefficients)
            In :attr:`coef_`'s order.
        """
        out = super().coef_jacobian(X)
        if self.out_of_bounds == "calibrated":
            out[self.outside(_as_frame(self, X, reset=False))] = 0.0
        return out

    def _physics(self) -> ParametricModel:
        """The model fitted: the optional parameters without covariates held."""
        check_is_fitted(self)
        return restrict(resolve_model(self.model), self.parameter_names_)

    def _n_outputs(self) -> int:
        return int(self.n_targets_)

    def _rows(self, X: Any) -> tuple[pd.DataFrame, np.ndarray, list[np.ndarray]]:
        check_is_fitted(self)
        X = _as_frame(self, X, reset=False)
        return X, self._physics().start(X), self._design(X, fitting=False)

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """The model at the corrected parameters: ``(rows,)`` if fitted on one-dimensional
        ``y``, else ``(rows, targets)``.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        ndarray
            The predictions.
        """
        model = self._physics()
        X = _as_frame(self, X, reset=False)
        out = self._in_domain(model, X, self._corrected(X))[0]
        return out[:, 0] if self._y_1d else out

    def outside_domain(self, X: pd.DataFrame) -> np.ndarray:
        """Tell on which rows the corrected parameters leave the model's domain.

        There the model returns NaN or infinite values (a drift that takes a lifetime
        below zero under a square root, say), and :meth:`predict` gives those rows the
        model at its calibrated parameters (the calibration's offsets, or a warm start's
        intercepts), else at its start values.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        ndarray of bool, shape (n_samples,)
            True where the corrected model is not finite.
        """
        model = self._physics()
        X = _as_frame(self, X, reset=False)
        return self._in_domain(model, X, self._corrected(X))[1]

    def _in_domain(self, model: ParametricModel, X: pd.DataFrame,
                   theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The model at ``theta``, and where it is not finite, at the calibrated parameters,
        else at the start values; and the rows so replaced. A row not finite even at its
        start values is a :class:`ModelError`."""
        values = _predict_rows(model, theta, X, self.n_targets_)
        replaced = ~np.isfinite(values).all(axis=1)
        rows = np.flatnonzero(replaced)
        if rows.size:
            start = model.start(X.iloc[rows])
            offsets = self.calibration_["offset"].to_numpy(dtype=float)
            pending = np.ones(rows.size, dtype=bool)
            for fallback in (start + offsets, start):
                idx = np.flatnonzero(pending)
                sub = _predict_rows(model, fallback[idx], X.iloc[rows[idx]], self.n_targets_)
                ok = np.isfinite(sub).all(axis=1)
                values[rows[idx[ok]]] = sub[ok]
                pending[idx[ok]] = False
                if not pending.any():
                    break
            if pending.any():
                bad = rows[pending]
                raise ModelError(f"model {model.source}: predict returned NaN or infinite "
                                 f"values on {bad.size} of {len(X)} rows even at its start "
                                 f"values (first rows: {bad[:5].tolist()})")
        return values, replaced

    def corrected_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """``start(X) + delta(X)`` per row, one column per parameter.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        pandas.DataFrame
            One column per parameter, indexed as ``X``.
        """
        return pd.DataFrame(self._corrected(X), columns=self.parameter_names_, index=X.index)

    def start_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """The model's start values per row (the prior's parameters).

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        pandas.DataFrame
            One column per parameter, indexed as ``X``.
        """
        check_is_fitted(self)
        return pd.DataFrame(self._physics().start(X), columns=self.parameter_names_,
                            index=X.index)

    def __sklearn_tags__(self) -> Any:
        """Multi-output: one column per target of the user's model."""
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True  # one column per target of the user's model
        return tags

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "_coef")


#: :class:`ParametricBoostRegressor`'s ``min_improvement`` is at most this share of the
#: prior's MAE on the training rows.
MIN_IMPROVEMENT_SHARE = 1e-2

#: The candidates :class:`ParametricBoostRegressor` compares, simplest first.
CANDIDATES = ("prior", "calibrated", "drift", "ridge_drift", "boost")

#: ``drift``: how the drift candidates are made (forward selection, ridge over the whole pool).
DRIFTS = ("forward", "ridge", "both")

#: ``method="linearised"``: the best-scored single candidates refitted exactly each step
#: (:func:`~workbench.param_select.forward_select`'s ``shortlist``).
LINEARISED_SHORTLIST = 5

#: The ridge drift's penalties, chosen by the choice's CV (largest first: warm starts).
RIDGE_ALPHAS = (1e4, 1e3, 1e2, 1e1, 1.0, 1e-1, 1e-2)


class ParametricBoostRegressor(RegressorMixin, BaseEstimator):
    """A user's model calibrated, with parameter drifts chosen by CV, or neither.

    ``fit`` scores on the same CV folds of the rows it is given (``cv``): the prior
    (the model at its start values; no fit, so its training MAE), the calibrated model
    (:class:`ParametricRegressor` without covariates) and the linear drift whose covariates
    forward selection chooses from ``start`` over ``candidates``
    (:func:`workbench.param_select.forward_select`'s engine: each candidate refitted on
    every split, warm-started). A more complex candidate wins only by more than
    ``min_improvement``; the winner is refitted on all rows (``estimator_``).
    :attr:`choices_` tells the CV MAE of each and which won; where the drift does not win,
    :attr:`note_` says the error is not a drift of the parameters. With ``drift="ridge"``
    (or ``"both"``) the ``"ridge_drift"`` candidate replaces (or joins) the forward drift:
    every parameter drifts in its whole pool (``start`` and ``candidates``), no selection,
    its ridge penalty chosen from ``ridge_alphas`` on the same folds. With ``boost``, the
    parameter-space boosting (:mod:`workbench.parametric_gbm`, any scikit-learn regressor
    per parameter) is a further candidate, its rounds chosen on the same folds.

    Parameters
    ----------
    model : str or ParametricModel
        The path of a model file or a model.
    start : dict of str -> list of str, default=None
        Covariates every drift model has (None: intercepts only).
    candidates : "auto", dict of str -> list of str or None, default="auto"
        The selection's pool; ``"auto"``: :func:`covariate_pool` of ``features`` for every
        parameter, and ``"intercept"`` first for an optional one (the term as a constant);
        None: no drift candidate.
    features : list of str, default=None
        The columns the ``"auto"`` pool is built from (None: every numeric column of ``X``
        that is no parameter's column).
    squares, products : bool, default=True
        Whether the ``"auto"`` pool has the features' squares and pairwise products.
    cv : int or CV splitter, default=5
        The folds of every choice (the covariates, the candidate, the boosting's rounds):
        an int, ``RepeatedKFold(cv, n_repeats)`` seeded by ``random_state``; a splitter,
        its folds of ``X`` (e.g. the forward-chaining
        :class:`~workbench.selection.LabelTimeSeriesSplit`, which looks the rows up by
        ``X``'s index).
    n_repeats : int, default=1
        The repeats of an int ``cv`` (a splitter's folds are made once: it must be 1).
    max_steps : int, default=20
        The most covariates the selection adds (``"linearised"``: the most steps).
    method : {"refit", "linearised"}, default="refit"
        How the forward selection scores a candidate: ``"refit"`` fits the model with it on
        every fold; ``"linearised"`` takes one Gauss-Newton step of the enlarged model from
        the current fit on every fold (:func:`~workbench.param_linear.linear_scores`, the
        whole model's Jacobian, no refit) and refits only the best-scored candidates
        (:func:`~workbench.param_select.forward_select`'s ``method``: for large pools and
        models whose fits cost much).
    min_improvement : float, default=1e-3
        The CV MAE (targets' units) a covariate, or a more complex candidate, must gain; at
        most :data:`MIN_IMPROVEMENT_SHARE` of the prior's MAE on the training rows
        (:attr:`min_improvement_`), so that targets in small units (1e-9 s) can leave the
        prior.
    drift : {"forward", "ridge", "both"}, default="forward"
        The drift candidates: ``"forward"``, covariates chosen by forward selection (fitted
        with ``alpha``); ``"ridge"``, the ``"ridge_drift"`` candidate, every parameter's
        whole pool at once with the ridge penalty CV picks from ``ridge_alphas`` (no
        selection: many covariates, shrunk); ``"both"``, the two, CV choosing.
    ridge_alphas : sequence of float, default=None
        The ridge drift's penalties (None: :data:`RIDGE_ALPHAS`, 1e-2 to 1e4).
    alpha, alpha_l1, loss, huber_delta, max_iter, tol, out_of_bounds, calibrate, solver
        :class:`ParametricRegressor`'s (``calibrate=False``: the calibrated candidate's and
        the drift's fits start their offsets at 0; a ``boost`` template with ``init=None``
        still starts from its own calibration).
    random_state : int, default=None
        Seeds the splits (None: 0).
    n_jobs : int, default=None
        Processes scoring the selection's candidates (:mod:`workbench.parallel`).
    verbose : bool, default=False
        Report what ``fit`` does, a line per phase, CV fold and selection step (e.g.
        ``parametric: selection step 3: a_s <- Z*N  cv_mae=1.7400 (12 s)``): INFO records of
        the ``workbench.parametric_boost`` logger, or printed to standard error where no
        logging is set up (:mod:`workbench._progress`). No number depends on it.
    boost : ParameterSpaceBoostRegressor, default=None
        The ``"boost"`` candidate's template (None: no such candidate); its ``model``,
        ``loss``, ``huber_delta``, ``out_of_bounds`` and ``random_state`` are set from
        these.

    Attributes
    ----------
    estimator_ : ParametricRegressor or ParameterSpaceBoostRegressor
        The winner, refitted on all rows.
    choice_ : str
        ``"prior"``, ``"calibrated"``, ``"drift"``, ``"ridge_drift"`` or ``"boost"``.
    choices_ : DataFrame
        ``candidate``, ``cv_mae``, ``chosen``.
    note_ : str
    other_candidates_ : dict of str -> estimator
        The candidates CV scored but did not choose, unfitted with their choices made
        (covariates, ridge penalty, boosting rounds), simplest first, the prior and a boost
        of 0 rounds (its start model) left out:
        :class:`~workbench.fitted_prior.FittedPriorBoost`'s ``alternative="candidates"``
        fits the stage on each of them.
    selection_ : SelectionResult or None
        The forward selection (its path).
    ridge_path_ : DataFrame or None
        With a ridge drift: ``alpha``, ``cv_mae`` and ``chosen`` per penalty tried.
    cv_splits_ : list of (fit, validation) index arrays
        The folds every choice was scored on (positions into ``X``).
    cv_mae_ : float
        The winner's CV MAE.
    min_improvement_ : float
        The gain the selection and the choice asked for: ``min_improvement``, at most
        :data:`MIN_IMPROVEMENT_SHARE` of the prior's training MAE.
    n_iter_ : int
        The winner's Gauss-Newton iterations.
    """

    _parameter_constraints: dict = {
        "model": _MODEL,
        "start": [None, dict],
        "candidates": [None, StrOptions({"auto"}), dict],
        "features": [None, list, tuple],
        "squares": ["boolean"],
        "products": ["boolean"],
        "cv": [Interval(numbers.Integral, 2, None, closed="left"),
               HasMethods(["split", "get_n_splits"])],
        "n_repeats": [Interval(numbers.Integral, 1, None, closed="left")],
        "max_steps": [Interval(numbers.Integral, 0, None, closed="left")],
        "method": [StrOptions(set(SELECTION_METHODS))],
        "min_improvement": [Interval(numbers.Real, 0, None, closed="left")],
        "drift": [StrOptions(set(DRIFTS))],
        "ridge_alphas": [None, "array-like"],
        **{k: v for k, v in ParametricRegressor._parameter_constraints.items()
           if k not in ("model", "covariates")},
        "random_state": [None, numbers.Integral],
        "n_jobs": [None, numbers.Integral],
        "verbose": ["boolean"],
        "boost": [None, HasMethods(["fit", "staged_predict"])],
    }

    def __init__(self, *, model: str | ParametricModel | None = None,
                 start: dict[str, list[str]] | None = None,
                 candidates: str | dict[str, list[str]] | None = "auto",
                 features: Sequence[str] | None = None, squares: bool = True,
                 products: bool = True, cv: Any = 5, n_repeats: int = 1, max_steps: int = 20,
                 method: str = "refit", min_improvement: float = 1e-3, drift: str = "forward",
                 ridge_alphas: Sequence[float] | None = None, alpha: float = 1.0,
                 alpha_l1: float = 0.0,
                 loss: str = "huber", huber_delta: float = 1.0, max_iter: int = 20,
                 tol: float = 1e-6, out_of_bounds: str = "extrapolate", calibrate: bool = True,
                 solver: str = "newton", random_state: int | None = None,
                 n_jobs: int | None = None, verbose: bool = False, boost: Any = None) -> None:
        self.model = model
        self.start = start
        self.candidates = candidates
        self.features = features
        self.squares = squares
        self.products = products
        self.cv = cv
        self.n_repeats = n_repeats
        self.max_steps = max_steps
        self.method = method
        self.min_improvement = min_improvement
        self.drift = drift
        self.ridge_alphas = ridge_alphas
        self.alpha = alpha
        self.alpha_l1 = alpha_l1
        self.loss = loss
        self.huber_delta = huber_delta
        self.max_iter = max_iter
        self.tol = tol
        self.out_of_bounds = out_of_bounds
        self.calibrate = calibrate
        self.solver = solver
        self.random_state = random_state
        self.n_jobs = n_jobs
        self.verbose = verbose
        self.boost = boost

    def candidate_pool(self, X: pd.DataFrame) -> dict[str, list[str]]:
        """Return the selection's pool on the rows ``X``: each parameter's candidate
        covariates (``candidates``, or the ``"auto"`` pool of ``features``).

        Parameters
        ----------
        X : pandas.DataFrame
            The rows (the ``"auto"`` pool's columns without ``features``).

        Returns
        -------
        dict of str -> list of str
            Parameter -> its candidate covariates (empty with ``candidates=None``).
        """
        return self._pool(resolve_model(self.model), X)

    def _pool(self, model: ParametricModel, X: pd.DataFrame) -> dict[str, list[str]]:
        if self.candidates is None:
            return {}
        if isinstance(self.candidates, dict):
            return {p: list(v) for p, v in self.candidates.items()}
        if self.features is not None:
            features = list(self.features)
        else:
            used = {v for v in model.parameters.values() if isinstance(v, str)}
            features = [str(c) for c in X.columns if str(c) not in used
                        and pd.api.types.is_numeric_dtype(X[c])]
        pool = covariate_pool(features, model.names, squares=self.squares,
                              products=self.products)
        for p in getattr(model, "optional", ()):  # an optional term may enter as a constant
            pool[p] = ["intercept", *pool[p]]
        return pool

    def _alphas(self) -> list[float]:
        alphas = RIDGE_ALPHAS if self.ridge_alphas is None else self.ridge_alphas
        out = sorted((float(a) for a in np.ravel(alphas)), reverse=True)
        if not out or any(not np.isfinite(a) or a < 0 for a in out):
            raise ValueError(f"ridge_alphas must be finite penalties >= 0, at least one; "
                             f"got {list(np.ravel(alphas))}")
        return out

    def fit(self, X: pd.DataFrame, y: Any) -> Self:
        """Choose among prior, calibrated model and drifts by CV; refit the winner.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.
        y : array-like of shape (n_samples,) or (n_samples, n_targets)
            The measured targets.

        Returns
        -------
        self
            The fitted model.
        """
        self._validate_params()
        X = _as_frame(self, X, reset=True)
        t0 = time.perf_counter()
        say = Progress(__name__, self.verbose, "parametric: ")
        model = resolve_model(self.model)
        Y = _targets(y)
        base = self.calibrated_model()
        # the fit settings every candidate shares (calibrated_model's, one declaration)
        common: dict[str, Any] = {k: v for k, v in base.get_params(deep=False).items()
                                  if k not in ("covariates", "calibrate")}
        prior = ParametricRegressor(**{**common, "max_iter": 0}, calibrate=False)
        prior_fit = clone(prior).fit(X, Y)  # also checks the model (one line per bad case)
        scores = {"prior": float(np.mean(np.abs(prior_fit.predict(X) - Y)))}
        # in the targets' unit, but at most a share of the prior's error: a target measured
        # in small units (1e-9 s) could otherwise never leave the prior
        self.min_improvement_ = min(float(self.min_improvement),
                                    MIN_IMPROVEMENT_SHARE * scores["prior"])
        rs = 0 if self.random_state is None else int(self.random_state)
        self.cv_splits_ = _cv_splits(X, self.cv, self.n_repeats, rs)
        folds = _sliced(X, Y, self.cv_splits_)
        say(f"{len(model.names)} parameters, {len(X)} rows, {len(folds)} CV folds; the "
            f"prior's training MAE {scores['prior']:.4g}")
        scores["calibrated"] = float(_fit_splits(
            base, {}, folds, [None] * len(folds),
            done=_fold_lines(say, "calibrated model", len(folds)))[0])
        say(f"calibrated model: cv_mae={scores['calibrated']:.4g} ({say.elapsed()})")
        pool = self._pool(model, X)
        unknown = [p for p in list(pool) + list(self.start or {}) if p not in model.parameters]
        if unknown:
            raise ValueError(f"start and candidates name unknown parameter(s) {unknown}; the "
                             f"model's parameters are {model.names}")
        current = {p: list((self.start or {}).get(p, [])) for p in model.names}
        pairs = [(p, c) for p in model.names for c in dict.fromkeys(pool.get(p, []))
                 if c not in current[p]]
        self.selection_: SelectionResult | None = None
        self.ridge_path_: pd.DataFrame | None = None
        drift: dict[str, list[str]] | None = None
        ridge: ParametricRegressor | None = None
        if self.drift != "ridge" and (pairs or any(current.values())):
            say(f"drift: forward selection over {len(pairs)} candidate terms, at most "
                f"{self.max_steps} step(s)")
            jobs = effective_n_jobs(self.n_jobs)
            if self.method == "linearised":
                # IRLS-weighted scores: the calibrated model's residuals may lie far beyond
                # Huber's threshold, where the Newton weights are 0 (linear_scores' irls)
                self.selection_ = _linearised_select(
                    X, base, current, pairs, folds, jobs, self.max_steps, self.min_improvement_,
                    LINEARISED_SHORTLIST, "auto", say.child("selection "), t0, common,
                    irls_scores=True)
            else:
                self.selection_ = _refit_select(X, base, current, pairs, folds, jobs,
                                                self.max_steps, self.min_improvement_,
                                                say.child("selection "), t0, common)
            drift = self.selection_.covariates
            scores["drift"] = float(self.selection_.cv_mae)
            say(f"drift: {len(self.selection_.path) - 1} step(s), cv_mae={scores['drift']:.4g} "
                f"({say.elapsed()})")
        if self.drift != "forward" and (pairs or any(current.values())):
            library = {p: current[p] + [c for q, c in pairs if q == p] for p in model.names}
            ridge, scores["ridge_drift"], self.ridge_path_ = ridge_drift(
                clone(base).set_params(covariates=library), folds, self._alphas(),
                progress=say.child("ridge drift: "))
        drifts = {"drift": clone(base).set_params(covariates=drift) if drift else None,
                  "ridge_drift": ridge}
        booster = None
        if self.boost is not None:  # from the better drift by CV (None: the calibrated)
            best = min((k for k in drifts if k in scores), key=scores.__getitem__,
                       default="drift")
            booster, scores["boost"] = boost_candidate(clone(self.boost).set_params(
                model=self.model, loss=self.loss, huber_delta=self.huber_delta,
                out_of_bounds=self.out_of_bounds, random_state=rs), folds, drifts[best],
                progress=say.child("boost: "))[:2]
        self.choice_ = "prior"
        for name in CANDIDATES[1:]:
            if name in scores and scores[self.choice_] - scores[name] > self.min_improvement_:
                self.choice_ = name
        beaten = ("calibrated model" if {"drift", "ridge_drift"} & set(scores)
                  else "other candidates")
        self.note_ = ("" if self.choice_ in ("drift", "ridge_drift", "boost") else
                      "the error is not a drift of the parameters: the drift did not beat "
                      f"the {beaten} in CV")
        self.choices_ = pd.DataFrame({"candidate": list(scores), "cv_mae": list(scores.values()),
                                      "chosen": [k == self.choice_ for k in scores]})
        models = {"prior": prior, "calibrated": base, **drifts, "boost": booster}
        winner = models[self.choice_]
        # a boost of 0 rounds is its start model, a candidate already
        idle = booster is not None and booster.n_estimators == 0
        self.other_candidates_ = {k: clone(models[k]) for k in CANDIDATES[1:]
                                  if k in scores and k != self.choice_
                                  and models[k] is not None and not (k == "boost" and idle)}
        if say:
            cv = ", ".join(f"{k} {v:.4g}" for k, v in scores.items() if k != "prior")
            say(f"chose {self.choice_} (cv_mae: {cv}; the prior's training MAE "
                f"{scores['prior']:.4g}); refitting it on all {len(X)} rows")
        self.estimator_ = clone(winner).fit(X, np.asarray(y, dtype=float))
        self.cv_mae_ = scores[self.choice_]
        self.n_iter_ = self.estimator_.n_iter_
        self.seconds_ = time.perf_counter() - t0
        return self

    def calibrated_model(self) -> ParametricRegressor:
        """The ``"calibrated"`` candidate, unfitted: the model with its parameters calibrated
        and no drift, the fit settings these.

        Returns
        -------
        ParametricRegressor
            Unfitted; with these ``model``, ``calibrate``, penalties, loss, ``max_iter``,
            ``tol``, ``out_of_bounds`` and ``solver``.
        """
        return ParametricRegressor(
            model=self.model, alpha=self.alpha, alpha_l1=self.alpha_l1, loss=self.loss,
            huber_delta=self.huber_delta, max_iter=self.max_iter, tol=self.tol,
            out_of_bounds=self.out_of_bounds, solver=self.solver, calibrate=self.calibrate)

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """The winner's prediction.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        ndarray
            The predictions: ``(rows,)`` if fitted on one-dimensional ``y``, else
            ``(rows, targets)``.
        """
        check_is_fitted(self)
        return self.estimator_.predict(_as_frame(self, X, reset=False))

    def corrected_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """The winner's parameters per row.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        pandas.DataFrame
            One column per parameter, indexed as ``X``.
        """
        check_is_fitted(self)
        return self.estimator_.corrected_parameters(_as_frame(self, X, reset=False))

    def __sklearn_tags__(self) -> Any:
        """Multi-output: one column per target of the user's model."""
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True  # one column per target of the user's model
        return tags

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "estimator_")


def _fold_lines(say: Callable[[str], None] | None, what: str,
                n_folds: int) -> Callable[[int], None] | None:
    """``done(k)`` reporting ``"<what>: CV fold k/n"`` (and ``" (t s)"``, the time since
    the fit began, from a :class:`~workbench._progress.Progress`), or None when ``say`` is
    off."""
    if not say:
        return None
    elapsed = getattr(say, "elapsed", None)
    return lambda k: say(f"{what}: CV fold {k}/{n_folds}"
                         + (f" ({elapsed()})" if elapsed is not None else ""))


def boost_candidate(template: Any, folds: list[tuple], drift: Any = None, *,
                    progress: Callable[[str], None] | None = None
                    ) -> tuple[Any, float, np.ndarray]:
    """Score ``template`` by CV on the sliced ``folds`` (``(X_fit, y_fit, X_val, y_val)``).

    Each fold is fitted with ``template.n_estimators`` rounds; the CV MAE after every round
    (the mean over all held-out values, from the staged predictions) chooses the rounds.
    A template with ``init="drift"`` starts from ``drift`` (an unfitted ParametricRegressor
    with the selected covariates; None: the calibrated model).

    Parameters
    ----------
    template : ParameterSpaceBoostRegressor
        The unfitted candidate (:mod:`workbench.parametric_gbm`; its ``n_estimators``:
        the most rounds).
    folds : list of tuple
        ``(X_fit, y_fit, X_val, y_val)`` per fold.
    drift : ParametricRegressor, optional
        The start of an ``init="drift"`` template.
    progress : callable, optional
        Called with a line after each fold and with the chosen rounds (e.g. the fit's
        :class:`~workbench._progress.Progress`); None or false: no lines.

    Returns
    -------
    estimator : ParameterSpaceBoostRegressor
        ``template`` with ``n_estimators`` the chosen rounds (unfitted).
    cv_mae : float
        Its CV MAE.
    curve : ndarray
        The CV MAE after 0, 1, ... rounds.
    """
    if isinstance(template.init, str):
        template = clone(template).set_params(init=drift)
    n = template.n_estimators + 1
    abs_sum, count = np.zeros(n), 0
    done = _fold_lines(progress, f"{n - 1} rounds at most", len(folds))
    for k, (X_fit, y_fit, X_val, y_val) in enumerate(folds, 1):
        fitted = clone(template).fit(X_fit, y_fit)
        y_val = np.asarray(y_val, dtype=float)
        last = 0.0
        for m, pred in enumerate(fitted.staged_predict(X_val)):
            last = float(np.abs(np.reshape(pred, y_val.shape) - y_val).sum())
            abs_sum[m] += last
        abs_sum[fitted.n_iter_ + 1:] += last  # a fold that stopped early keeps its last
        count += y_val.size
        if done is not None:
            done(k)
    curve = abs_sum / count
    rounds = int(np.argmin(curve))
    if progress:
        progress(f"{rounds} rounds chosen, cv_mae={curve[rounds]:.4g}")
    return clone(template).set_params(n_estimators=rounds), float(curve[rounds]), curve


def ridge_drift(template: ParametricRegressor, folds: list[tuple], alphas: Sequence[float], *,
                progress: Callable[[str], None] | None = None
                ) -> tuple[ParametricRegressor, float, pd.DataFrame]:
    """Choose the ridge penalty of a drift over a whole covariate library by CV.

    Every parameter drifts in all of ``template.covariates`` at once (no selection); each
    penalty of ``alphas`` is scored on the sliced ``folds``, in the given order, each fold's
    fit warm-started from the previous penalty's (largest first: the next fit starts near).

    Parameters
    ----------
    template : ParametricRegressor
        The unfitted drift, its ``covariates`` the whole library.
    folds : list of tuple
        ``(X_fit, y_fit, X_val, y_val)`` per fold.
    alphas : sequence of float
        The penalties tried.
    progress : callable, optional
        Called with a line after each penalty is scored; None or false: no lines.

    Returns
    -------
    estimator : ParametricRegressor
        ``template`` with the chosen ``alpha`` (unfitted).
    cv_mae : float
        Its CV MAE.
    path : DataFrame
        ``alpha``, ``cv_mae`` and ``chosen`` per penalty.
    """
    warm: list = [None] * len(folds)
    maes = []
    for i, a in enumerate(alphas, 1):
        mae, warm = _fit_splits(clone(template).set_params(alpha=float(a)),
                                template.covariates or {}, folds, warm)
        maes.append(float(mae))
        if progress:
            progress(f"alpha {float(a):g} ({i}/{len(alphas)}) cv_mae={float(mae):.4g}")
    k = int(np.argmin(maes))
    path = pd.DataFrame({"alpha": [float(a) for a in alphas], "cv_mae": maes,
                         "chosen": [i == k for i in range(len(maes))]})
    return clone(template).set_params(alpha=float(alphas[k])), maes[k], path
