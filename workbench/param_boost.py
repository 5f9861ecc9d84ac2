"""Boosting in the control model's parameter space: correct the Hamiltonian, not the eigenvalues.

:class:`HamiltonianParameterRegressor` predicts all N eigenvalues of a chain at once as the
ascending eigenvalues of ``sign * H(theta(x) + delta(x))``, where ``theta(x)`` are the control
model's onsite frequencies and couplings (columns of ``X``) and the correction of each
parameter ``p`` is linear in a small covariate library, ``delta_p(x) = phi_p(x) . c_p``.
The coefficients are fitted by (robust, regularised) Gauss-Newton with an exact
re-diagonalisation at every iteration; the Jacobian comes from Hellmann-Feynman
(:func:`workbench.hamiltonian.chain_spectrum`).
"""

from __future__ import annotations

import numbers

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted

from .hamiltonian import chain_spectrum

__all__ = ["HamiltonianParameterRegressor", "PARAM_LOSSES", "default_library"]


def _squared(r, delta):
    return 0.5 * r * r, np.ones_like(r)


def _absolute(r, delta):
    a = np.abs(r)
    floor = 1e-4 * max(float(np.median(a)), 1e-12)  # IRLS weights 1/|r|, bounded
    return a, 1.0 / np.maximum(a, floor)


def _huber(r, delta):
    a = np.abs(r)
    return (np.where(a <= delta, 0.5 * r * r, delta * (a - 0.5 * delta)),
            np.minimum(1.0, delta / np.maximum(a, 1e-12)))


#: Losses of the parameter-space fit by name (the names of :data:`workbench.LOSSES`):
#: ``f(residual, huber_delta) -> (loss of each residual, IRLS weight of each residual)``.
PARAM_LOSSES = {"squared_error": _squared, "absolute_error": _absolute, "huber": _huber}


def _names(value, what: str) -> list[str]:
    if value is None:
        return []
    if isinstance(value, str):
        raise ValueError(f"{what} must be a list of column names, got the string {value!r}")
    names = list(value)
    if not all(isinstance(v, str) for v in names):
        raise ValueError(f"{what} must be a list of column names (str), got {names!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"{what} contains duplicate names: {names}")
    return names


def _columns(X: pd.DataFrame, names: list[str], what: str) -> np.ndarray:
    position = {str(c): i for i, c in enumerate(X.columns)}
    missing = [c for c in names if c not in position]
    if missing:
        raise ValueError(f"{what} column(s) {missing} are not columns of X; columns are: "
                         f"{list(position)}")
    index = [position[c] for c in names]
    try:  # fast path: an all-numeric frame converts as one block
        values = X.to_numpy(dtype=float)[:, index]
    except (TypeError, ValueError):
        try:
            values = X.iloc[:, index].to_numpy(dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{what} columns {names} must be numeric: {exc}") from None
    if not np.all(np.isfinite(values)):
        rows = np.flatnonzero(~np.isfinite(values).all(axis=1))[:10].tolist()
        raise ValueError(f"{what} columns contain NaN or infinite values (rows {rows})")
    return values


def _detunings(onsite: list[str]) -> list[str]:
    return [f"{a}-{b}" for a, b in zip(onsite, onsite[1:])]


def default_library(onsite, couplings) -> dict[str, list[str]]:
    """The default covariates of each parameter (besides the intercept).

    Onsite ``f_i``: ``f_i``, ``f_i^2`` and each adjacent coupling with its square. Coupling
    ``g_i``: ``g_i``, ``g_i^2`` and the adjacent detuning ``f_i-f_{i+1}``.
    """
    on, co = list(onsite), list(couplings)
    lib = {}
    for i, p in enumerate(on):
        nb = [co[j] for j in (i - 1, i) if 0 <= j < len(co)]
        lib[p] = [p, f"{p}^2"] + [n for g in nb for n in (g, f"{g}^2")]
    for i, p in enumerate(co):
        lib[p] = [p, f"{p}^2", f"{on[i]}-{on[i + 1]}"]
    return lib


def _parse(name: str, variables) -> tuple[str, int]:
    """Covariate name -> (variable, power): ``"x"`` -> (x, 1), ``"x^2"`` -> (x, 2)."""
    if name in variables:
        return name, 1
    base, sep, power = name.rpartition("^")
    if sep and base in variables and power.isdigit() and int(power) >= 1:
        return base, int(power)
    raise ValueError(f"unknown covariate {name!r}: a covariate is a parameter, an adjacent "
                     "detuning 'f_i-f_j', or a column of X, optionally followed by '^k'; "
                     f"X's columns are {sorted(v for v in variables)}")


def _soft(z, t):
    return np.sign(z) * np.maximum(np.abs(z) - t, 0.0)


def _lasso_quadratic(H, b, l1, x0, max_iter=20000, tol=1e-9):
    """argmin_x 0.5 x'Hx - b'x + sum(l1 * |x|) for positive semi-definite ``H`` (FISTA)."""
    lipschitz = max(float(np.linalg.eigvalsh(H)[-1]), 1e-300)
    x, z, t = x0.copy(), x0.copy(), 1.0
    for _ in range(max_iter):
        x_new = _soft(z - (H @ z - b) / lipschitz, l1 / lipschitz)
        t_new = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * t * t))
        z = x_new + ((t - 1.0) / t_new) * (x_new - x)
        done = np.abs(x_new - x).max() <= tol * max(1.0, np.abs(x_new).max())
        x, t = x_new, t_new
        if done:
            break
    return x


class HamiltonianParameterRegressor(RegressorMixin, BaseEstimator):
    """Multi-output regressor of a chain's N eigenvalues via corrections of its Hamiltonian.

    ``predict(X)`` = ascending eigenvalues of ``sign * H(theta(X) + delta(X))`` with
    ``theta = X[onsite + couplings]`` and ``delta_p(x) = phi_p(x) . c_p`` for each of the
    ``2N - 1`` parameters.

    The covariates ``phi_p`` of parameter ``p`` are an intercept (never penalised) and the
    covariates that ``covariates`` names for ``p``. A covariate is a *variable* optionally
    raised to a power (``"f1^2"``); variables are the parameters themselves, the adjacent
    detunings ``"f_i-f_{i+1}"`` (named from the onsite columns) and any column of ``X``
    (e.g. voltages). Every variable is centred by its training mean before the power is
    taken; every covariate is then standardised with its training mean and sd (sd 0 -> 1),
    so a coefficient is in the targets' units (MHz) per standard deviation of its covariate.

    Fitting minimises ``sum rho(y - lambda) + alpha / 2 * ||c||^2 + alpha_l1 * ||c||_1``
    (intercepts excluded from both penalties), ``rho`` one of :data:`PARAM_LOSSES`
    (``r^2 / 2``, ``|r|`` or Huber), by Gauss-Newton with IRLS weights:
    ``(A^T W A + alpha D) dc = A^T W r - alpha D c`` with ``A`` the stacked
    ``J[:, k, p] * phi_p(x)``; with ``alpha_l1 > 0`` the step minimises the same quadratic
    model plus the L1 term (FISTA). The step is halved (up to 30 times) until
    the objective does not increase; iteration stops when the relative improvement is below
    ``tol``, no step improves it, or after ``max_iter`` iterations.

    Parameters
    ----------
    onsite : list of str
        Columns of ``X`` with the N control-model onsite frequencies (MHz), in chain order.
    couplings : list of str
        Columns of ``X`` with the N - 1 nearest-neighbour couplings, in chain order.
    sign : {-1, 1}, default=-1
        The targets are eigenvalues of ``sign * H``.
    covariates : "default" or dict of str -> list of str, default="default"
        ``"default"``: :func:`default_library`. A dict maps parameter names to their
        covariate names; parameters it does not list get only an intercept.
    features : list of str, default=None
        Columns of ``X`` added, with their squares, to *every* parameter's covariates.
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

    Attributes
    ----------
    parameter_names_ : list of str
        ``onsite + couplings``.
    covariate_names_ : dict of str -> list of str
        Covariates of each parameter (starting with ``"intercept"``).
    coef_ : pandas.DataFrame
        One row per (parameter, covariate), column ``"coef"`` (MHz per covariate sd);
        ``coef_dict()`` gives the same as a dict.
    n_iter_ : int
        Gauss-Newton iterations taken.
    train_loss_ : ndarray
        Objective at the start and after each accepted iteration.
    n_features_in_, feature_names_in_
    """

    def __init__(self, *, onsite=None, couplings=None, sign=-1, covariates="default",
                 features=None, alpha=1.0, alpha_l1=0.0, loss="squared_error",
                 huber_delta=1.0, max_iter=20, tol=1e-6):
        self.onsite = onsite
        self.couplings = couplings
        self.sign = sign
        self.covariates = covariates
        self.features = features
        self.alpha = alpha
        self.alpha_l1 = alpha_l1
        self.loss = loss
        self.huber_delta = huber_delta
        self.max_iter = max_iter
        self.tol = tol

    # ------------------------------------------------------------------ validation
    def _check_params(self):
        onsite = _names(self.onsite, "onsite")
        couplings = _names(self.couplings, "couplings")
        if len(onsite) < 2:
            raise ValueError(f"onsite must name at least 2 columns, got {onsite!r}")
        if len(couplings) != len(onsite) - 1:
            raise ValueError(f"couplings must name len(onsite) - 1 = {len(onsite) - 1} "
                             f"columns, got {len(couplings)}: {couplings!r}")
        features = _names(self.features, "features")
        if set(onsite) & set(couplings) or set(features) & set(onsite + couplings):
            raise ValueError("onsite, couplings and features must name distinct columns")
        if isinstance(self.sign, bool) or self.sign not in (-1, 1):
            raise ValueError(f"sign must be -1 or 1, got {self.sign!r}")
        params = onsite + couplings
        if isinstance(self.covariates, str):
            if self.covariates != "default":
                raise ValueError('covariates must be "default" or a dict parameter -> list of '
                                 f"covariate names, got {self.covariates!r}")
            library = default_library(onsite, couplings)
        elif isinstance(self.covariates, dict):
            unknown = [p for p in self.covariates if p not in params]
            if unknown:
                raise ValueError(f"covariates names unknown parameter(s) {unknown}; "
                                 f"parameters are {params}")
            library = {p: _names(self.covariates.get(p, []), f"covariates[{p!r}]")
                       for p in params}
        else:
            raise ValueError('covariates must be "default" or a dict parameter -> list of '
                             f"covariate names, got {type(self.covariates).__name__}")
        for name, value, low in (("alpha", self.alpha, 0), ("alpha_l1", self.alpha_l1, 0)):
            if not (isinstance(value, numbers.Real) and np.isfinite(value) and value >= low):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if self.loss not in PARAM_LOSSES:
            raise ValueError(f"unknown loss {self.loss!r}; valid names are: "
                             f"{', '.join(PARAM_LOSSES)}")
        if not (isinstance(self.huber_delta, numbers.Real) and np.isfinite(self.huber_delta)
                and self.huber_delta > 0):
            raise ValueError(f"huber_delta must be a finite number > 0, got "
                             f"{self.huber_delta!r}")
        if (not isinstance(self.max_iter, numbers.Integral) or isinstance(self.max_iter, bool)
                or self.max_iter < 0):
            raise ValueError(f"max_iter must be an integer >= 0, got {self.max_iter!r}")
        if not (isinstance(self.tol, numbers.Real) and self.tol >= 0):
            raise ValueError(f"tol must be a number >= 0, got {self.tol!r}")
        return onsite, couplings, features, library

    # ------------------------------------------------------------------ covariates
    def _resolve_library(self, X, onsite, couplings, features, library):
        """(variable, power) terms of each parameter and the X columns they read."""
        params = onsite + couplings
        internal = set(params) | set(_detunings(onsite))
        variables = internal | {str(c) for c in X.columns}
        every = [(v, k) for v in features for k in (1, 2)]
        terms = {p: [_parse(name, variables) for name in library[p]] + every for p in params}
        columns = list(dict.fromkeys(v for ts in terms.values() for v, _ in ts
                                     if v not in internal))
        return terms, columns

    def _variables(self, X) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        theta = _columns(X, self.parameter_names_, "parameter")
        out = {name: theta[:, j] for j, name in enumerate(self.parameter_names_)}
        for i, name in enumerate(_detunings(self.onsite_)):
            out[name] = theta[:, i] - theta[:, i + 1]
        if self.columns_:
            V = _columns(X, self.columns_, "covariate")
            out.update({name: V[:, j] for j, name in enumerate(self.columns_)})
        return theta, out

    def _design(self, variables: dict[str, np.ndarray], n: int, fitting: bool) -> list:
        """Standardised covariate matrix ``phi_p`` (with intercept first) of each parameter."""
        phis = []
        for p in self.parameter_names_:
            cols = [(variables[v] - self.var_mean_[v]) ** k for v, k in self.terms_[p]]
            raw = np.column_stack(cols) if cols else np.empty((n, 0))
            if fitting:
                sd = raw.std(axis=0)
                self.col_mean_[p], self.col_scale_[p] = raw.mean(axis=0), np.where(sd > 0, sd, 1.0)
            z = (raw - self.col_mean_[p]) / self.col_scale_[p]
            phis.append(np.column_stack([np.ones(n), z]))
        return phis

    # ------------------------------------------------------------------ model
    def _objective(self, r, c, penalty):
        data = PARAM_LOSSES[self.loss](r, self.huber_delta)[0].sum()
        pc = penalty * c
        return float(data + 0.5 * self.alpha * np.sum(pc * c) + self.alpha_l1 * np.abs(pc).sum())

    def _delta(self, phis, c):
        return np.column_stack([phi @ c[sl] for phi, sl in zip(phis, self._slices)])

    def _spectrum(self, theta):
        N = len(self.onsite_)
        return chain_spectrum(theta[:, :N], theta[:, N:], self.sign)

    def _initial(self, coef_init, index) -> np.ndarray:
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

    def fit(self, X, y, coef_init=None):
        """Fit the coefficients on ``X`` (DataFrame) and ``y`` (n, N ascending eigenvalues).

        ``coef_init``: starting coefficients, e.g. another fit's ``coef_`` (or
        ``coef_dict()``); entries are
        matched by (parameter, covariate), missing ones start at 0 and ones this model's
        covariates lack are ignored (a warm start when covariates are added or removed).
        """
        onsite, couplings, features, library = self._check_params()
        if not isinstance(X, pd.DataFrame):
            raise ValueError("X must be a pandas DataFrame holding the onsite, coupling and "
                             f"covariate columns by name, got {type(X).__name__}")
        if len(X) == 0:
            raise ValueError("X has no rows")
        self.onsite_, self.couplings_, self.features_ = onsite, couplings, features
        self.parameter_names_ = onsite + couplings
        self.terms_, self.columns_ = self._resolve_library(X, onsite, couplings, features,
                                                           library)
        theta0, variables = self._variables(X)
        n, N = len(theta0), len(onsite)
        y = np.asarray(y, dtype=float)
        if y.shape != (n, N):
            raise ValueError(f"y must have shape (n_samples, n_sites) = ({n}, {N}), "
                             f"got {y.shape}")
        if not np.all(np.isfinite(y)):
            raise ValueError("y contains NaN or infinite values")
        self.feature_names_in_ = np.asarray([str(c) for c in X.columns], dtype=object)
        self.n_features_in_ = X.shape[1]
        self.var_mean_ = {k: float(v.mean()) for k, v in variables.items()}
        self.col_mean_, self.col_scale_ = {}, {}
        phis = self._design(variables, n, fitting=True)
        self.covariate_names_ = {
            p: ["intercept"] + [v if k == 1 else f"{v}^{k}" for v, k in self.terms_[p]]
            for p in self.parameter_names_}
        index = [(p, name) for p in self.parameter_names_ for name in self.covariate_names_[p]]
        sizes = [phi.shape[1] for phi in phis]
        ends = np.cumsum(sizes)
        self._slices = [slice(e - s, e) for s, e in zip(sizes, ends)]
        penalty = np.ones(ends[-1])
        penalty[ends - np.asarray(sizes)] = 0.0  # intercepts are not penalised

        c = self._initial(coef_init, index)
        lam, jac = self._spectrum(theta0 + self._delta(phis, c))
        r = y - lam
        obj = self._objective(r, c, penalty)
        history, n_iter = [obj], 0
        loss = PARAM_LOSSES[self.loss]
        for n_iter in range(1, self.max_iter + 1):
            w = loss(r, self.huber_delta)[1].ravel()
            A = np.hstack([(jac[:, :, j, None] * phi[:, None, :]).reshape(n * N, -1)
                           for j, phi in enumerate(phis)])
            H = A.T @ (w[:, None] * A) + self.alpha * np.diag(penalty)
            g = A.T @ (w * r.ravel()) - self.alpha * penalty * c
            if self.alpha_l1 > 0:
                dc = _lasso_quadratic(H, g + H @ c, self.alpha_l1 * penalty, c) - c
            else:
                try:
                    dc = np.linalg.solve(H, g)
                except np.linalg.LinAlgError:  # singular (alpha = 0, collinear covariates)
                    dc = np.linalg.lstsq(H, g, rcond=None)[0]
            step, accepted = 1.0, False
            for _ in range(30):
                c_new = c + step * dc
                lam_new, jac_new = self._spectrum(theta0 + self._delta(phis, c_new))
                r_new = y - lam_new
                obj_new = self._objective(r_new, c_new, penalty)
                if obj_new <= obj:
                    accepted = True
                    break
                step *= 0.5
            if not accepted:
                break
            improvement = (obj - obj_new) / max(obj, np.finfo(float).tiny)
            c, r, jac, obj = c_new, r_new, jac_new, obj_new
            history.append(obj)
            if improvement < self.tol:
                break
        self._coef, self._index = c, index
        self.n_iter_ = n_iter
        self.train_loss_ = np.asarray(history)
        return self

    @property
    def coef_(self) -> pd.DataFrame:
        """One row per (parameter, covariate), column ``"coef"``."""
        check_is_fitted(self)
        index = pd.MultiIndex.from_tuples(self._index, names=["parameter", "covariate"])
        return pd.DataFrame({"coef": self._coef}, index=index)

    def coef_dict(self) -> dict[tuple[str, str], float]:
        """``{(parameter, covariate): coefficient}`` (a cheap ``coef_init``)."""
        check_is_fitted(self)
        return dict(zip(self._index, self._coef.tolist()))

    def _corrected(self, X) -> np.ndarray:
        check_is_fitted(self)
        if not isinstance(X, pd.DataFrame):
            raise ValueError("X must be a pandas DataFrame holding the onsite, coupling and "
                             f"covariate columns by name, got {type(X).__name__}")
        theta0, variables = self._variables(X)
        return theta0 + self._delta(self._design(variables, len(theta0), fitting=False),
                                    self._coef)

    def corrected_parameters(self, X) -> pd.DataFrame:
        """``theta(X) + delta(X)``, columns named like the onsite and coupling inputs."""
        return pd.DataFrame(self._corrected(X), columns=self.parameter_names_, index=X.index)

    def coefficient_table(self) -> pd.DataFrame:
        """The non-zero coefficients: parameter, covariate, coefficient in MHz per covariate sd
        (``coef``) and, for non-intercept terms, the covariate's training sd (``covariate_sd``)."""
        check_is_fitted(self)
        rows = []
        for p in self.parameter_names_:
            sds = np.concatenate([[np.nan], self.col_scale_[p]])
            for name, coef, sd in zip(self.covariate_names_[p], self._coef[self._slice_of(p)],
                                      sds):
                if coef != 0.0:
                    rows.append(dict(parameter=p, covariate=name, coef=float(coef),
                                     covariate_sd=float(sd)))
        return pd.DataFrame(rows, columns=["parameter", "covariate", "coef", "covariate_sd"])

    def _slice_of(self, p: str) -> slice:
        return self._slices[self.parameter_names_.index(p)]

    def predict(self, X) -> np.ndarray:
        """Ascending eigenvalues of ``sign * H(theta(X) + delta(X))``, shape (n, N)."""
        return self._spectrum(self._corrected(X))[0]

    def __sklearn_is_fitted__(self):
        return hasattr(self, "_coef")
