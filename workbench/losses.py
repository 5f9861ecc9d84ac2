"""Regression losses for base boosting: value, negative gradient and the shape the line search
needs.

Each loss is a function of the residual ``u = y - prediction`` and is *piecewise quadratic*
in ``u`` between a few known kink points (``kinks``). That is all the exact line search in
:mod:`workbench.line_search` needs. Values are means over examples (as in scikit-learn's
and the reference implementation's losses), so a line-search penalty is on the same scale
whatever the number of rows.

Losses whose shape depends on the data (Huber's ``delta``) are *bound* to a residual vector
with :meth:`Loss.bind` before use; the bound loss has fixed parameters, which keeps the line
objective convex.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "LOSSES",
    "AbsoluteError",
    "Huber",
    "Loss",
    "Quantile",
    "SquaredError",
    "get_loss",
]


class Loss:
    """Base class. Subclasses define ``name``, :meth:`elementwise`, :meth:`psi` and ``kinks``."""

    name: str = ""

    def bind(self, residual: np.ndarray) -> Loss:
        """Return a loss whose data-dependent parameters are fixed from ``residual``.

        Parameters
        ----------
        residual : ndarray of shape (n_samples,)
            The residuals ``y - prediction`` the loss is bound to.

        Returns
        -------
        Loss
            The bound loss (this one, for a loss without such parameters).
        """
        return self

    def elementwise(self, u: np.ndarray) -> np.ndarray:
        """Loss of each residual ``u = y - prediction``.

        Parameters
        ----------
        u : ndarray
            The residuals.

        Returns
        -------
        ndarray
            The loss of each, of ``u``'s shape.
        """
        raise NotImplementedError

    def psi(self, u: np.ndarray) -> np.ndarray:
        """Negative gradient with respect to the prediction, as a function of ``u``.

        Parameters
        ----------
        u : ndarray
            The residuals.

        Returns
        -------
        ndarray
            ``-dL/dpred`` at each, of ``u``'s shape.
        """
        raise NotImplementedError

    def kinks(self) -> tuple[float, ...]:
        """Residual values between which the loss is a single quadratic (or linear) piece.

        Returns
        -------
        tuple of float
            The kinks, ascending (none for a loss quadratic everywhere).
        """
        return ()

    def __call__(self, y: np.ndarray, pred: np.ndarray) -> float:
        """Mean loss of ``pred`` against ``y``."""
        return float(np.mean(self.elementwise(np.asarray(y) - np.asarray(pred))))

    def negative_gradient(self, y: np.ndarray, pred: np.ndarray) -> np.ndarray:
        """Pseudo-residuals ``-dL/dpred`` at ``pred`` (a bound copy of the loss is used).

        Parameters
        ----------
        y : ndarray of shape (n_samples,)
            The targets.
        pred : ndarray of shape (n_samples,)
            The predictions.

        Returns
        -------
        ndarray of shape (n_samples,)
            The pseudo-residuals.
        """
        u = np.asarray(y, dtype=float) - np.asarray(pred, dtype=float)
        return self.bind(u).psi(u)


@dataclass(frozen=True)
class SquaredError(Loss):
    """``mean(u**2)``; pseudo-residual ``u``."""

    name = "squared_error"

    def elementwise(self, u: np.ndarray) -> np.ndarray:
        """``u**2``."""
        return u * u

    def psi(self, u: np.ndarray) -> np.ndarray:
        """``u`` (a copy)."""
        return np.array(u, dtype=float, copy=True)


@dataclass(frozen=True)
class AbsoluteError(Loss):
    """``mean(|u|)``; pseudo-residual ``sign(u)``."""

    name = "absolute_error"

    def elementwise(self, u: np.ndarray) -> np.ndarray:
        """``|u|``."""
        return np.abs(u)

    def psi(self, u: np.ndarray) -> np.ndarray:
        """``sign(u)``."""
        return np.sign(u).astype(float)

    def kinks(self) -> tuple[float, ...]:
        """A kink at 0."""
        return (0.0,)


@dataclass(frozen=True)
class Huber(Loss):
    """Huber loss: ``u**2 / 2`` for ``|u| <= delta``, ``delta * (|u| - delta / 2)`` beyond.

    Parameters
    ----------
    quantile : float, default=0.9
        Which quantile of the residuals' ``|u|`` is ``delta`` when ``delta`` is ``None``.
    delta : float, default=None
        The threshold; ``None``: the ``quantile`` quantile of ``|u|`` of the residuals the
        loss is bound to, as in Friedman (2001) and scikit-learn.
    """

    quantile: float = 0.9
    delta: float | None = None
    name = "huber"

    def __post_init__(self) -> None:
        """Check ``quantile`` and ``delta``."""
        if not 0.0 < self.quantile <= 1.0:
            raise ValueError(f"huber quantile must be in (0, 1], got {self.quantile!r}")
        if self.delta is not None and not self.delta >= 0.0:
            raise ValueError(f"huber delta must be >= 0, got {self.delta!r}")

    def bind(self, residual: np.ndarray) -> Loss:
        """Fix ``delta`` as the ``quantile`` quantile of ``|residual|`` (kept when given)."""
        if self.delta is not None:
            return self
        delta = float(np.quantile(np.abs(residual), self.quantile)) if len(residual) else 0.0
        return Huber(quantile=self.quantile, delta=delta)

    def _delta(self) -> float:
        if self.delta is None:
            raise RuntimeError("Huber loss is not bound to residuals: call bind(residual) first")
        return self.delta

    def elementwise(self, u: np.ndarray) -> np.ndarray:
        """``u**2 / 2`` within ``delta``, linear beyond (a bound loss)."""
        d = self._delta()
        a = np.abs(u)
        return np.where(a <= d, 0.5 * u * u, d * (a - 0.5 * d))

    def psi(self, u: np.ndarray) -> np.ndarray:
        """``u`` clipped to ``[-delta, delta]`` (a bound loss)."""
        d = self._delta()
        return np.clip(u, -d, d).astype(float)

    def kinks(self) -> tuple[float, ...]:
        """Kinks at ``-delta`` and ``delta`` (a bound loss)."""
        d = self._delta()
        return (-d, d) if d > 0 else (0.0,)

    def __call__(self, y: np.ndarray, pred: np.ndarray) -> float:
        """Mean loss of ``pred`` against ``y``, bound to their residuals."""
        u = np.asarray(y, dtype=float) - np.asarray(pred, dtype=float)
        return float(np.mean(self.bind(u).elementwise(u)))


@dataclass(frozen=True)
class Quantile(Loss):
    """Pinball loss for the ``alpha`` quantile: ``alpha * u`` if ``u > 0`` else
    ``(alpha - 1) * u``.

    Parameters
    ----------
    alpha : float, default=0.9
        The quantile's level."""

    alpha: float = 0.9
    name = "quantile"

    def __post_init__(self) -> None:
        """Check ``alpha``."""
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"quantile alpha must be in (0, 1), got {self.alpha!r}")

    def elementwise(self, u: np.ndarray) -> np.ndarray:
        """``alpha * u`` above 0, ``(alpha - 1) * u`` below."""
        return np.where(u > 0, self.alpha * u, (self.alpha - 1.0) * u)

    def psi(self, u: np.ndarray) -> np.ndarray:
        """``alpha`` above 0, ``alpha - 1`` below."""
        return np.where(u > 0, self.alpha, self.alpha - 1.0).astype(float)

    def kinks(self) -> tuple[float, ...]:
        """A kink at 0."""
        return (0.0,)


#: The registry of losses by name. ``alpha`` is Huber's quantile or the quantile level.
LOSSES: dict[str, type[Loss]] = {
    "squared_error": SquaredError,
    "absolute_error": AbsoluteError,
    "huber": Huber,
    "quantile": Quantile,
}


def get_loss(loss: str | Loss, alpha: float = 0.9) -> Loss:
    """Resolve a loss name (or pass a :class:`Loss` instance through).

    Parameters
    ----------
    loss : str or Loss
        A name of :data:`LOSSES`, or a loss, returned as it is.
    alpha : float, default=0.9
        Huber's ``quantile`` and the quantile loss's level, as ``alpha`` in scikit-learn's
        ``GradientBoostingRegressor``; other losses ignore it.

    Returns
    -------
    Loss
        The loss.

    Raises
    ------
    ValueError
        An unknown name, listing the valid ones.
    """
    if isinstance(loss, Loss):
        return loss
    if not isinstance(loss, str) or loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}; valid names are: {', '.join(sorted(LOSSES))}")
    if loss == "huber":
        return Huber(quantile=alpha)
    if loss == "quantile":
        return Quantile(alpha=alpha)
    return LOSSES[loss]()
