"""Cheap scores of candidate covariates for forward selection: one Gauss-Newton step.

Around a fitted :class:`~workbench.param_boost.HamiltonianParameterRegressor` the model is
linear in its coefficients: ``lambda(c + dc) ~ lambda(c) + A dc`` with ``A`` the stacked
``J[:, k, p] * phi_p(x)``. Adding candidate columns ``a`` (one covariate; for a parasitic
coupling not yet in the model, its intercept too) and taking the Gauss-Newton step of the
enlarged model (IRLS weights fixed) is a bordered linear system, solved through the Schur
complement with the current normal matrix's inverse: O(n D) per candidate instead of a refit.
The step predicts the held-out eigenvalues; :func:`linear_scores` returns the held-out
absolute errors of every candidate. The Jacobian of a parasitic coupling that is not yet in
the model (value 0) comes from the same eigenvectors (Hellmann-Feynman).
"""

from __future__ import annotations

import numpy as np

from .param_boost import (PARAM_LOSSES, HamiltonianParameterRegressor, _columns,
                          _normal_equations, _parse, parasitic_names, product_factors,
                          resolve_graph)

__all__ = ["linear_scores"]


def _eigvecs(est: HamiltonianParameterRegressor, X):
    """Eigenvalues and eigenvectors of ``sign * H`` at the fitted corrected parameters."""
    theta = est._corrected(X)
    N = len(est.onsite_)
    graph = est.graph_
    h = np.zeros((len(theta), N, N))
    d = np.arange(N)
    h[:, d, d] = theta[:, :N]
    for e, (a, b) in enumerate(graph.edges):
        h[:, a, b] = h[:, b, a] = theta[:, N + e]
    return np.linalg.eigh(est.sign * h)


def _jacobian(vec, sign, N, pairs) -> np.ndarray:
    """``d lambda_k / d theta_p`` for the onsite terms and the couplings of ``pairs``."""
    a = np.array([i for i, _ in pairs], dtype=int)
    b = np.array([j for _, j in pairs], dtype=int)
    jac = np.empty((vec.shape[0], N, N + len(pairs)))
    jac[:, :, :N] = sign * np.swapaxes(vec**2, 1, 2)
    jac[:, :, N:] = sign * 2.0 * np.swapaxes(vec[:, a, :] * vec[:, b, :], 1, 2)
    return jac


class _Variables:
    """Raw variable values of a frame, as the regressor computes them (a product's factors
    centred by the fitted model's means, or for a new product by those of ``ref``, the
    fitting rows' variables)."""

    def __init__(self, est, X, ref=None):
        self.est, self.X, self.ref = est, X, ref
        self.theta = _columns(X, est.onsite_ + est.couplings_, "parameter")
        self.names = {n: j for j, n in enumerate(est.onsite_ + est.couplings_)}
        self.cache, self.variables = {}, None

    def _mean(self, factor):
        known = self.est.factor_mean_ or {}
        return known[factor] if factor in known else (self.ref or self)(factor).mean()

    def __call__(self, name):
        if name not in self.cache:
            if self.variables is None:
                self.variables = (set(self.names) | set(self.est._derived_)
                                  | {str(c) for c in self.X.columns})
            factors = self.est.products_.get(name) or product_factors(name, self.variables)
            if factors:
                a, b = factors
                v = (self(a) - self._mean(a)) * (self(b) - self._mean(b))
            elif name in self.names:
                v = self.theta[:, self.names[name]]
            elif name in self.est._derived_:
                kind, a, b = self.est._derived_[name]
                v = (self.theta[:, a] - self.theta[:, b] if kind == "-"
                     else np.sqrt(np.abs(self.theta[:, a] * self.theta[:, b])))
            else:
                v = _columns(self.X, [name], "covariate")[:, 0]
            self.cache[name] = v
        return self.cache[name]


def linear_scores(est: HamiltonianParameterRegressor, X_fit, y_fit, X_val, y_val,
                  candidates: list[tuple[str, str]]) -> np.ndarray:
    """Held-out absolute-error sums after one Gauss-Newton step of ``est`` (fitted on
    ``X_fit``) enlarged by each candidate ``(parameter, covariate)``."""
    y_fit, y_val = np.asarray(y_fit, float), np.asarray(y_val, float)
    N = len(est.onsite_)
    _, all_pairs = resolve_graph(N, est.edges, est.parasitic)
    pairs = list(est.graph_.edges[:len(est.couplings_)]) + list(all_pairs)
    names = est.onsite_ + est.couplings_ + parasitic_names(est.onsite_, all_pairs)
    col = {p: j for j, p in enumerate(names)}
    active = [col[p] for p in est.parameter_names_]

    lam_f, vec_f = _eigvecs(est, X_fit)
    lam_v, vec_v = _eigvecs(est, X_val)
    J_f = _jacobian(vec_f, est.sign, N, pairs)
    J_v = _jacobian(vec_v, est.sign, N, pairs)
    r = y_fit - lam_f
    rv = y_val - lam_v
    w = PARAM_LOSSES[est.loss](r, est.huber_delta)[1]

    # current design and normal equations (as in fit, at the solution)
    vf = _Variables(est, X_fit)
    vv = _Variables(est, X_val, ref=vf)
    var_f = {v: vf(v) for ts in est.terms_.values() for v, _ in ts}
    var_v = {v: vv(v) for ts in est.terms_.values() for v, _ in ts}
    phis_f = est._design(var_f, len(r), fitting=False)
    phis_v = est._design(var_v, len(rv), fitting=False)
    Phi_f, sel = est._padded(phis_f)
    Phi_v, _ = est._padded(phis_v)
    K = Phi_f.shape[2]
    pidx = sel // K
    Ja_f = np.ascontiguousarray(J_f[:, :, active])
    AtWA, AtWr = _normal_equations(Ja_f, w, r, Phi_f, sel)
    penalty = np.ones(len(sel))
    starts = np.r_[0, np.flatnonzero(np.diff(pidx)) + 1]
    penalty[starts] = 0.0
    c = est._coef
    H = AtWA + est.alpha * np.diag(penalty)
    g = AtWr - est.alpha * penalty * c
    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        Hinv = np.linalg.pinv(H)
    dc0 = Hinv @ g
    flat_f = Phi_f.reshape(len(r), -1)[:, sel]
    flat_v = Phi_v.reshape(len(rv), -1)[:, sel]
    # M[j, q, p] = sum_k J[j, k, q] w J[j, k, p] (q active), s[j, p] = sum_k J w r
    Jw = np.ascontiguousarray(np.swapaxes(Ja_f * w[:, :, None], 1, 2))
    M = np.matmul(Jw, J_f)  # (n, P_active, P_all)
    s = np.matmul((w * r)[:, None, :], J_f)[:, 0, :]
    Mpp = np.einsum("jkp,jk,jkp->jp", J_f, w, J_f)
    dv0 = _theta_change(flat_v, dc0, starts, len(active))  # (nv, P_active, 1)

    by_param: dict[str, list[int]] = {}
    for m, (p, _) in enumerate(candidates):
        by_param.setdefault(p, []).append(m)
    out = np.empty(len(candidates))
    all_vars = set(est._derived_) | set(est.onsite_ + est.couplings_) | \
        {str(v) for v in X_fit.columns}
    for p, members in by_param.items():
        q = col[p]
        is_new = p not in est.parameter_names_
        Zf, Zv = [], []
        for m in members:
            v, k = _parse(candidates[m][1], all_vars)
            raw_f = (vf(v) - vf(v).mean()) ** k
            mu, sd = raw_f.mean(), raw_f.std()
            sd = sd if sd > 0 else 1.0
            Zf.append((raw_f - mu) / sd)
            Zv.append(((vv(v) - vf(v).mean()) ** k - mu) / sd)
        Zf, Zv = np.stack(Zf, axis=1), np.stack(Zv, axis=1)  # (n, C)
        C = Zf.shape[1]
        if is_new:  # the parasitic coupling's intercept enters with its first covariate
            Zf = np.stack([np.ones_like(Zf), Zf], axis=2)
            Zv = np.stack([np.ones_like(Zv), Zv], axis=2)
            pen = np.array([0.0, 1.0])
        else:
            Zf, Zv, pen = Zf[:, :, None], Zv[:, :, None], np.array([1.0])
        m_ = Zf.shape[2]
        G = flat_f * M[:, pidx, q]  # (n, D)
        Bt = (Zf.reshape(len(r), C * m_).T @ G).reshape(C, m_, -1)  # b^T per candidate
        HinvB = Bt @ Hinv  # (C, m, D)
        bHb = np.einsum("cmd,cnd->cmn", Bt, HinvB)
        Hc = np.einsum("j,jcm,jcn->cmn", Mpp[:, q], Zf, Zf) + est.alpha * np.diag(pen)
        gc = np.einsum("j,jcm->cm", s[:, q], Zf)
        S = Hc - bHb
        rhs = gc - HinvB @ g
        try:
            dca = np.linalg.solve(S, rhs[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            dca = np.einsum("cmn,cn->cm", np.linalg.pinv(S), rhs)
        ddc = -np.einsum("cmd,cm->cd", HinvB, dca)  # dc = dc0 + ddc
        dth = dv0 + _theta_change(flat_v, ddc.T, starts, len(active))  # (nv, Pa, C)
        dlam = np.matmul(J_v[:, :, active], dth)  # (nv, N, C)
        dlam += J_v[:, :, q, None] * np.einsum("jcm,cm->jc", Zv, dca)[:, None, :]
        out[members] = np.abs(rv[:, :, None] - dlam).sum(axis=(0, 1))
    return out


def _theta_change(flat_v, dc, starts, P):
    """Parameter changes ``phi_p . dc_p`` per row: (nv, P, C) for ``dc`` (D, C) or (D,)."""
    dc = dc.reshape(len(dc), -1)
    prod = flat_v[:, :, None] * dc[None, :, :]  # (nv, D, C)
    return np.add.reduceat(prod, starts, axis=1)
