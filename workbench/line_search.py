"""Exact line search for a stage coefficient.

Solves ``argmin_a  loss(y, F + a * b) + penalty * |a|`` for the losses of
:mod:`workbench.losses`. The objective is convex in ``a`` and, as a function of ``a``, a
single quadratic (or linear) piece between *breakpoints*: the values of ``a`` at which some
residual ``y_i - F_i - a * b_i`` crosses a kink of the loss, plus ``a = 0`` for the penalty.
So the minimum is found exactly: a binary search over the sorted breakpoints finds the
smallest objective value among them (a convex sequence), then the two pieces on either side
are minimised in closed form. Cost: ``O(n log n)``. No starting point, no tolerance.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from .losses import Loss, get_loss

__all__ = ["line_search"]


def _vertex(obj: Callable[[float], float], lo: float, hi: float) -> float | None:
    """Minimiser of the single quadratic piece ``obj`` on ``[lo, hi]`` (open ends allowed)."""
    if np.isfinite(lo) and np.isfinite(hi):
        x0, h = lo, (hi - lo) / 2.0
    elif np.isfinite(hi):  # left tail (-inf, hi]
        h = max(1.0, abs(hi))
        x0 = hi - 2.0 * h
    elif np.isfinite(lo):  # right tail [lo, inf)
        h = max(1.0, abs(lo))
        x0 = lo
    else:
        x0, h = -1.0, 1.0
    if h <= 0:
        return None
    f0, f1, f2 = obj(x0), obj(x0 + h), obj(x0 + 2.0 * h)
    curvature = f0 - 2.0 * f1 + f2
    if not curvature > 0:
        return None  # linear piece: its minimum is at an end, already a candidate
    a = x0 + h - h * (f2 - f0) / (2.0 * curvature)
    return a if lo <= a <= hi else None


def line_search(y: ArrayLike, current: ArrayLike, direction: ArrayLike,
                loss: str | Loss = "absolute_error", penalty: float = 0.1,
                alpha: float = 0.9) -> float:
    """Coefficient ``a`` minimising ``loss(y, current + a * direction) + penalty * |a|``.

    Parameters
    ----------
    y, current, direction : array-like of shape (n_samples,)
        Targets, the current model's predictions ``F`` and the new basis function's
        predictions ``b``.
    loss : str or Loss
        Line-search loss, a name in :data:`workbench.losses.LOSSES` or a loss object. A
        data-dependent loss (Huber) is bound to the residuals ``y - current``.
    penalty : float
        L1 penalty on ``a`` (>= 0).
    alpha : float
        Huber quantile / quantile level when ``loss`` is a name.

    Returns
    -------
    float
        The exact minimiser (0.0 when ``direction`` is identically zero). Where the
        minimum is attained on an interval, a point of it with the smallest objective
        among the breakpoints is returned.
    """
    y = np.asarray(y, dtype=float).ravel()
    current = np.asarray(current, dtype=float).ravel()
    b = np.asarray(direction, dtype=float).ravel()
    if not (y.shape == current.shape == b.shape):
        raise ValueError(
            f"y, current and direction must have the same length, got {y.shape[0]}, "
            f"{current.shape[0]} and {b.shape[0]}"
        )
    for name, arr in (("y", y), ("current", current), ("direction", b)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"line_search: {name} contains NaN or infinite values")
    if not penalty >= 0:
        raise ValueError(f"line_search: penalty must be >= 0, got {penalty!r}")
    if y.size == 0 or not np.any(b):
        return 0.0

    r = y - current
    bound = get_loss(loss, alpha=alpha).bind(r)

    def obj(a: float) -> float:
        return float(np.mean(bound.elementwise(r - a * b))) + penalty * abs(a)

    nz = b != 0
    breaks = [np.zeros(1)]
    for kink in bound.kinks():
        breaks.append((r[nz] - kink) / b[nz])
    cands = np.unique(np.concatenate(breaks))
    cands = cands[np.isfinite(cands)]

    # Binary search for the smallest j with obj(c[j+1]) >= obj(c[j]): the minimum of a
    # convex sequence.
    lo, hi = 0, len(cands) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if obj(cands[mid + 1]) >= obj(cands[mid]):
            hi = mid
        else:
            lo = mid + 1
    j = lo
    best_a, best_f = float(cands[j]), obj(cands[j])
    left = cands[j - 1] if j > 0 else -np.inf
    right = cands[j + 1] if j + 1 < len(cands) else np.inf
    for seg in ((left, cands[j]), (cands[j], right)):
        a = _vertex(obj, *seg)
        if a is not None:
            f = obj(a)
            if f < best_f:
                best_a, best_f = float(a), f
    return best_a
