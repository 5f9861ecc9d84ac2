"""A Gaussian-process basis with one length scale per input, its cost bounded in rows."""

from __future__ import annotations

from numbers import Integral, Real
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import check_is_fitted, validate_data

__all__ = ["ARDGaussianProcess"]


class ARDGaussianProcess(RegressorMixin, BaseEstimator):
    """A Gaussian process whose RBF kernel has one length scale per input.

    The length scales, the signal variance and the noise level are fitted by maximising the
    marginal likelihood (automatic relevance determination: an input that does not matter
    gets a long length scale, so the correction is smooth along it and extrapolates flat in
    it). The fit is cubic in rows: above ``max_rows`` training rows it is fitted on a random
    subset of ``max_rows`` rows (``random_state``), so its cost stays bounded.

    Parameters
    ----------
    noise_level : float, default=1.0
        Starting value of the white-noise level (of the normalised target).
    length_scale_bounds : tuple of float, default=(1e-2, 1e3)
        Bounds of every length scale (inputs are best standardised first).
    max_rows : int, default=1000
        Most rows the process is fitted on.
    n_restarts_optimizer : int, default=0
        Extra starts of the marginal-likelihood optimiser, from random hyperparameters.
    random_state : int, RandomState instance or None, default=None
        Seeds the row subset and the optimiser's restarts.

    Attributes
    ----------
    estimator_ : GaussianProcessRegressor
        The fitted process.
    length_scales_ : ndarray of shape (n_features,)
        The fitted length scale of each input.
    subsampled_ : bool
        Whether the process was fitted on a subset of the rows.
    n_features_in_ : int
        Inputs seen in ``fit``.
    """

    _parameter_constraints: dict = {
        "noise_level": [Interval(Real, 0, None, closed="neither")],
        "length_scale_bounds": [tuple],
        "max_rows": [Interval(Integral, 2, None, closed="left")],
        "n_restarts_optimizer": [Interval(Integral, 0, None, closed="left")],
        "random_state": ["random_state"],
    }

    def __init__(self, *, noise_level: float = 1.0,
                 length_scale_bounds: tuple[float, float] = (1e-2, 1e3), max_rows: int = 1000,
                 n_restarts_optimizer: int = 0, random_state: Any = None) -> None:
        self.noise_level = noise_level
        self.length_scale_bounds = length_scale_bounds
        self.max_rows = max_rows
        self.n_restarts_optimizer = n_restarts_optimizer
        self.random_state = random_state

    def fit(self, X: Any, y: Any) -> ARDGaussianProcess:
        """Fit the process (on at most ``max_rows`` rows); returns ``self``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : array-like of shape (n_samples,)
            The target.

        Returns
        -------
        ARDGaussianProcess
            The fitted model.
        """
        self._validate_params()
        X, y = validate_data(self, X, y, y_numeric=True, dtype=float)
        rng = check_random_state(self.random_state)
        self.subsampled_ = len(X) > self.max_rows
        if self.subsampled_:
            rows = np.sort(rng.choice(len(X), self.max_rows, replace=False))
            X, y = X[rows], y[rows]
        kernel = (ConstantKernel() * RBF(np.ones(X.shape[1]), self.length_scale_bounds)
                  + WhiteKernel(self.noise_level))
        self.estimator_ = GaussianProcessRegressor(
            kernel, normalize_y=True, n_restarts_optimizer=self.n_restarts_optimizer,
            random_state=rng.randint(np.iinfo(np.int32).max)).fit(X, y)
        self.length_scales_ = np.atleast_1d(self.estimator_.kernel_.k1.k2.length_scale)
        return self

    def predict(self, X: Any) -> np.ndarray:
        """The process's mean at ``X``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The prediction.
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=float, reset=False)
        return self.estimator_.predict(X)
