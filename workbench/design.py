"""Which experiments next: greedy optimal batches for a model that is (locally) linear in its
coefficients.

Every candidate setting ``x`` contributes a *block* ``B(x)`` of shape ``(q, D)``: the
derivatives of its ``q`` predicted outputs with respect to the model's ``D`` coefficients,
divided by the measurement noise's sd. With ``G`` the inverse of the current information
matrix ``F`` (the measured rows' ``sum B^T B`` plus the prior's precision, e.g. a ridge
penalty), the model's predictive covariance at ``x`` is ``B G B^T`` (in noise units), and
measuring ``x`` adds ``B^T B`` to ``F``:

* D-optimal: the gain of ``x`` is ``log det(I + B G B^T)`` (nats of information about the
  coefficients; the determinant lemma);
* I-optimal: the gain is the fall of the average predictive variance over *reference*
  settings (``tr(G M)``, ``M`` the mean of the reference blocks' ``B^T B``), which is
  ``tr(S^-1 B G M G B^T)`` with ``S = I + B G B^T``.

A batch is chosen greedily: the best candidate, then ``G`` updated as if it had been
measured (Woodbury; its outcome does not matter for a linear model), then the next. So a
batch of N is not N copies of one setting: a chosen setting's information lowers the gain of
the settings like it. For a linear model the result is the textbook design (the two ends of
an interval for a straight line; -1, 0, 1 for a parabola).

:func:`ensemble_blocks` turns the predictions of several models (e.g. cross-validation fold
models) into blocks: their spread is treated as a Gaussian over functions with the
ensemble's covariance, the same machinery then picks diverse, uncertain settings.

Core module: numpy only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from sklearn.base import clone

__all__ = ["CRITERIA", "Batch", "DesignProblem", "drift_problem", "ensemble_blocks",
           "greedy_design",
           "robust_sd"]

#: Design criteria of :func:`greedy_design`.
CRITERIA = ("d", "i")


@dataclass
class Batch:
    """A greedy batch of :func:`greedy_design`.

    Parameters
    ----------
    index : ndarray of int
        The picks: positions into the candidates, in the order chosen.
    gain : ndarray
        Each pick's criterion gain given the measured rows and the earlier picks (nats for D,
        noise-variance units of the average predictive variance for I).
    sd : ndarray
        Each pick's predictive sd per output at the time it was chosen (noise sd units).
    sd_before : ndarray
        Every candidate's predictive sd per output before the batch.
    informs, informs_fraction : ndarray
        The coefficient whose variance each pick lowers most, relatively, and by what
        fraction.
    criterion : {"d", "i"}
        The criterion.
    """

    index: np.ndarray
    gain: np.ndarray
    sd: np.ndarray
    sd_before: np.ndarray
    informs: np.ndarray
    informs_fraction: np.ndarray
    criterion: str


@dataclass
class DesignProblem:
    """What a fitted model knows, for :func:`greedy_design`.

    Parameters
    ----------
    blocks : ndarray of shape (m, q, D)
        The candidates' blocks, in noise units.
    information : ndarray of shape (D, D)
        The information of the measured rows, in noise units.
    noise_sd : ndarray
        The noise sd of each output, in the targets' units (an sd in noise units times it is
        in the targets' units).
    coefficients : list of str
        The coefficients' names.
    what : str
        What they are.
    informs : str, default="the variance of {name} falls {fraction:.0%}"
        How to say that a pick lowers one's variance (formatted with ``name`` and
        ``fraction``)."""

    blocks: np.ndarray
    information: np.ndarray
    noise_sd: np.ndarray
    coefficients: list[str]
    what: str
    informs: str = "the variance of {name} falls {fraction:.0%}"


def robust_sd(residuals: ArrayLike, axis: int | tuple[int, ...] | None = None) -> np.ndarray:
    """1.4826 x the median absolute deviation from the median (the sd for Gaussian
    residuals, unmoved by a few wild ones), floored at 1e-12.

    Parameters
    ----------
    residuals : array-like
        The residuals.
    axis : int or tuple of int, default=None
        Over which axes (``None``: all).

    Returns
    -------
    ndarray
        The robust sd, the ``axis`` axes removed.
    """
    r = np.asarray(residuals, dtype=float)
    med = np.median(r, axis=axis, keepdims=True)
    return np.maximum(1.4826 * np.median(np.abs(r - med), axis=axis), 1e-12)


def _inverse(information: np.ndarray) -> np.ndarray:
    F = np.asarray(information, dtype=float)
    F = 0.5 * (F + F.T)
    try:
        G = np.linalg.inv(np.linalg.cholesky(F))
        return G.T @ G
    except np.linalg.LinAlgError:
        raise ValueError("the information matrix is not positive definite: the measured rows "
                         "and the prior do not determine every coefficient (add a ridge "
                         "penalty or more rows)") from None


def _check(blocks: ArrayLike, information: ArrayLike, n: int, criterion: str,
           reference: ArrayLike | None, repeats: bool
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    B = np.asarray(blocks, dtype=float)
    if B.ndim != 3:
        raise ValueError(f"blocks must have shape (n_candidates, n_outputs, n_coefficients), "
                         f"got {B.shape}")
    m, _, D = B.shape
    F = np.asarray(information, dtype=float)
    if F.shape != (D, D):
        raise ValueError(f"information must be ({D}, {D}) for {D} coefficients, got {F.shape}")
    if criterion not in CRITERIA:
        raise ValueError(f"unknown design criterion {criterion!r}; valid: {', '.join(CRITERIA)}")
    if isinstance(n, bool) or int(n) != n or not 1 <= n <= (np.inf if repeats else m):
        raise ValueError(f"n must be an integer from 1 to the number of candidates ({m}), "
                         f"got {n!r}")
    for name, a in (("blocks", B), ("information", F)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} contain NaN or infinite values")
    R = B if reference is None else np.asarray(reference, dtype=float)
    if R.ndim != 3 or R.shape[2] != D or not np.all(np.isfinite(R)):
        raise ValueError(f"reference must be finite blocks (n_reference, n_outputs, {D}), got "
                         f"shape {R.shape}")
    return B, F, R


def greedy_design(blocks: ArrayLike, information: ArrayLike, n: int, *, criterion: str = "d",
                  reference: ArrayLike | None = None, repeats: bool = False) -> Batch:
    """Choose ``n`` of the candidates' ``blocks`` (shape ``(m, q, D)``) greedily by the D- or
    I-criterion (``criterion`` "d" or "i"), given the current ``information`` ``(D, D)``.

    Parameters
    ----------
    blocks : array-like of shape (m, q, D)
        The candidates' blocks.
    information : array-like of shape (D, D)
        The current information.
    n : int
        How many to choose.
    criterion : {"d", "i"}, default="d"
        The D- or the I-criterion.
    reference : array-like, default=None
        Blocks of the settings whose average predictive variance the I-criterion lowers
        (``None``: the candidates themselves).
    repeats : bool, default=False
        Whether a candidate may be chosen again (a replicate measurement).

    Returns
    -------
    Batch
        The chosen candidates in the order picked, each with its gain and predictive sd.
    """
    B, F, R = _check(blocks, information, n, criterion, reference, repeats)
    m, q, D = B.shape
    G = _inverse(F)
    M = np.einsum("rqd,rqe->de", R, R) / len(R) if criterion == "i" else None
    eye = np.eye(q)
    free = np.ones(m, dtype=bool)
    index, gains, sds, informs, fractions = [], [], [], [], []
    # U = B G, C = B G B^T (and UM = U M for I) for every candidate, updated by the rank-q
    # Woodbury term of each pick instead of recomputed: O(m q^2 D) per pick, not O(m q D^2)
    U = B @ G  # (m, q, D)
    Bt = np.swapaxes(B, 1, 2)
    C = U @ Bt  # predictive covariance (m, q, q)
    sd_before = np.sqrt(np.maximum(np.diagonal(C, axis1=1, axis2=2), 0.0))
    UM = None if M is None else U @ M
    for _ in range(int(n)):
        S = C + eye
        if UM is None:
            gain = np.linalg.slogdet(S)[1]
        else:
            T = UM @ np.swapaxes(U, 1, 2)
            gain = np.trace(np.linalg.solve(S, T), axis1=1, axis2=2)
        gain = np.where(free, gain, -np.inf)
        c = int(np.argmax(gain))
        u = U[c]  # (q, D): G B_c^T transposed
        Sinv_u = np.linalg.solve(S[c], u)
        drop = u.T @ Sinv_u  # G - G' (Woodbury)
        ratio = np.diag(drop) / np.maximum(np.diag(G), np.finfo(float).tiny)
        index.append(c)
        gains.append(float(gain[c]))
        sds.append(np.sqrt(np.maximum(np.diag(C[c]), 0.0)))
        informs.append(int(np.argmax(ratio)))
        fractions.append(float(np.max(ratio)))
        G = G - drop
        P = B @ u.T  # (m, q, q): B G B_c^T
        U = U - P @ Sinv_u
        C = U @ Bt
        if UM is not None:
            UM = UM - P @ (Sinv_u @ M)
        free[c] = repeats
    return Batch(index=np.asarray(index), gain=np.asarray(gains), sd=np.asarray(sds),
                 sd_before=sd_before, informs=np.asarray(informs),
                 informs_fraction=np.asarray(fractions), criterion=criterion)


def ensemble_blocks(predictions: ArrayLike, noise_sd: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Blocks and information for the spread of an ensemble's predictions.

    Output ``t`` is modelled as ``mean + E_t(x) . w_t`` with ``w_t ~ N(0, I_K)`` and ``E_t`` the
    deviations from the ensemble mean over ``sqrt(K - 1)`` (so the predictive variance is the
    ensemble's variance).

    Parameters
    ----------
    predictions : array-like of shape (K, m, q)
        K models' predictions of q outputs at m settings.
    noise_sd : array-like of shape (q,) or float
        The measurement noise's sd per output.

    Returns
    -------
    blocks : ndarray of shape (m, q, K q)
        The candidates' blocks, each output divided by its noise sd.
    information : ndarray of shape (K q, K q)
        The identity (the prior on ``w``).
    """
    P = np.asarray(predictions, dtype=float)
    if P.ndim != 3 or P.shape[0] < 2:
        raise ValueError(f"predictions must have shape (n_models >= 2, n_settings, n_outputs), "
                         f"got {P.shape}")
    K, m, q = P.shape
    sd = np.broadcast_to(np.asarray(noise_sd, dtype=float), (q,))
    if not np.all(np.isfinite(sd) & (sd > 0)):
        raise ValueError(f"noise_sd must be finite and > 0, got {noise_sd!r}")
    E = (P - P.mean(axis=0)) / np.sqrt(K - 1)  # (K, m, q)
    blocks = np.zeros((m, q, K * q))
    for t in range(q):
        blocks[:, t, t * K:(t + 1) * K] = E[:, :, t].T / sd[t]
    return blocks, np.eye(K * q)


def drift_problem(regressor: Any, pool: Mapping[str, Sequence[str]], X: Any, Y: Any,
                  candidates: Any, what: str, **params: Any) -> DesignProblem:
    """The Fisher information of a fitted drift regressor's correction coefficients.

    Gauss-Newton: the model's Jacobian times the covariates (the regressor's
    ``coef_jacobian``), plus the ridge penalty as the coefficients' prior; one noise sd for
    every target, the robust sd of the regressor's training residuals. The coefficients are
    those of every covariate of ``pool`` besides the fitted ones (at the fitted model, the
    others at 0: DuMouchel and Jones's "potential terms"), so a design does not starve the
    terms a selection has not taken yet.

    Parameters
    ----------
    regressor : DriftRegressor
        The fitted regressor (:class:`~workbench.param_regressor.HamiltonianParameterRegressor`
        or :class:`~workbench.param_regressor.ParametricRegressor`).
    pool : mapping of str -> sequence of str
        Each parameter's candidate covariates.
    X, Y : DataFrame
        The measured rows and targets the regressor was fitted on.
    candidates : DataFrame
        The candidate settings.
    what : str
        What the coefficients correct, for the problem's description.
    **params
        Further settings of the regressor with the whole pool.

    Returns
    -------
    DesignProblem
        One block per candidate.
    """
    library = {p: [c for c in names if c != "intercept"]
               for p, names in regressor.covariate_names_.items()}
    for p, names in pool.items():
        library[p] = list(dict.fromkeys(library.get(p, []) + list(names)))
    full = clone(regressor).set_params(covariates=library, max_iter=0, **params)
    full.fit(X, Y, coef_init=regressor.coef_dict())
    measured = np.asarray(Y, dtype=float)
    fitted = np.asarray(regressor.predict(X), dtype=float).reshape(measured.shape)
    sigma = float(robust_sd(measured - fitted))
    names = [f"{p}:{c}" for p, c in full.coef_.index]
    return DesignProblem(full.coef_jacobian(candidates) / sigma,
                         full.information(X) / sigma**2,
                         np.full(measured.shape[1], sigma), names,
                         f"the {len(names)} correction coefficients of {what}",
                         informs="the variance of the coefficient {name} falls "
                                 "{fraction:.0%}")
