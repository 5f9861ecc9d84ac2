"""The parameter-space regressor: any physics model, its parameters drifting linearly.

:class:`ParametricRegressor` fits ``y ~ f(theta(x); x)`` for a physics model ``f`` (a user's
model file, :mod:`workbench.parametric`, or a model object such as
:class:`workbench.hamiltonian.HamiltonianModel`): ``theta_p(x) = start_p(x) + delta_p(x)``
with ``delta_p(x) = phi_p(x) . c_p`` linear in standardised covariates (an intercept, the
calibration offset, and the covariates it is given; their names are read by
:mod:`workbench._covariates`). It first calibrates the intercepts globally (Kennedy and
O'Hagan's calibration: :func:`scipy.optimize.least_squares` with a robust loss), then fits
every coefficient by the parameter-space engine (:func:`workbench.param_engine.gauss_newton`:
the normal equations, IRLS and Newton weights, ridge and L1 penalties), with the model's
Jacobian or central finite differences. It is the one parameter-space regressor:
:class:`HamiltonianParameterRegressor`, the Hamiltonian family's, is this one with the
device's spectrum as the model (:func:`workbench.param_boost.device_model`), its covariates
named from the coupling graph, no calibration step and IRLS weights by default.
"""

from __future__ import annotations

import hashlib
import numbers
import os
from collections.abc import Iterable, Sequence
from typing import Any, ClassVar, Self, cast

import numpy as np
import pandas as pd
from scipy.optimize import least_squares
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils._param_validation import HasMethods, Interval, Options, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from ._covariates import column, columns, term, variable
from .hamiltonian import PARASITIC_KINDS, CouplingGraph, HamiltonianModel
from .param_boost import (
    _columns,
    _names,
    default_library,
    device_model,
    parasitic_names,
    resolve_graph,
)
from .param_engine import PARAM_LOSSES, SOLVERS, gauss_newton
from .param_engine import drift as _drift
from .parametric import (
    ModelError,
    ParametricModel,
    check_model,
    resolve_model,
    restrict,
)

__all__ = ["OUT_OF_BOUNDS", "HamiltonianParameterRegressor", "ParametricRegressor"]

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


def _ranges(names: Any, block: np.ndarray) -> dict[str, tuple[float, float]]:
    """``(min, max)`` of each column of ``block`` (one reduction over them all), by name."""
    lo, hi = np.min(block, axis=0), np.max(block, axis=0)
    return {k: (float(a), float(b)) for k, a, b in zip(names, lo, hi)}


def _device_frame(X: Any) -> None:
    """A device's rows come as a DataFrame (its columns by name)."""
    if not isinstance(X, pd.DataFrame):
        raise ValueError("X must be a pandas DataFrame holding the onsite, coupling and "
                         f"covariate columns by name, got {type(X).__name__}")


class _WarmStart(dict):
    """:meth:`ParametricRegressor.coef_dict`: the coefficients, and the fit's calibration
    with the digest of its rows and its parameters' names (``out_of_bounds="calibrated"``
    reuses it on the same rows and parameters instead of calibrating again)."""

    calibration: tuple[str, tuple[str, ...], np.ndarray] | None = None


class ParametricRegressor(RegressorMixin, BaseEstimator):
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
    weights and step halving (:func:`~workbench.param_engine.gauss_newton`).

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
        default, :class:`HamiltonianParameterRegressor`).

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

    # ------------------------------------------------------------------ coefficients
    def _layout(self, phis: list[np.ndarray]) -> None:
        """Each parameter's block of coefficients (``_slices``) from its covariates."""
        sizes = [phi.shape[1] for phi in phis]
        ends = np.cumsum(sizes)
        self._slices = [slice(e - s, e) for s, e in zip(sizes, ends)]

    def _penalty(self) -> np.ndarray:
        """The ridge and L1 penalties' weight of each coefficient: 0 for the intercepts."""
        penalty = np.ones(self._slices[-1].stop)
        penalty[[s.start for s in self._slices]] = 0.0
        return penalty

    @staticmethod
    def _coef_start(coef_init: Any, index: list[tuple[str, str]]) -> np.ndarray:
        """Starting coefficients: ``coef_init``'s (a fitted model's ``coef_``, a Series or a
        dict keyed by (parameter, covariate)) where it has a finite value, else 0."""
        c = np.zeros(len(index))
        if coef_init is None:
            return c
        if isinstance(coef_init, pd.DataFrame) and "coef" in coef_init.columns:
            coef_init = coef_init["coef"]
        if isinstance(coef_init, pd.Series):
            known = coef_init.to_dict()
        elif isinstance(coef_init, dict):
            known = coef_init
        else:
            raise ValueError("coef_init must be a fitted model's coef_ (a DataFrame or Series "
                             "indexed by (parameter, covariate)) or a dict keyed by "
                             f"(parameter, covariate), got {type(coef_init).__name__}")
        for j, key in enumerate(index):
            value = known.get(key)
            if value is not None and np.isfinite(value):
                c[j] = value
        return c

    def coefficient_table(self) -> pd.DataFrame:
        """The non-zero coefficients: parameter, covariate, coefficient (``coef``, the
        parameter's units per covariate sd: MHz for a Hamiltonian; an intercept is the
        parameter's offset) and, for non-intercept terms, the covariate's training sd
        (``covariate_sd``).

        Returns
        -------
        pandas.DataFrame
            Columns ``parameter``, ``covariate``, ``coef``, ``covariate_sd``.
        """
        check_is_fitted(self)
        rows = []
        for p, sl in zip(self.parameter_names_, self._slices):
            sds = np.concatenate([[np.nan], self.col_scale_[p]])
            for name, coef, sd in zip(self.covariate_names_[p], self._coef[sl], sds):
                if coef != 0.0:
                    rows.append(dict(parameter=p, covariate=name, coef=float(coef),
                                     covariate_sd=float(sd)))
        return pd.DataFrame(rows, columns=["parameter", "covariate", "coef", "covariate_sd"])

    @property
    def coef_(self) -> pd.DataFrame:
        """One row per (parameter, covariate), column ``"coef"``."""
        check_is_fitted(self)
        index = pd.MultiIndex.from_tuples(self._index, names=["parameter", "covariate"])
        return pd.DataFrame({"coef": self._coef}, index=index)

    def _coef_pairs(self) -> dict[tuple[str, str], float]:
        """``{(parameter, covariate): coefficient}``."""
        check_is_fitted(self)
        return dict(zip(self._index, self._coef.tolist()))

    def _fit_drift(self, model: Any, X: pd.DataFrame, start: np.ndarray, Y: np.ndarray,
                   phis: list[np.ndarray], coef: np.ndarray, penalty: np.ndarray, *,
                   solver: str, irls_fallback: bool) -> None:
        """Fit the coefficients (:func:`gauss_newton` with this regressor's settings) and
        set ``_coef``, ``n_iter_`` and ``train_loss_``."""
        fit = gauss_newton(model, X, start, Y, phis, coef, penalty, loss=self.loss,
                           huber_delta=self.huber_delta, alpha=self.alpha,
                           alpha_l1=self.alpha_l1, max_iter=self.max_iter, tol=self.tol,
                           solver=solver, irls_fallback=irls_fallback)
        self._coef = fit.coef
        self.n_iter_ = fit.n_iter
        self.train_loss_ = fit.history

    def _coef_jacobian(self, X: pd.DataFrame) -> np.ndarray:
        """``d predict(X)[j, k] / d coef[d]`` at the fitted coefficients, every row.

        The model's Jacobian (a Hamiltonian's: Hellmann-Feynman) times each parameter's
        covariates: the rows of the Gauss-Newton design matrix.

        Parameters
        ----------
        X : DataFrame
            The rows.

        Returns
        -------
        ndarray of shape (rows, targets, coefficients)
            In ``coef_``'s order.
        """
        data, start, phis = self._rows(X)
        jac = self._physics().jacobian(start + _drift(phis, self._coef), data, self._n_outputs())
        return np.concatenate([jac[:, :, p, None] * phi[:, None, :]
                               for p, phi in enumerate(phis)], axis=2)

    def information(self, X: pd.DataFrame) -> np.ndarray:
        """The Gauss-Newton information of the coefficients from the rows of ``X``.

        ``A^T A + alpha P`` (``A`` = :meth:`coef_jacobian`, ``P`` the ridge penalty's
        diagonal: 0 for the intercepts), in units of the measurement noise's variance.

        Parameters
        ----------
        X : DataFrame
            The rows.

        Returns
        -------
        ndarray of shape (coefficients, coefficients)
            The information matrix, in ``coef_``'s order.
        """
        A = self.coef_jacobian(X)
        return np.einsum("nkd,nke->de", A, A) + self.alpha * np.diag(self._penalty())

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
        block = np.column_stack(list(leaf.values())) if leaf else np.empty((n, 0))
        finite = np.asarray(np.isfinite(block).all(axis=0))
        bad = [c for c, ok in zip(leaf, finite) if not ok]
        if bad:  # named by the first parameter whose covariates read such a column
            p = next(p for p in self.parameter_names_
                     if any(set(self._leaves(v)) & set(bad) for v, _ in self.terms_[p]))
            raise ValueError(f"the covariates of parameter {p!r} have missing or "
                             f"non-numeric values (column(s) {bad})")
        if fitting:
            self.column_range_ = _ranges(leaf, block)  # finite: checked above
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
            self.variable_range_ = (_ranges(cache, np.column_stack(list(cache.values())))
                                    if cache else {})
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
        out = _WarmStart(self._coef_pairs())
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
            In ``coef_``'s order.
        """
        out = self._coef_jacobian(X)
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


class HamiltonianParameterRegressor(ParametricRegressor):
    """Multi-output regressor of a device's N eigenvalues via corrections of its Hamiltonian.

    ``predict(X)`` = ascending eigenvalues of ``sign * H(theta(X) + delta(X))`` with
    ``theta = X[onsite + couplings]`` (and 0 for each active parasitic coupling) and
    ``delta_p(x) = phi_p(x) . c_p`` for each parameter ``p``.

    The covariates ``phi_p`` of parameter ``p`` are an intercept (never penalised) and the
    covariates that ``covariates`` names for ``p``, in the parametric regressor's language
    (:mod:`workbench._covariates`). A covariate is a *variable* optionally raised to a power
    (``"f1^2"``); a variable is a column of ``X`` (the control parameters are columns; e.g.
    voltages), or of two columns the difference ``"a-b"`` (a detuning ``"f_i-f_j"``), the
    geometric mean ``"sqrt|a*b|"`` (of two couplings sharing a site) or the product
    ``"a*b"`` (each factor centred by its training mean first; e.g. a qubit's bias times a
    neighbouring bias line, the first-order frequency change from flux crosstalk). Every
    variable is centred by its training mean
    before the power is taken; every covariate is then standardised with its training mean and
    sd (sd 0 -> 1), so a coefficient is in the targets' units (MHz) per standard deviation of
    its covariate.

    Fitting minimises ``sum rho(y - lambda) + alpha / 2 * ||c||^2 + alpha_l1 * ||c||_1``
    (intercepts excluded from both penalties), ``rho`` one of
    :data:`~workbench.param_engine.PARAM_LOSSES` (``r^2 / 2``, ``|r|`` or Huber), by
    Gauss-Newton with IRLS weights:
    ``(A^T W A + alpha D) dc = A^T W r - alpha D c`` with ``A`` the stacked
    ``J[:, k, p] * phi_p(x)``; with ``alpha_l1 > 0`` the step minimises the same quadratic
    model plus the L1 term (FISTA). The step is halved (up to 30 times) until
    the objective does not increase; iteration stops when the relative improvement is below
    ``tol``, no step improves it, or after ``max_iter`` iterations. ``solver="newton"``
    weights the normal matrix by the loss's curvature ``rho''(r)`` instead of the IRLS
    weights ``psi(r) / r`` (the same for squared error; Huber: 1 inside ``huber_delta``, 0
    beyond) once an iteration improves the objective by less than 10 %: near the optimum it
    converges in fewer iterations (IRLS converges linearly there); if a Newton step finds
    no decrease, the fit goes on with IRLS steps.

    Parameters
    ----------
    onsite : list of str
        Columns of ``X`` with the N control-model onsite frequencies (MHz), in site order.
    couplings : list of str
        Columns of ``X`` with the control model's couplings, one per edge, in edge order.
    edges : list of [i, j], default=None
        The coupling graph (0-based site pairs, one per coupling column); None: the
        nearest-neighbour chain ``[[0, 1], [1, 2], ...]``.
    parasitic : None, "none", "next_nearest", "diagonal" or list of [i, j], default=None
        Site pairs with a parasitic coupling the control model lacks (control value 0); see
        :meth:`~workbench.hamiltonian.CouplingGraph.parasitic_edges`. A parasitic coupling
        named ``"<onsite_i>~<onsite_j>"`` is in the model only if ``covariates`` gives it at
        least one covariate (``"default"``: the geometric means of the couplings bridging it).
    sign : {-1, 1}, default=-1
        The targets are eigenvalues of ``sign * H``.
    covariates : "default" or dict of str -> list of str, default="default"
        ``"default"``: :func:`default_library`. A dict maps parameter names to their
        covariate names; control parameters it does not list get only an intercept,
        parasitic ones are left out.
    features : list of str, default=None
        Columns of ``X`` added, with their squares, to every control parameter's covariates.
    alpha : float, default=1.0
        Ridge penalty on the non-intercept coefficients.
    alpha_l1 : float, default=0.0
        L1 penalty on the non-intercept coefficients.
    loss : {"squared_error", "absolute_error", "huber"}, default="squared_error"
    huber_delta : float, default=1.0
        Huber threshold (targets' units).
    max_iter : int, default=20
        Maximum Gauss-Newton iterations.
    tol : float, default=1e-6
        Stop when the relative decrease of the objective is below this.
    solver : {"irls", "newton"}, default="irls"
        Weights of the Gauss-Newton normal equations: IRLS ``psi(r) / r`` or the loss's
        curvature (``"newton"``; ``absolute_error`` has none and keeps IRLS).

    Attributes
    ----------
    parameter_names_ : list of str
        ``onsite + couplings`` and the active parasitic couplings.
    graph_ : CouplingGraph
        The model's graph: the control edges, then the active parasitic ones.
    covariate_names_ : dict of str -> list of str
        Covariates of each parameter (starting with ``"intercept"``).
    coef_, coef_dict() : pandas.DataFrame, dict
        One row per (parameter, covariate), column ``"coef"`` (MHz per covariate sd);
        ``coef_dict()`` gives the same as a dict (:class:`ParametricRegressor`'s).
    products_ : dict of str -> (str, str)
        The product covariates' variables and their two factors.
    factor_mean_ : dict of str -> float
        Training means of the product factors (empty without products).
    model_ : HamiltonianModel
        The spectrum fitted (:func:`device_model` with the active parasitic couplings).
    n_iter_ : int
        Gauss-Newton iterations taken.
    train_loss_ : ndarray
        Objective at the start and after each accepted iteration.
    n_features_in_, feature_names_in_
    """

    _parameter_constraints: dict = {
        "onsite": [None, list, tuple],
        "couplings": [None, list, tuple],
        "edges": [None, "array-like"],
        "parasitic": [None, StrOptions(set(PARASITIC_KINDS)), "array-like"],
        "sign": [Options(numbers.Integral, {-1, 1})],
        "covariates": [StrOptions({"default"}), dict],
        "features": [None, list, tuple],
        # the fit's settings, as the parametric regressor declares them
        **{k: v for k, v in ParametricRegressor._parameter_constraints.items()
           if k in ("alpha", "alpha_l1", "loss", "huber_delta", "max_iter", "tol", "solver")},
    }

    def __init__(self, *, onsite: Sequence[str] | None = None,
                 couplings: Sequence[str] | None = None,
                 edges: Iterable[Sequence[int]] | None = None,
                 parasitic: str | Iterable[Sequence[int]] | None = None, sign: int = -1,
                 covariates: str | dict[str, list[str]] = "default",
                 features: Sequence[str] | None = None, alpha: float = 1.0,
                 alpha_l1: float = 0.0, loss: str = "squared_error", huber_delta: float = 1.0,
                 max_iter: int = 20, tol: float = 1e-6, solver: str = "irls") -> None:
        self.onsite = onsite
        self.couplings = couplings
        self.edges = edges
        self.parasitic = parasitic
        self.sign = sign
        self.covariates = covariates  # type: ignore[assignment]  # also "default"
        self.features = features
        self.alpha = alpha
        self.alpha_l1 = alpha_l1
        self.loss = loss
        self.huber_delta = huber_delta
        self.max_iter = max_iter
        self.tol = tol
        self.solver = solver

    # ------------------------------------------------------------------ validation
    def _check_params(self) -> tuple[list[str], list[str], list[str], dict[str, list[str]],
                                     CouplingGraph, list[str]]:
        self._validate_params()  # each value against _parameter_constraints
        onsite = _names(self.onsite, "onsite")
        couplings = _names(self.couplings, "couplings")
        if len(onsite) < 2:
            raise ValueError(f"onsite must name at least 2 columns, got {onsite!r}")
        graph, pairs = resolve_graph(len(onsite), self.edges, self.parasitic)
        if len(couplings) != graph.n_edges:
            what = "len(onsite) - 1" if self.edges is None else "len(edges)"
            raise ValueError(f"couplings must name {what} = {graph.n_edges} "
                             f"columns, got {len(couplings)}: {couplings!r}")
        features = _names(self.features, "features")
        if set(onsite) & set(couplings) or set(features) & set(onsite + couplings):
            raise ValueError("onsite, couplings and features must name distinct columns")
        extra = parasitic_names(onsite, pairs)
        params = onsite + couplings
        covariates: Any = self.covariates
        if isinstance(covariates, str):  # "default"
            library = default_library(onsite, couplings, self.edges, pairs)
        else:
            unknown = [p for p in covariates if p not in params + extra]
            if unknown:
                raise ValueError(f"covariates names unknown parameter(s) {unknown}; "
                                 f"parameters are {params + extra}")
            library = {p: _names(covariates.get(p, []), f"covariates[{p!r}]")
                       for p in params + extra}
        active = [(pair, p) for pair, p in zip(pairs, extra) if library.get(p)]
        graph = graph.with_edges([pair for pair, _ in active])
        return onsite, couplings, features, library, graph, [p for _, p in active]

    #: The parametric regressor's settings this one fixes: no calibration (the control
    #: values are the start, every intercept starts at 0), no guard beyond the training box.
    calibrate = False
    out_of_bounds = "extrapolate"
    _IRLS_FALLBACK = True
    _CHECK_MODEL = False  # the model is the device's spectrum; fit checks its columns

    # ------------------------------------------------------------------ the model
    def _whole_model(self) -> HamiltonianModel:
        """The device's spectrum with every parasitic coupling (:func:`device_model`)."""
        device = getattr(self, "_device", None)
        if device is None:  # before fit
            device = device_model(_names(self.onsite, "onsite"),
                                  _names(self.couplings, "couplings"), self.edges,
                                  self.parasitic, self.sign)
        return device

    def _named_covariates(self) -> dict[str, list[str]]:
        return self._library

    def fit(self, X: pd.DataFrame, y: Any, coef_init: Any = None) -> Self:
        """Fit the coefficients on ``X`` (DataFrame) and ``y`` (n, N ascending eigenvalues).

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The onsite, coupling and covariate columns, by name.
        y : array-like of shape (n_samples, N)
            The measured eigenvalues, ascending.
        coef_init : pandas.DataFrame or dict, default=None
            Starting coefficients, e.g. another fit's ``coef_`` (or ``coef_dict()``); entries
            are matched by (parameter, covariate), missing ones start at 0 and ones this
            model's covariates lack are ignored (a warm start when covariates are added or
            removed).

        Returns
        -------
        self
            The fitted model.
        """
        onsite, couplings, features, library, graph, extra = self._check_params()
        _device_frame(X)
        if len(X) == 0:
            raise ValueError("X has no rows")
        n, N = len(X), len(onsite)
        _columns(X, onsite + couplings, "parameter")  # present, numeric and finite
        if features:
            _columns(X, features, "feature")
        y = np.asarray(y, dtype=float)
        if y.shape != (n, N):
            raise ValueError(f"y must have shape (n_samples, n_sites) = ({n}, {N}), "
                             f"got {y.shape}")
        if not np.all(np.isfinite(y)):
            raise ValueError("y contains NaN or infinite values")
        self.onsite_, self.couplings_, self.features_ = onsite, couplings, features
        self.parasitic_, self.graph_ = extra, graph
        self._device = device_model(onsite, couplings, self.edges, self.parasitic, self.sign)
        every = [f"{v}^{k}" if k > 1 else v for v in features for k in (1, 2)]
        self._library = {p: list(library.get(p, [])) + (every if p in onsite + couplings
                                                         else [])
                         for p in onsite + couplings + extra}
        self._fit(X, y, coef_init)  # the parameters were validated above
        self.model_ = restrict(self._device, self.parameter_names_)
        self.products_ = {v: cast(tuple[str, str], self._var(v)[1:])
                          for ts in self.terms_.values() for v, _ in ts
                          if self._var(v)[0] == "*"}
        return self

    def _physics(self) -> Any:
        check_is_fitted(self)
        return self.model_

    def _check_X(self, X: Any) -> None:
        check_is_fitted(self)
        _device_frame(X)

    def _rows(self, X: Any) -> tuple[pd.DataFrame, np.ndarray, list[np.ndarray]]:
        self._check_X(X)
        return super()._rows(X)

    def control_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """The control model's parameters ``theta(X)`` in :attr:`parameter_names_` order
        (0 for the parasitic couplings it lacks): :meth:`start_parameters`.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The onsite, coupling and covariate columns, by name.

        Returns
        -------
        pandas.DataFrame
            The control parameters, indexed as ``X``.
        """
        self._check_X(X)
        return self.start_parameters(X)
