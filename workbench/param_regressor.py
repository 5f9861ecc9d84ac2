"""The parameter-space regressor: any physics model, its parameters drifting linearly.

:class:`ParametricRegressor` fits ``y ~ f(theta(x); x)`` for a physics model ``f`` (a user's
model file, :mod:`workbench.parametric`, or a model object such as
:class:`workbench.hamiltonian.HamiltonianModel`): ``theta_p(x) = start_p(x) + delta_p(x)``
with ``delta_p(x) = phi_p(x) . c_p`` linear in standardised covariates (an intercept, the
calibration offset, and the covariates it is given; their names are read by
:mod:`workbench._covariates`). It first calibrates the intercepts globally (Kennedy and
O'Hagan's calibration: :func:`scipy.optimize.least_squares` with a robust loss), then fits
every coefficient by the parameter-space engine (:class:`workbench.param_engine.DriftRegressor`:
the normal equations, IRLS and Newton weights, ridge and L1 penalties), with the model's
Jacobian or central finite differences. The Hamiltonian family's regressor
(:class:`workbench.param_boost.HamiltonianParameterRegressor`) is this one with the device's
spectrum as the model and its covariates built from the coupling graph.
"""

from __future__ import annotations

import hashlib
import numbers
import os
from typing import Any, ClassVar, Self

import numpy as np
import pandas as pd
from scipy.optimize import least_squares
from sklearn.base import BaseEstimator
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from ._covariates import column, columns, term, variable
from .param_engine import PARAM_LOSSES, SOLVERS, DriftRegressor
from .param_engine import drift as _drift
from .parametric import (
    ModelError,
    ParametricModel,
    check_model,
    resolve_model,
    restrict,
)

__all__ = ["OUT_OF_BOUNDS", "ParametricRegressor"]

#: ``out_of_bounds``: what a new row beyond the training rows gets.
OUT_OF_BOUNDS = ("extrapolate", "clip", "calibrated")

#: scipy's robust losses for the calibration, by the regressor's ``loss``.
_SCIPY_LOSS = {"squared_error": "linear", "absolute_error": "soft_l1", "huber": "huber"}

_MODEL = [str, os.PathLike, HasMethods(["predict", "jacobian", "start"])]


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


def _finite(values: dict[str, np.ndarray]) -> np.ndarray:
    """Whether each of ``values``' arrays is finite everywhere (one check over them all)."""
    if not values:
        return np.ones(0, dtype=bool)
    return np.isfinite(np.column_stack(list(values.values()))).all(axis=0)


def _ranges(values: dict[str, np.ndarray], low: Any, high: Any) -> dict[str, tuple[float, float]]:
    """``(low, high)`` of each of ``values``' arrays (one reduction over them all)."""
    if not values:
        return {}
    block = np.column_stack(list(values.values()))
    lo, hi = low(block, axis=0), high(block, axis=0)
    return {k: (float(a), float(b)) for k, a, b in zip(values, lo, hi)}


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
    def _var(self, name: str) -> tuple[str, ...]:
        """:func:`~workbench._covariates.variable` of ``name`` over the training columns,
        remembered (a selection designs thousands of fits)."""
        parsed = self.__dict__.setdefault("_parsed", {})
        var = parsed.get(name)
        if var is None:
            var = parsed[name] = variable(name, self._columns)
            assert var is not None
        return var

    def _leaves(self, name: str) -> tuple[str, ...]:
        """The columns a covariate's variable is made of."""
        var = self._var(name)
        return var if len(var) == 1 else var[1:]

    def _raw(self, X: pd.DataFrame) -> dict[str, np.ndarray]:
        """The columns the covariates are made of, read at once (clipped to their training
        range with ``out_of_bounds="clip"``)."""
        names = sorted({c for ts in self.terms_.values() for v, _ in ts
                        for c in self._leaves(v)})
        raw = columns(X, names)
        if self.out_of_bounds == "clip":
            for c, (low, high) in getattr(self, "column_range_", {}).items():
                if c in raw:
                    raw[c] = np.clip(raw[c], low, high)
        return raw

    def _values(self, raw: dict[str, np.ndarray], name: str) -> np.ndarray:
        var = self._var(name)
        if len(var) == 1:
            return raw[name]
        return self._combined(var, raw[var[1]], raw[var[2]])

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
        leaf = self._raw(X)
        bad = [c for c, ok in zip(leaf, _finite(leaf)) if not ok]
        if bad:  # named by the first parameter whose covariates read such a column
            p = next(p for p in self.parameter_names_
                     if any(set(self._leaves(v)) & set(bad) for v, _ in self.terms_[p]))
            raise ValueError(f"the covariates of parameter {p!r} have missing or "
                             f"non-numeric values (column(s) {bad})")
        if fitting:
            self.column_range_ = _ranges(leaf, np.nanmin, np.nanmax)
            self.factor_mean_ = {}
            for ts in self.terms_.values():
                for v, _ in ts:
                    var = self._var(v)
                    if var[0] == "*":
                        for f in var[1:]:
                            self.factor_mean_[f] = float(leaf[f].mean())
            self.var_mean_, self.col_mean_, self.col_scale_ = {}, {}, {}
        cache: dict[str, np.ndarray] = {}
        phis = []
        for p in self.parameter_names_:
            cols = []
            for v, k in self.terms_[p]:
                if v not in cache:
                    cache[v] = self._values(leaf, v)
                    if fitting:
                        self.var_mean_[v] = float(cache[v].mean())
                cols.append((cache[v] - self.var_mean_[v]) ** k)
            raw = np.column_stack(cols) if cols else np.empty((n, 0))
            if fitting:
                sd = raw.std(axis=0)
                self.col_mean_[p] = raw.mean(axis=0)
                self.col_scale_[p] = np.where(sd > 0, sd, 1.0)
            phis.append(np.column_stack([np.ones(n),
                                         (raw - self.col_mean_[p]) / self.col_scale_[p]]))
        if fitting:
            self.variable_range_ = _ranges(cache, np.min, np.max)
        return phis

    #: What a Newton step that finds no decrease does: go on with IRLS steps (True) or stop.
    _IRLS_FALLBACK: ClassVar[bool] = False
    #: Check the model on the training rows before fitting (:func:`check_model`; a user's
    #: model file may be unusable in many ways).
    _CHECK_MODEL: ClassVar[bool] = True

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickle; a model pickled before ``calibration_`` was made when read keeps it."""
        old = state.pop("calibration_", None)
        if old is not None and "_calibration" not in state:
            state["_calibration"] = (list(old["parameter"]), list(old["start"]),
                                     old["offset"].to_numpy(dtype=float))
        super().__setstate__(state)

    @property
    def calibration_(self) -> pd.DataFrame:
        """Per parameter its start (a value or a column's name) and the calibrated offset."""
        check_is_fitted(self)
        names, starts, offsets = self._calibration
        return pd.DataFrame({"parameter": names,
                             "start": [v if isinstance(v, str) else float(v) for v in starts],
                             "offset": offsets})

    def _whole_model(self) -> Any:
        """The model with every parameter, its optional ones included (``model``)."""
        return resolve_model(self.model)

    def _named_covariates(self) -> dict[str, list[str]]:
        """Each parameter's covariates (``covariates``)."""
        return self.covariates or {}

    def _setup(self, X: Any, y: Any) -> tuple[ParametricModel, np.ndarray, np.ndarray,
                                              list[np.ndarray]]:
        full = self._whole_model()
        Y = _targets(y)
        self._y_1d = np.asarray(y).ndim == 1
        if len(Y) != len(X):
            raise ValueError(f"X has {len(X)} rows and y {len(Y)}")
        covariates = self._named_covariates()
        unknown = [p for p in covariates if p not in full.parameters]
        if unknown:
            raise ValueError(f"covariates name unknown parameter(s) {unknown}; the model's "
                             f"parameters are {full.names}")
        # an optional parameter is fitted only where its covariates are named
        optional = set(getattr(full, "optional", ()))
        model = restrict(full, [p for p in full.names if p not in optional or covariates.get(p)])
        self.parameter_names_ = model.names
        self._columns = {str(c) for c in X.columns}
        self._parsed: dict[str, tuple[str, ...]] = {}  # _var's
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
        return self._fit(X, y, coef_init)

    def _fit(self, X: Any, y: Any, coef_init: Any) -> Self:
        """:meth:`fit` once the parameters are validated."""
        X = _as_frame(self, X, reset=True)
        model, start, Y, phis = self._setup(X, y)
        if self._CHECK_MODEL:  # one line per way the model is unusable
            check_model(model, X, Y.shape[1], start)
        penalty = self._penalty()
        c = self._coef_start(coef_init, self._index)
        if coef_init is None and self.calibrate:
            c[[s.start for s in self._slices]] = self._calibrate(model, X, start, Y)
        if self.out_of_bounds == "calibrated":
            self.calibrated_offset_ = self._held(model, X, start, Y, c, coef_init)
        # calibration_'s columns (a frame made when read: a selection fits thousands)
        self._calibration = (list(model.names), [model.parameters[p] for p in model.names],
                             c[[s.start for s in self._slices]].copy())
        # "newton": Newton weights once close to the optimum, stopping where a step finds no
        # decrease; "irls": IRLS weights throughout
        self._fit_drift(model, X, start, Y, phis, c, penalty, solver=self.solver,
                        irls_fallback=self._IRLS_FALLBACK)
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
        return restrict(self._whole_model(), self.parameter_names_)

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
            offsets = self._calibration[2]
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
