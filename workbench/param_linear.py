"""Cheap scores of candidate covariates for forward selection: one Gauss-Newton step.

Around a fitted :class:`~workbench.param_regressor.ParametricRegressor` (the Hamiltonian
family's :class:`~workbench.param_regressor.HamiltonianParameterRegressor` is one) the model is
linear in its
coefficients: ``lambda(c + dc) ~ lambda(c) + A dc`` with ``A`` the stacked
``J[:, k, p] * phi_p(x)``. Adding candidate columns ``a`` (one covariate; for an optional
parameter not yet in the model, such as a parasitic coupling, its intercept too) and taking
the Gauss-Newton step of the enlarged model (IRLS weights fixed) is a bordered linear system,
solved through the Schur complement with the current normal matrix's inverse: O(n D) per
candidate instead of a refit. The step predicts the held-out targets; :func:`linear_scores`
returns the held-out absolute errors of every candidate. The Jacobian of an optional
parameter not yet in the model (at its start value) is the whole model's, every parameter
free: its ``predict_and_jacobian`` where it has one (the Hamiltonian's: Hellmann-Feynman from
one eigendecomposition), else its ``jacobian``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ._covariates import column, term, variable
from .param_engine import _normal_equations, _weights, padded
from .parametric import cached_jacobian

__all__ = ["linear_scores"]


@dataclass
class _Step:
    """The fitted model's Gauss-Newton step at its solution, on the fitting and held-out
    rows: what every candidate's bordered update reuses."""

    col: dict[str, int]  # parameter name -> column of the full Jacobians
    J_f: np.ndarray  # (n, N, P_all) Jacobian on the fitting rows
    J_v: np.ndarray  # (nv, N, P_all) on the held-out rows
    Ja_v: np.ndarray  # (nv, N, Pa) held-out Jacobian of the active parameters
    w: np.ndarray  # (n, N) normal-equation weights
    s: np.ndarray  # (n, P_all): sum_k J w r
    Jw: np.ndarray  # (n, Pa, N) active Jacobian times the weights
    flat_f: np.ndarray  # (n, D) the fitting rows' design at the coefficients' positions
    PhiT_v: np.ndarray  # (Pa, nv, K) the held-out design, parameter first
    sel: np.ndarray  # flat positions of the coefficients in the padded design
    pidx: np.ndarray  # parameter of each coefficient
    Hinv: np.ndarray  # (D, D) inverse of the penalised normal matrix
    g: np.ndarray  # (D,) penalised gradient
    base: np.ndarray  # (nv, N) held-out residuals after the model's own step
    vf: Callable[[str], np.ndarray]  # the fitting rows' variables
    vv: Callable[[str], np.ndarray]  # the held-out rows' variables
    parse: Callable[[str], tuple[str, int]]  # a covariate's name -> (variable, power)


@dataclass
class _Linearised:
    """What the step needs of a fitted regressor on a fold: the whole model's prediction and
    Jacobian (every parameter, the optional ones not yet in the model included, column
    ``col[p]``), the current design and each row set's variables."""

    col: dict[str, int]
    lam_f: np.ndarray
    lam_v: np.ndarray
    J_f: np.ndarray
    J_v: np.ndarray
    Phi_f: np.ndarray
    Phi_v: np.ndarray
    sel: np.ndarray
    vf: Callable[[str], np.ndarray]
    vv: Callable[[str], np.ndarray]
    parse: Callable[[str], tuple[str, int]]


class _Columns:
    """A :class:`~workbench.param_regressor.ParametricRegressor`'s variables on a frame (its
    columns, products, differences, geometric means), a new product's factors centred by
    the fitting rows' means (``ref``)."""

    def __init__(self, est: Any, X: pd.DataFrame, ref: _Columns | None = None) -> None:
        self.est, self.X, self.ref = est, X, ref
        self.columns = {str(c) for c in X.columns}
        self.cache: dict[str, np.ndarray] = {}

    def _mean(self, factor: str) -> float:
        known = getattr(self.est, "factor_mean_", None) or {}
        return known[factor] if factor in known else float((self.ref or self)(factor).mean())

    def __call__(self, name: str) -> np.ndarray:
        if name not in self.cache:
            var = variable(name, self.columns)
            if var is None:
                raise ValueError(f"unknown covariate variable {name!r}")
            if len(var) == 1:
                v = column(self.X, name)
            elif var[0] == "*":
                v = (self(var[1]) - self._mean(var[1])) * (self(var[2]) - self._mean(var[2]))
            else:
                v = self.est._combined(var, self(var[1]), self(var[2]))
            self.cache[name] = v
        return self.cache[name]


def _parametric(est: Any, X_fit: pd.DataFrame, X_val: pd.DataFrame) -> _Linearised:
    """A :class:`~workbench.param_regressor.ParametricRegressor`'s: the whole model (every
    optional parameter free, the ones not in the fit at their start values) and its Jacobian
    at the fitted parameters."""
    whole = est._whole_model()
    col = {p: j for j, p in enumerate(whole.names)}
    T = est._n_outputs()
    # the start of each parameter not in the fit (a column's parameter is always fitted)
    held = np.asarray([0.0 if isinstance(v, str) else float(v)
                       for v in (whole.parameters[p] for p in whole.names)])
    out = []
    for X in (X_fit, X_val):
        theta = np.tile(held, (len(X), 1))
        theta[:, [col[p] for p in est.parameter_names_]] = est._corrected(X)
        if hasattr(whole, "predict_and_jacobian"):
            lam, jac = whole.predict_and_jacobian(theta, X, T)
        else:
            lam = whole.predict(theta, X, T)
            jac = cached_jacobian(whole, theta, X, T)
        out.append((np.asarray(lam, dtype=float).reshape(len(X), T), jac,
                    padded(est._design(X, fitting=False))))
    (lam_f, J_f, (Phi_f, sel)), (lam_v, J_v, (Phi_v, _)) = out
    vf = _Columns(est, X_fit)
    vv = _Columns(est, X_val, ref=vf)
    columns = {str(c) for c in X_fit.columns}
    return _Linearised(col, lam_f, lam_v, J_f, J_v, Phi_f, Phi_v, sel, vf, vv,
                       lambda name: term(name, columns))


def _current_step(est: Any, X_fit: pd.DataFrame, y_fit: np.ndarray,
                  X_val: pd.DataFrame, y_val: np.ndarray, irls: bool = False) -> _Step:
    """The current design, normal equations and Newton step of ``est`` (as in fit, at the
    solution)."""
    lin = _parametric(est, X_fit, X_val)
    col, J_f, J_v = lin.col, lin.J_f, lin.J_v
    active = [col[p] for p in est.parameter_names_]
    r = y_fit - lin.lam_f
    rv = y_val - lin.lam_v
    n = len(r)
    newton = getattr(est, "solver", "irls") == "newton" and not irls
    w, wr = _weights(est.loss, r, est.huber_delta, newton)

    # current design and normal equations (as in fit, at the solution)
    Phi_f, Phi_v, sel = lin.Phi_f, lin.Phi_v, lin.sel
    K = Phi_f.shape[2]
    pidx = sel // K
    Ja_f = np.ascontiguousarray(J_f[:, :, active])
    Ja_v = np.ascontiguousarray(J_v[:, :, active])
    AtWA, AtWr = _normal_equations(Ja_f, w, r, Phi_f, sel, wr=wr)
    penalty = np.ones(len(sel))
    penalty[np.r_[0, np.flatnonzero(np.diff(pidx)) + 1]] = 0.0
    c = est._coef
    H = AtWA + est.alpha * np.diag(penalty)
    g = AtWr - est.alpha * penalty * c
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        Hinv = np.linalg.pinv(H)
    dc0 = Hinv @ g
    flat_f = Phi_f.reshape(n, -1)[:, sel]
    PhiT_v = np.ascontiguousarray(np.swapaxes(Phi_v, 0, 1))  # (Pa, nv, K)
    # held-out residuals after the current model's own step
    base = rv - _predict_change(PhiT_v, Ja_v, sel, dc0[:, None])[:, :, 0]

    # border of each candidate: sum_k J[j, k, p] w J[j, k, q] (p active, q the candidate's)
    Jw = np.ascontiguousarray(np.swapaxes(Ja_f * w[:, :, None], 1, 2))  # (n, Pa, N)
    s = np.matmul(wr[:, None, :], J_f)[:, 0, :]  # (n, P_all): sum_k J w r
    return _Step(col=col, J_f=J_f, J_v=J_v, Ja_v=Ja_v, w=w, s=s, Jw=Jw, flat_f=flat_f,
                 PhiT_v=PhiT_v, sel=sel, pidx=pidx, Hinv=Hinv, g=g, base=base, vf=lin.vf,
                 vv=lin.vv, parse=lin.parse)


def _bordered_update(est: Any, st: _Step, p: str,
                     covariates: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """One Newton step of the model enlarged by each covariate of parameter ``p``: the
    change of the current coefficients ``(D, Cq)`` and the held-out change of ``p`` itself
    ``(nv, Cq)``, by the Schur complement of the bordered normal equations. ``covariates``
    ``["intercept"]``: an optional parameter's offset alone (no change where ``p`` is in
    the model: it has one)."""
    vf, vv = st.vf, st.vv
    n = len(st.w)
    q = st.col[p]
    is_new = p not in est.parameter_names_
    if covariates == ["intercept"]:
        nv = len(st.base)
        if not is_new:
            return np.zeros((len(st.sel), 1)), np.zeros((nv, 1))
        Zf, Zv, pen = np.ones((n, 1, 1)), np.ones((nv, 1, 1)), np.array([0.0])
        return _schur(est, st, q, Zf, Zv, pen)
    zf, zv = [], []  # each candidate's standardised covariate: fit rows, held-out rows
    for name in covariates:
        v, k = st.parse(name)
        raw_f = (vf(v) - vf(v).mean()) ** k
        mu, sd = raw_f.mean(), raw_f.std()
        sd = sd if sd > 0 else 1.0
        zf.append((raw_f - mu) / sd)
        zv.append(((vv(v) - vf(v).mean()) ** k - mu) / sd)
    Zf, Zv = np.stack(zf, axis=1), np.stack(zv, axis=1)  # (n, Cq)
    if is_new:  # an optional parameter's intercept enters with its first covariate
        Zf = np.stack([np.ones_like(Zf), Zf], axis=2)
        Zv = np.stack([np.ones_like(Zv), Zv], axis=2)
        pen = np.array([0.0, 1.0])
    else:
        Zf, Zv, pen = Zf[:, :, None], Zv[:, :, None], np.array([1.0])
    return _schur(est, st, q, Zf, Zv, pen)


def _schur(est: Any, st: _Step, q: int, Zf: np.ndarray, Zv: np.ndarray,
           pen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bordered step of the candidates' columns ``Zf`` (n, Cq, m) of the parameter in
    column ``q`` (penalty weights ``pen``, one per column): the change of the current
    coefficients ``(D, Cq)`` and the held-out change of that parameter ``(nv, Cq)``."""
    n, Cq, mq = Zf.shape
    Jq = np.ascontiguousarray(st.J_f[:, :, q])
    Mq = np.matmul(st.Jw, Jq[:, :, None])[:, :, 0]  # (n, Pa)
    G = st.flat_f * Mq[:, st.pidx]  # (n, D)
    Bt = (Zf.reshape(n, Cq * mq).T @ G).reshape(Cq, mq, -1)  # b^T per candidate
    HinvB = Bt @ st.Hinv  # (Cq, m, D)
    bHb = np.einsum("cmd,cnd->cmn", Bt, HinvB)
    Mqq = np.einsum("jk,jk,jk->j", Jq, st.w, Jq)
    Hc = np.einsum("j,jcm,jcn->cmn", Mqq, Zf, Zf) + est.alpha * np.diag(pen)
    gc = np.einsum("j,jcm->cm", st.s[:, q], Zf)
    S = Hc - bHb
    rhs = gc - HinvB @ st.g
    try:
        dca = np.linalg.solve(S, rhs[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        dca = np.einsum("cmn,cn->cm", np.linalg.pinv(S), rhs)
    return -np.einsum("cmd,cm->dc", HinvB, dca), np.einsum("jcm,cm->jc", Zv, dca)


def linear_scores(est: Any, X_fit: pd.DataFrame, y_fit: ArrayLike,
                  X_val: pd.DataFrame, y_val: ArrayLike,
                  candidates: list[tuple[str, str]], chunk_elements: int = 4_000_000,
                  irls: bool = False) -> np.ndarray:
    """Held-out absolute-error sums after one Gauss-Newton step of ``est`` (fitted on
    ``X_fit``) enlarged by each candidate ``(parameter, covariate)``.

    The step's weights are those of ``est.solver`` (IRLS or the loss's curvature), or IRLS
    with ``irls``: Huber's curvature is 0 beyond its threshold, so where most residuals of the
    current fit lie beyond it (a model far from the data before its drift) the Newton step
    sees few rows, and IRLS weights (``psi(r) / r``) keep every row. Cost:
    O(n D (P + C)) for the candidates' border columns, O(C D^2) for the Schur complements
    and O(n_val (D_pad + N P) C) for the held-out predictions, C candidates, D coefficients
    and P parameters; the held-out predictions are made for blocks of candidates of about
    ``chunk_elements`` entries.

    Parameters
    ----------
    est : HamiltonianParameterRegressor or ParametricRegressor
        The current model, fitted on ``X_fit``.
    X_fit, X_val : pandas.DataFrame
        The fold's fitting and held-out rows.
    y_fit, y_val : array-like of shape (rows, N)
        Their measured targets (eigenvalues).
    candidates : list of (str, str)
        The ``(parameter, covariate)`` pairs to score.
    chunk_elements : int, default=4_000_000
        The size of a block of held-out predictions.
    irls : bool, default=False
        Score with IRLS weights whatever ``est.solver`` is.

    Returns
    -------
    ndarray of shape (n_candidates,)
        Each candidate's held-out absolute-error sum.
    """
    y_fit, y_val = np.asarray(y_fit, float), np.asarray(y_val, float)
    if y_fit.ndim == 1:
        y_fit, y_val = y_fit[:, None], y_val[:, None]
    st = _current_step(est, X_fit, y_fit, X_val, y_val, irls)
    N = st.J_f.shape[1]
    nv, Pa = len(st.base), st.PhiT_v.shape[0]
    by_param: dict[tuple[str, bool], list[int]] = {}  # an offset alone is its own block
    for m, (p, c) in enumerate(candidates):
        by_param.setdefault((p, c == "intercept"), []).append(m)
    C = len(candidates)
    ddc = np.empty((len(st.sel), C))  # coefficient change of the current model's terms
    direct = np.empty((nv, C))  # held-out change of the candidate's parameter itself
    qs = np.empty(C, dtype=int)
    for (p, _), members in by_param.items():
        ddc[:, members], direct[:, members] = _bordered_update(
            est, st, p, [candidates[m][1] for m in members])
        qs[members] = st.col[p]
    out = np.empty(C)
    block = max(1, chunk_elements // max(1, nv * (N + Pa)))
    for a in range(0, C, block):
        b = min(C, a + block)
        dlam = _predict_change(st.PhiT_v, st.Ja_v, st.sel, ddc[:, a:b])  # (nv, N, c)
        dlam += st.J_v[:, :, qs[a:b]] * direct[:, None, a:b]
        np.subtract(st.base[:, :, None], dlam, out=dlam)
        out[a:b] = np.abs(dlam).sum(axis=(0, 1))
    return out


def _predict_change(PhiT_v: np.ndarray, Ja_v: np.ndarray, sel: np.ndarray,
                    dc: np.ndarray) -> np.ndarray:
    """Linearised held-out eigenvalue changes ``A_v dc``, (nv, N, C) for ``dc`` (D, C):
    the parameter changes ``T[j, p] = phi_p(x_j) . dc_p`` per parameter (one batched
    product over the padded design), then ``J_v T`` per row."""
    Pa, nv, K = PhiT_v.shape
    pad = np.zeros((Pa * K, dc.shape[1]))
    pad[sel] = dc
    T = np.matmul(PhiT_v, pad.reshape(Pa, K, -1))  # (Pa, nv, C)
    return np.matmul(Ja_v, np.ascontiguousarray(np.swapaxes(T, 0, 1)))  # (nv, N, C)
