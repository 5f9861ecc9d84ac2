"""The parameter-space engine: one robust, penalised Gauss-Newton fit for any physics model.

Both parameter-space families fit the same thing. A physics model ``f(theta; data)`` with
named parameters (:mod:`workbench.parametric`'s contract: a user's model file, or
:class:`workbench.hamiltonian.HamiltonianModel`, a coupled device's spectrum with its
Hellmann-Feynman Jacobian) is evaluated at per-row parameters
``theta_p(x) = start_p(x) + phi_p(x) . c_p``, ``phi_p`` an intercept and standardised
covariates; :func:`gauss_newton` fits the coefficients ``c`` by minimising
``sum rho(y - f) + alpha / 2 ||c||^2 + alpha_l1 ||c||_1`` (intercepts unpenalised) with
IRLS or Newton weights (:data:`PARAM_LOSSES`), the normal equations of
:func:`_normal_equations` (never forming the design matrix), FISTA for the L1 term and step
halving. :class:`~workbench.param_regressor.ParametricRegressor` (the Hamiltonian family's
:class:`~workbench.param_regressor.HamiltonianParameterRegressor` among them) is the
estimator around it.

The model object needs ``predict(theta, data, n_targets)`` (``(rows, targets)``) and
``jacobian(theta, data, n_targets)`` (``(rows, targets, parameters)``). A model that gets
both from one computation (the eigendecomposition of a Hamiltonian gives its eigenvalues and,
through Hellmann-Feynman, their derivatives) also has
``predict_and_jacobian(theta, data, n_targets, out=None)``; the engine then evaluates every
trial step with its Jacobian and keeps the accepted one's (no second computation), else it
evaluates the trials alone and the Jacobian once per accepted step
(:func:`workbench.parametric.cached_jacobian`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from .losses import AbsoluteError, Huber, SquaredError
from .parametric import ModelError, cached_jacobian

__all__ = ["PARAM_LOSSES", "SOLVERS", "GaussNewtonFit", "drift",
           "gauss_newton", "objective"]


def _squared(r: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    return 0.5 * SquaredError().elementwise(r), np.ones_like(r)


def _absolute(r: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    a = AbsoluteError().elementwise(r)
    floor = 1e-4 * max(float(np.median(a)), 1e-12)  # IRLS weights 1/|r|, bounded
    return a, 1.0 / np.maximum(a, floor)


def _huber(r: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """:class:`workbench.losses.Huber` with a fixed ``delta``; IRLS weight ``psi(r) / r``."""
    h = Huber(delta=float(delta))
    big = np.abs(r) > 1e-12
    weight = np.ones_like(r)
    np.divide(h.psi(r), r, out=weight, where=big)
    return h.elementwise(r), weight


#: Losses of the parameter-space fit by name (the names of :data:`workbench.LOSSES`):
#: ``f(residual, huber_delta) -> (loss of each residual, IRLS weight of each residual)``.
PARAM_LOSSES = {"squared_error": _squared, "absolute_error": _absolute, "huber": _huber}

#: Curvature ``rho''(r)`` of the losses that have one (the Newton solver's weights).
_CURVATURE = {"squared_error": lambda r, delta: np.ones_like(r),
              "huber": lambda r, delta: (np.abs(r) <= delta).astype(float)}

#: Gauss-Newton weightings of :class:`HamiltonianParameterRegressor` (``solver``).
SOLVERS = ("irls", "newton")
#: The Newton solver takes IRLS steps until an iteration improves the objective by less
#: than this fraction: far from the optimum (most residuals beyond Huber's delta) the
#: curvature model is poor and IRLS, a majorisation, does better.
_NEWTON_SWITCH = 0.1


def _weights(loss: str, r: np.ndarray, delta: float,
             newton: bool) -> tuple[np.ndarray, np.ndarray]:
    """Normal-equation weights and weighted residuals ``(w, w_r)``: ``w_r = psi(r)`` (the
    loss's negative gradient) always; ``w = psi(r) / r`` (IRLS) or, with ``newton`` and a
    loss with curvature, ``rho''(r)``."""
    w = PARAM_LOSSES[loss](r, delta)[1]
    wr = w * r
    if newton and loss in _CURVATURE:
        w = _CURVATURE[loss](r, delta)
    return w, wr


def _soft(z: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    return np.sign(z) * np.maximum(np.abs(z) - t, 0.0)


def _lasso_quadratic(H: np.ndarray, b: np.ndarray, l1: np.ndarray | float, x0: np.ndarray,
                     max_iter: int = 20000, tol: float = 1e-9) -> np.ndarray:
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


def _normal_equations(jac: np.ndarray, w: np.ndarray, r: np.ndarray, Phi: np.ndarray,
                      sel: np.ndarray, chunk_elements: int = 8_000_000,
                      wr: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton normal equations ``A^T W A`` and ``A^T W r`` (``A^T wr`` when ``wr``,
    the weighted residuals, is given).

    ``A[(j, k), (p, c)] = jac[j, k, p] * Phi[j, p, c]`` (``Phi`` padded to (n, P, K), ``sel``
    the flat (p, c) positions of the real coefficients). ``A`` is never formed: with
    ``M[j, p, q] = sum_k jac[j, k, p] w[j, k] jac[j, k, q]`` (P x P per row),
    ``(A^T W A)[(p, c), (q, d)] = sum_j Phi[j, p, c] M[j, p, q] Phi[j, q, d]``, built one
    parameter's block row at a time over chunks of about ``chunk_elements`` entries of ``M``:
    O(n D^2 + n N P^2) instead of O(n N D^2) for D coefficients.
    """
    n, N, P = jac.shape
    K = Phi.shape[2]
    sel = np.asarray(sel)
    pidx = sel // K
    flat = Phi.reshape(n, P * K)
    D = len(sel)
    wr = w * r if wr is None else wr
    s = np.matmul(wr[:, None, :], jac)[:, 0, :]  # (n, P): sum_k J w r
    g = (flat[:, sel] * s[:, pidx]).sum(axis=0)
    H = np.zeros((D, D))
    bounds = np.r_[0, np.flatnonzero(np.diff(pidx)) + 1, D]  # block of each active param
    params = pidx[bounds[:-1]]
    step = max(1, chunk_elements // max(1, P * P, N * P))
    buffer = np.empty((min(n, step), P, P)) if P >= 64 else None
    for a in range(0, n, step):
        sl = slice(a, min(n, a + step))
        Jw = np.swapaxes(jac[sl] * w[sl, :, None], 1, 2)  # (m, P, N)
        if buffer is None:
            M = np.matmul(Jw, jac[sl])  # (m, P, P)
        else:  # large blocks: one BLAS product per row beats numpy's stacked matmul
            M = buffer[:len(Jw)]
            for i, (left, right) in enumerate(zip(Jw, jac[sl])):
                np.matmul(left, right, out=M[i])
        F = flat[sl][:, sel]  # (m, D)
        for b, p in enumerate(params):
            lo, hi = bounds[b], bounds[b + 1]
            H[lo:hi, lo:] += F[:, lo:hi].T @ (M[:, p, pidx[lo:]] * F[:, lo:])
    H = np.triu(H) + np.triu(H, 1).T
    return H, g


def drift(phis: list[np.ndarray], c: np.ndarray) -> np.ndarray:
    """Return the parameters' corrections, each parameter's covariates times its coefficients.

    Parameters
    ----------
    phis : list of ndarray of shape (rows, K_p)
        Each parameter's covariates (intercept first).
    c : ndarray
        The coefficients, parameter by parameter.

    Returns
    -------
    ndarray of shape (rows, parameters)
        Each row's correction of each parameter.
    """
    out, start = [], 0
    for phi in phis:
        out.append(phi @ c[start:start + phi.shape[1]])
        start += phi.shape[1]
    return np.column_stack(out)


def padded(phis: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Stack the parameters' covariate matrices into one zero-padded array.

    Parameters
    ----------
    phis : list of ndarray
        One ``(rows, K_p)`` covariate matrix per parameter.

    Returns
    -------
    Phi : ndarray of shape (rows, P, K)
        The matrices, each padded with zeros to the widest ``K``.
    sel : ndarray of int
        The flat positions of the coefficients in ``Phi``'s last two axes
        (:func:`_normal_equations`' ``Phi`` and ``sel``).
    """
    n, K = len(phis[0]), max(phi.shape[1] for phi in phis)
    Phi = np.zeros((n, len(phis), K))
    sel: list[int] = []
    for p, phi in enumerate(phis):
        Phi[:, p, :phi.shape[1]] = phi
        sel.extend(p * K + np.arange(phi.shape[1]))
    return Phi, np.asarray(sel)


def objective(r: np.ndarray, c: np.ndarray, penalty: np.ndarray, *, loss: str,
              huber_delta: float, alpha: float, alpha_l1: float) -> float:
    """``sum rho(r) + alpha / 2 ||P c||^2 + alpha_l1 ||P c||_1`` (``P`` the penalty weights:
    0 for the intercepts).

    Parameters
    ----------
    r : ndarray
        The residuals.
    c, penalty : ndarray
        The coefficients and their penalty weights.
    loss, huber_delta, alpha, alpha_l1
        The regressor's settings.

    Returns
    -------
    float
        The penalised loss.
    """
    data = PARAM_LOSSES[loss](r, huber_delta)[0].sum()
    pc = penalty * c
    return float(data + 0.5 * alpha * np.sum(pc * c) + alpha_l1 * np.abs(pc).sum())


@dataclass(frozen=True)
class GaussNewtonFit:
    """What :func:`gauss_newton` found.

    Parameters
    ----------
    coef : ndarray
        The fitted coefficients, parameter by parameter.
    n_iter : int
        The iterations taken.
    history : ndarray
        The objective at the start and after each accepted iteration.
    """

    coef: np.ndarray
    n_iter: int
    history: np.ndarray


def _evaluate(model: Any, theta: np.ndarray, data: pd.DataFrame, n_targets: int,
              joint: bool, out: np.ndarray | None) -> tuple[np.ndarray | None, Any]:
    """The model (and, ``joint``, its Jacobian) at trial parameters; ``(None, None)`` where
    the model fails there (NaN, an error): a trial step may leave the model's domain (a
    negative lifetime) where its start did not."""
    try:
        with np.errstate(all="ignore"):
            if joint:
                return model.predict_and_jacobian(theta, data, n_targets, out=out)
            return model.predict(theta, data, n_targets), None
    except ModelError:
        return None, None


def gauss_newton(model: Any, data: pd.DataFrame, start: np.ndarray, Y: np.ndarray,
                 phis: list[np.ndarray], coef: np.ndarray, penalty: np.ndarray, *,
                 loss: str, huber_delta: float, alpha: float, alpha_l1: float,
                 max_iter: int, tol: float, solver: str = "irls",
                 irls_fallback: bool = True) -> GaussNewtonFit:
    """Fit the drift coefficients of ``model`` by robust, penalised Gauss-Newton.

    Each iteration solves ``(A^T W A + alpha D) dc = A^T W r - alpha D c`` (``A`` the stacked
    ``J[:, k, p] * phi_p(x)``, ``D`` the penalty weights; with ``alpha_l1 > 0`` the quadratic
    model plus the L1 term, by FISTA), halves the step (up to 30 times) until the objective
    does not increase (a trial where the model fails counts as an increase) and stops when the
    relative improvement is below ``tol``, no step improves it, or after ``max_iter``
    iterations. ``solver="newton"`` weights the normal matrix by the loss's curvature
    ``rho''(r)`` instead of the IRLS weights ``psi(r) / r`` once an iteration improves the
    objective by less than 10 %; with ``irls_fallback``, a Newton iteration that finds no
    decrease is retried with IRLS weights (from then on), else the fit stops there.

    Parameters
    ----------
    model : object
        ``predict(theta, data, n_targets)`` and ``jacobian(theta, data, n_targets)``
        (optionally ``predict_and_jacobian``; see the module's docstring).
    data : DataFrame
        The rows (handed to the model).
    start : ndarray of shape (rows, parameters)
        The parameters' start values of each row.
    Y : ndarray of shape (rows, targets)
        The targets.
    phis : list of ndarray of shape (rows, K_p)
        Each parameter's covariates, intercept first.
    coef : ndarray
        The starting coefficients, parameter by parameter.
    penalty : ndarray
        The penalties' weight of each coefficient (0 for the intercepts).
    loss, huber_delta, alpha, alpha_l1, max_iter, tol
        The loss (:data:`PARAM_LOSSES`), Huber's threshold, the ridge and L1 penalties,
        the iterations allowed and the relative improvement that stops them.
    solver : {"irls", "newton"}, default="irls"
        The normal equations' weights near the optimum.
    irls_fallback : bool, default=True
        Whether a failed Newton iteration is retried with IRLS weights.

    Returns
    -------
    GaussNewtonFit
        The coefficients reached and how the iterations went.
    """
    Phi, sel = padded(phis)
    T = Y.shape[1]
    joint = hasattr(model, "predict_and_jacobian")

    def theta(c: np.ndarray) -> np.ndarray:
        return start + drift(phis, c)

    def settings(r: np.ndarray, c: np.ndarray) -> float:
        return objective(r, c, penalty, loss=loss, huber_delta=huber_delta, alpha=alpha,
                         alpha_l1=alpha_l1)

    c = coef
    if joint:
        value, jac = model.predict_and_jacobian(theta(c), data, T)
    else:
        value, jac = model.predict(theta(c), data, T), None
    r = Y - value
    obj = settings(r, c)
    history, n_iter = [obj], 0
    newton = solver == "newton" and loss in _CURVATURE
    improvement, spare = np.inf, None
    while n_iter < max_iter:
        n_iter += 1
        near = improvement < _NEWTON_SWITCH  # Newton steps once close to the optimum
        if jac is None:
            jac = cached_jacobian(model, theta(c), data, T)
        w, wr = _weights(loss, r, huber_delta, newton and near)
        AtWA, AtWr = _normal_equations(jac, w, r, Phi, sel, wr=wr)
        H = AtWA + alpha * np.diag(penalty)
        g = AtWr - alpha * penalty * c
        if alpha_l1 > 0:
            dc = _lasso_quadratic(H, g + H @ c, alpha_l1 * penalty, c) - c
        else:
            try:
                dc = np.linalg.solve(H, g)
            except np.linalg.LinAlgError:  # singular (alpha = 0, collinear covariates)
                dc = np.linalg.lstsq(H, g, rcond=None)[0]
        step, accepted = 1.0, False
        for _ in range(30):
            c_new = c + step * dc
            value, jac_new = _evaluate(model, theta(c_new), data, T, joint, spare)
            if value is None:  # outside the model's domain: a shorter step
                step *= 0.5
                continue
            r_new = Y - value
            obj_new = settings(r_new, c_new)
            if obj_new <= obj:
                accepted = True
                break
            if joint:
                spare = jac_new  # the rejected trial's Jacobian array is reused
            step *= 0.5
        if not accepted:
            if newton and near and irls_fallback:  # the curvature model failed: IRLS now
                newton, n_iter = False, n_iter - 1
                continue
            break
        improvement = (obj - obj_new) / max(obj, np.finfo(float).tiny)
        if joint:
            spare = jac  # the Jacobians alternate between two arrays (no fresh pages)
        c, r, jac, obj = c_new, r_new, jac_new, obj_new
        history.append(obj)
        if improvement < tol:
            break
    return GaussNewtonFit(c, n_iter, np.asarray(history))
