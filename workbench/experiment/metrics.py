"""Scores computed the same way wherever a command reports one."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["mean_absolute_error"]


def mean_absolute_error(y: ArrayLike, pred: ArrayLike) -> float:
    """Mean absolute error over every entry of ``y`` and ``pred``.

    Parameters
    ----------
    y : array-like
        Measured values, any shape.
    pred : array-like
        Predictions, the shape of ``y`` (or broadcastable to it).

    Returns
    -------
    float
        ``mean(|y - pred|)`` over all entries (targets pooled, not averaged per target).

    Examples
    --------
    >>> mean_absolute_error([1.0, 2.0], [2.0, 4.0])
    1.5
    """
    return float(np.mean(np.abs(np.asarray(y, dtype=float) - np.asarray(pred, dtype=float))))
