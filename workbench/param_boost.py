"""Boosting in the control model's parameter space: correct the Hamiltonian, not the eigenvalues.

:class:`HamiltonianParameterRegressor` predicts all N eigenvalues of a chain at once as the
ascending eigenvalues of ``sign * H(theta(x) + delta(x))``, where ``theta(x)`` are the control
model's onsite frequencies and couplings (columns of ``X``) and the correction of each
parameter ``p`` is linear in a small covariate library, ``delta_p(x) = phi_p(x) . c_p``.
The coefficients are fitted by (robust, ridge-regularised) Gauss-Newton with an exact
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

__all__ = ["HamiltonianParameterRegressor"]

LOSSES = ("squared_error", "huber")
COVARIATES = ("default",)


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
    missing = [c for c in names if c not in X.columns]
    if missing:
        raise ValueError(f"{what} column(s) {missing} are not columns of X; columns are: "
                         f"{[str(c) for c in X.columns]}")
    try:
        values = X[names].to_numpy(dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} columns {names} must be numeric: {exc}") from None
    if not np.all(np.isfinite(values)):
        rows = np.flatnonzero(~np.isfinite(values).all(axis=1))[:10].tolist()
        raise ValueError(f"{what} columns contain NaN or infinite values (rows {rows})")
    return values


class HamiltonianParameterRegressor(RegressorMixin, BaseEstimator):
    """Multi-output regressor of a chain's N eigenvalues via corrections of its Hamiltonian.

    ``predict(X)`` = ascending eigenvalues of ``sign * H(theta(X) + delta(X))`` with
    ``theta = X[onsite + couplings]`` and ``delta_p(x) = phi_p(x) . c_p`` for each of the
    ``2N - 1`` parameters.

    Covariate library (``covariates="default"``), for parameter ``p``:

    * ``intercept`` (never penalised);
    * ``p`` and ``p^2`` (its own control value, centred by the training mean, and the square
      of the centred value);
    * onsite ``f_i`` only: each adjacent coupling ``g_{i-1}``, ``g_i`` (those that exist)
      and its square (centred as above);
    * coupling ``g_i`` only: the adjacent detuning ``f_i - f_{i+1}`` (centred);
    * every column named in ``features`` (e.g. voltages) and its square (centred).

    Every non-intercept column is then standardised with training mean and sd (sd 0 -> 1).
    Names are the input column names, e.g. ``"f1^2"``, ``"f1-f2"``; see ``covariate_names_``.

    Fitting minimises ``sum rho(y - lambda) + alpha / 2 * ||c_without_intercepts||^2`` with
    ``rho`` squared error (``r^2 / 2``) or Huber (IRLS weights ``min(1, delta / |r|)``) by
    Gauss-Newton: ``(A^T W A + alpha D) dc = A^T W r - alpha D c`` with ``A`` the stacked
    ``J[:, k, p] * phi_p(x)`` and ``D`` the penalty mask; the step is halved (up to 30 times)
    until the objective does not increase; iteration stops when the relative improvement is
    below ``tol``, no step improves it, or after ``max_iter`` iterations.

    Parameters
    ----------
    onsite : list of str
        Columns of ``X`` with the N control-model onsite frequencies (MHz), in chain order.
    couplings : list of str
        Columns of ``X`` with the N - 1 nearest-neighbour couplings, in chain order.
    sign : {-1, 1}, default=-1
        The targets are eigenvalues of ``sign * H``.
    covariates : {"default"}, default="default"
        The covariate library (see above).
    features : list of str, default=None
        Extra columns of ``X`` (e.g. voltages) added, with their squares, to every library.
    alpha : float, default=1.0
        Ridge penalty on the non-intercept coefficients (standardised covariates).
    loss : {"squared_error", "huber"}, default="squared_error"
    huber_delta : float, default=1.0
        Huber threshold (MHz).
    max_iter : int, default=20
        Maximum Gauss-Newton iterations.
    tol : float, default=1e-6
        Stop when the relative decrease of the objective is below this.

    Attributes
    ----------
    parameter_names_ : list of str
        ``onsite + couplings``.
    covariate_names_ : dict of str -> list of str
        Covariate names of each parameter (starting with ``"intercept"``).
    coef_ : pandas.DataFrame
        One row per (parameter, covariate), column ``"coef"`` (per standardised covariate).
    n_iter_ : int
        Gauss-Newton iterations taken.
    train_loss_ : ndarray
        Objective at the start and after each accepted iteration.
    n_features_in_, feature_names_in_
    """

    def __init__(self, *, onsite=None, couplings=None, sign=-1, covariates="default",
                 features=None, alpha=1.0, loss="squared_error", huber_delta=1.0,
                 max_iter=20, tol=1e-6):
        self.onsite = onsite
        self.couplings = couplings
        self.sign = sign
        self.covariates = covariates
        self.features = features
        self.alpha = alpha
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
        overlap = set(features) & set(onsite + couplings)
        if set(onsite) & set(couplings) or overlap:
            raise ValueError("onsite, couplings and features must name distinct columns")
        if isinstance(self.sign, bool) or self.sign not in (-1, 1):
            raise ValueError(f"sign must be -1 or 1, got {self.sign!r}")
        if self.covariates not in COVARIATES:
            raise ValueError(f"covariates must be one of {COVARIATES}, got {self.covariates!r}")
        if not (isinstance(self.alpha, numbers.Real) and np.isfinite(self.alpha)
                and self.alpha >= 0):
            raise ValueError(f"alpha must be a finite number >= 0, got {self.alpha!r}")
        if self.loss not in LOSSES:
            raise ValueError(f"loss must be one of {LOSSES}, got {self.loss!r}")
        if not (isinstance(self.huber_delta, numbers.Real) and np.isfinite(self.huber_delta)
                and self.huber_delta > 0):
            raise ValueError(f"huber_delta must be a finite number > 0, got "
                             f"{self.huber_delta!r}")
        if (not isinstance(self.max_iter, numbers.Integral) or isinstance(self.max_iter, bool)
                or self.max_iter < 0):
            raise ValueError(f"max_iter must be an integer >= 0, got {self.max_iter!r}")
        if not (isinstance(self.tol, numbers.Real) and self.tol >= 0):
            raise ValueError(f"tol must be a number >= 0, got {self.tol!r}")
        return onsite, couplings, features

    def _inputs(self, X, onsite, couplings, features):
        if not isinstance(X, pd.DataFrame):
            raise ValueError("X must be a pandas DataFrame holding the onsite, coupling and "
                             f"feature columns by name, got {type(X).__name__}")
        if len(X) == 0:
            raise ValueError("X has no rows")
        theta = _columns(X, onsite + couplings, "parameter")
        V = _columns(X, features, "feature") if features else np.empty((len(X), 0))
        return theta, V

    # ------------------------------------------------------------------ covariates
    def _variables(self, theta, V) -> dict[str, np.ndarray]:
        """Every raw variable any library uses, by name."""
        N = len(self.onsite_)
        out = {name: theta[:, j] for j, name in enumerate(self.parameter_names_)}
        for i in range(N - 1):
            a, b = self.onsite_[i], self.onsite_[i + 1]
            out[f"{a}-{b}"] = theta[:, i] - theta[:, i + 1]
        out.update({name: V[:, j] for j, name in enumerate(self.features_)})
        return out

    def _library(self) -> dict[str, list[tuple[str, int]]]:
        """(variable, power) terms of each parameter's library (intercept excluded)."""
        N = len(self.onsite_)
        on, co = self.onsite_, self.couplings_
        extra = [(v, k) for v in self.features_ for k in (1, 2)]
        lib = {}
        for i, p in enumerate(on):
            neighbours = [co[j] for j in (i - 1, i) if 0 <= j < N - 1]
            lib[p] = [(p, 1), (p, 2)] + [(g, k) for g in neighbours for k in (1, 2)] + extra
        for i, p in enumerate(co):
            lib[p] = [(p, 1), (p, 2), (f"{on[i]}-{on[i + 1]}", 1)] + extra
        return lib

    def _design(self, theta, V) -> list[np.ndarray]:
        """Standardised covariate matrix ``phi_p`` (with intercept first) of each parameter."""
        vars_ = self._variables(theta, V)
        phis = []
        for p in self.parameter_names_:
            cols = [(vars_[v] - self.var_mean_[v]) ** k for v, k in self.library_[p]]
            raw = np.column_stack(cols) if cols else np.empty((len(theta), 0))
            if p not in self.col_mean_:  # fitting: training statistics
                sd = raw.std(axis=0)
                self.col_mean_[p], self.col_scale_[p] = raw.mean(axis=0), np.where(sd > 0, sd, 1.0)
            z = (raw - self.col_mean_[p]) / self.col_scale_[p]
            phis.append(np.column_stack([np.ones(len(theta)), z]))
        return phis

    # ------------------------------------------------------------------ model
    def _objective(self, r, c, penalty):
        if self.loss == "huber":
            a, d = np.abs(r), self.huber_delta
            data = np.where(a <= d, 0.5 * r**2, d * (a - 0.5 * d)).sum()
        else:
            data = 0.5 * np.sum(r**2)
        return float(data + 0.5 * self.alpha * np.sum(penalty * c**2))

    def _delta(self, phis, c):
        return np.column_stack([phi @ c[sl] for phi, sl in zip(phis, self._slices)])

    def _spectrum(self, theta):
        N = len(self.onsite_)
        return chain_spectrum(theta[:, :N], theta[:, N:], self.sign)

    def fit(self, X, y):
        """Fit the coefficients on ``X`` (DataFrame) and ``y`` (n, N ascending eigenvalues)."""
        onsite, couplings, features = self._check_params()
        theta0, V = self._inputs(X, onsite, couplings, features)
        n, N = len(theta0), len(onsite)
        y = np.asarray(y, dtype=float)
        if y.shape != (n, N):
            raise ValueError(f"y must have shape (n_samples, n_sites) = ({n}, {N}), "
                             f"got {y.shape}")
        if not np.all(np.isfinite(y)):
            raise ValueError("y contains NaN or infinite values")

        self.onsite_, self.couplings_, self.features_ = onsite, couplings, features
        self.parameter_names_ = onsite + couplings
        self.feature_names_in_ = np.asarray([str(c) for c in X.columns], dtype=object)
        self.n_features_in_ = X.shape[1]
        self.library_ = self._library()
        self.var_mean_ = {k: float(v.mean()) for k, v in self._variables(theta0, V).items()}
        self.col_mean_, self.col_scale_ = {}, {}
        phis = self._design(theta0, V)
        self.covariate_names_ = {
            p: ["intercept"] + [v if k == 1 else f"{v}^{k}" for v, k in self.library_[p]]
            for p in self.parameter_names_}
        sizes = [phi.shape[1] for phi in phis]
        ends = np.cumsum(sizes)
        self._slices = [slice(e - s, e) for s, e in zip(sizes, ends)]
        penalty = np.ones(ends[-1])
        penalty[ends - np.asarray(sizes)] = 0.0  # intercepts are not penalised

        c = np.zeros(ends[-1])
        lam, jac = self._spectrum(theta0)
        r = y - lam
        obj = self._objective(r, c, penalty)
        history, n_iter = [obj], 0
        for n_iter in range(1, self.max_iter + 1):
            if self.loss == "huber":
                w = np.minimum(1.0, self.huber_delta / np.maximum(np.abs(r), 1e-12))
            else:
                w = np.ones_like(r)
            A = np.hstack([(jac[:, :, j, None] * phi[:, None, :]).reshape(n * N, -1)
                           for j, phi in enumerate(phis)])
            wf = w.ravel()
            G = A.T @ (wf[:, None] * A) + self.alpha * np.diag(penalty)
            b = A.T @ (wf * r.ravel()) - self.alpha * penalty * c
            dc = np.linalg.lstsq(G, b, rcond=None)[0]
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
        self._coef = c
        self.n_iter_ = n_iter
        self.train_loss_ = np.asarray(history)
        index = pd.MultiIndex.from_tuples(
            [(p, name) for p in self.parameter_names_ for name in self.covariate_names_[p]],
            names=["parameter", "covariate"])
        self.coef_ = pd.DataFrame({"coef": c}, index=index)
        return self

    def _corrected(self, X) -> np.ndarray:
        check_is_fitted(self)
        theta0, V = self._inputs(X, self.onsite_, self.couplings_, self.features_)
        return theta0 + self._delta(self._design(theta0, V), self._coef)

    def corrected_parameters(self, X) -> pd.DataFrame:
        """``theta(X) + delta(X)``, columns named like the onsite and coupling inputs."""
        return pd.DataFrame(self._corrected(X), columns=self.parameter_names_, index=X.index)

    def predict(self, X) -> np.ndarray:
        """Ascending eigenvalues of ``sign * H(theta(X) + delta(X))``, shape (n, N)."""
        return self._spectrum(self._corrected(X))[0]

    def __sklearn_is_fitted__(self):
        return hasattr(self, "coef_")
