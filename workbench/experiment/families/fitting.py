"""Fitting as the model families and ``workbench design`` fit: without convergence noise."""

from __future__ import annotations

import warnings
from typing import Any

from sklearn.exceptions import ConvergenceWarning

__all__ = ["quiet_fit"]


def quiet_fit(model: Any, X: Any, y: Any) -> Any:
    """Fit ``model`` on ``X``, ``y`` without scikit-learn's convergence warnings.

    An MLP's max_iter is the search's business, not noise.

    Parameters
    ----------
    model : estimator
        The model to fit.
    X, y : array-like
        Its training inputs and targets.

    Returns
    -------
    estimator
        What ``model.fit`` returns (the fitted model).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        return model.fit(X, y)
