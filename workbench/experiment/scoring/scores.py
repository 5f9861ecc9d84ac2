"""The score records of a result: per-target errors of the prior and the model, and CV estimates.

:class:`Scores` (one system's test and CV errors, with their bootstrap intervals),
:class:`ModelScores` (the model's, with what it chose and its prediction intervals' figures)
and :class:`CVEstimate` (a repeated or nested CV of the chosen model), each with a
``to_json`` that writes its part of the JSON
:meth:`~workbench.experiment.scoring.results.Result.to_json` writes; :func:`mae` and
:func:`mse`, the per-target errors they hold, and :func:`average`, the mean over targets
each ``*_avg`` key holds.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["CVEstimate", "ModelScores", "Scores", "average", "mae", "mse"]


def mae(y: ArrayLike, pred: ArrayLike) -> list[float]:
    """Per-column mean absolute error.

    Parameters
    ----------
    y, pred : array-like of shape (n_rows, n_targets) or (n_rows,)
        The measured values and their predictions.

    Returns
    -------
    list of float
        The mean absolute error of each column.
    """
    return np.mean(np.abs(np.asarray(y, float) - np.asarray(pred, float)), axis=0).tolist()


def mse(y: ArrayLike, pred: ArrayLike) -> list[float]:
    """Per-column mean squared error.

    Parameters
    ----------
    y, pred : array-like of shape (n_rows, n_targets) or (n_rows,)
        The measured values and their predictions.

    Returns
    -------
    list of float
        The mean squared error of each column.
    """
    return np.mean((np.asarray(y, float) - np.asarray(pred, float)) ** 2, axis=0).tolist()


def average(values: list[float]) -> float:
    """Average a figure over the targets (NaN for no target).

    Parameters
    ----------
    values : list of float
        One figure per target.

    Returns
    -------
    float
        Their mean (``nan`` when ``values`` is empty).
    """
    return float(np.mean(values)) if len(values) else math.nan


@dataclass
class Scores:
    """Per-target test and CV errors of one system (the prior, or the model).

    Every list holds one value per target, in the result's ``targets`` order; errors are in
    the targets' unit (MSE: its square). The bootstrap intervals of the test errors are
    filled in by :func:`~workbench.experiment.scoring.bootstrap.bootstrap_test_scores` (empty: not
    computed).

    Parameters
    ----------
    test_mae, test_mse : list of float
        The mean absolute and mean squared error on the test rows, scored once.
    cv_mae, cv_mse : list of float
        The same estimated on the training rows: the model's by its own CV (the folds of its
        choices, ``[selection]``), the prior's on those folds, or on the training rows where
        the family runs no CV of it; NaN where the family has no CV estimate.
    test_mae_ci : list of [low, high], default=[]
        Per target, the bootstrap interval of ``test_mae`` over the test rows.
    test_mae_avg_ci : list of float, default=[]
        ``[low, high]`` of the average of ``test_mae`` over the targets.
    test_mse_ci : list of [low, high], default=[]
        Per target, the bootstrap interval of ``test_mse``.
    test_mse_avg_ci : list of float, default=[]
        ``[low, high]`` of the average of ``test_mse`` over the targets.
    """

    test_mae: list[float]
    test_mse: list[float]
    cv_mae: list[float]
    cv_mse: list[float]
    test_mae_ci: list[list[float]] = field(default_factory=list)
    test_mae_avg_ci: list[float] = field(default_factory=list)
    test_mse_ci: list[list[float]] = field(default_factory=list)
    test_mse_avg_ci: list[float] = field(default_factory=list)

    def avg(self, key: str) -> float:
        """Average ``key`` over the targets.

        Parameters
        ----------
        key : str
            ``"test_mae"``, ``"cv_mse"``, ...

        Returns
        -------
        float
            The mean (NaN for an empty list).
        """
        return average(getattr(self, key))

    def ci(self, key: str) -> list[list[float]] | None:
        """Gather the bootstrap intervals of ``key``.

        Parameters
        ----------
        key : str
            ``"test_mae"``, ``"test_mse"`` (a model's ``"test_mae_diff"`` too).

        Returns
        -------
        list of [low, high], or None
            One ``[low, high]`` per target, then the average's: the rows
            :func:`~workbench.experiment.figures.mae_bars` takes (``None``: not computed).
        """
        per_target, pooled = getattr(self, f"{key}_ci"), getattr(self, f"{key}_avg_ci")
        if not per_target or not pooled:
            return None
        return [*map(list, per_target), list(pooled)]

    def to_json(self) -> dict[str, Any]:
        """Write the scores as JSON, with each list's average.

        Returns
        -------
        dict
            Every field (intervals only when computed) and ``<key>_avg`` of each error.
        """
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name.endswith("_ci") and not value:  # intervals not computed: no key
                continue
            out[f.name] = value
            if f.name in ("test_mae", "test_mse", "cv_mae", "cv_mse"):
                out[f"{f.name}_avg"] = average(value)
        return out


#: The per-target interval figures of :class:`ModelScores` (empty lists: no intervals).
INTERVAL_KEYS = ("test_coverage", "test_width", "cv_coverage", "cv_width")


@dataclass
class ModelScores(Scores):
    """The model's scores plus what it chose per target.

    The fields of :class:`Scores`, then these (every list one value per target; the interval
    figures empty without prediction intervals, ``[intervals]``, the ``_ci`` lists without
    bootstrap intervals).

    Parameters
    ----------
    test_mae, test_mse, cv_mae, cv_mse, test_mae_ci, test_mae_avg_ci, test_mse_ci, test_mse_avg_ci
        As in :class:`Scores`.
    selected : list of str, default=[]
        Per target, what the model predicts with (the family's word: e.g. ``"boosted"``,
        ``"prior"``, a candidate's name).
    coefs : list of list of float, default=[]
        Per target, the boosting stages' line-search coefficients (empty: none, e.g. where
        the prior was selected).
    extra : dict of str to list of float, default={}
        Family-specific per-target figures (e.g. ``cv_mae_boosted``), written inline in the
        JSON.
    test_coverage, test_width : list of float, default=[]
        The fraction of test rows inside their prediction interval, and the intervals' mean
        width.
    cv_coverage, cv_width : list of float, default=[]
        The same estimated by CV on the training rows.
    test_mae_diff_ci : list of [low, high], default=[]
        The paired bootstrap interval of model - prior test MAE: both systems' errors on the
        same resampled rows (below 0: the model's error is the lower).
    test_mae_diff_avg_ci : list of float, default=[]
        ``[low, high]`` of that difference averaged over the targets.
    """

    selected: list[str] = field(default_factory=list)
    coefs: list[list[float]] = field(default_factory=list)
    extra: dict[str, list[float]] = field(default_factory=dict)
    test_coverage: list[float] = field(default_factory=list)
    test_width: list[float] = field(default_factory=list)
    cv_coverage: list[float] = field(default_factory=list)
    cv_width: list[float] = field(default_factory=list)
    # filled in by bootstrap.bootstrap_test_scores
    test_mae_diff_ci: list[list[float]] = field(default_factory=list)
    test_mae_diff_avg_ci: list[float] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """Write the scores as JSON (:meth:`Scores.to_json`), the family's figures inline.

        Returns
        -------
        dict
            The scores; the interval figures and their averages only when computed.
        """
        out = super().to_json()
        out.update(out.pop("extra"))
        for key in INTERVAL_KEYS:
            if out[key]:
                out[f"{key}_avg"] = average(out[key])
            else:
                del out[key]
        return out


@dataclass
class CVEstimate:
    """A cross-validated estimate of the chosen model.

    Repeated K-fold CV on the training rows (``[evaluation] cv_repeats``: ``repeats`` set) or
    nested CV over all rows, every choice remade in each outer fold (``nested_folds``:
    ``n_rows`` set). Every list holds one value per target.

    Parameters
    ----------
    folds : int
        The folds of the CV.
    seed : int
        The seed of the folds.
    model_mae : list of float
        The model's out-of-fold MAE (repeated CV: the mean over the repeats).
    model_mse : list of float
        The model's out-of-fold MSE (likewise).
    prior_mae : list of float
        The prior's MAE on the same rows.
    repeats : int, default=None
        The repeats of the repeated CV (``None``: a nested CV).
    n_rows : int, default=None
        The rows of the nested CV, training and test (``None``: a repeated CV).
    model_mae_avg_per_repeat : list of float, default=None
        Repeated CV: per repeat, the model's MAE averaged over the targets.
    """

    folds: int
    seed: int
    model_mae: list[float]
    model_mse: list[float]
    prior_mae: list[float]
    repeats: int | None = None
    n_rows: int | None = None
    model_mae_avg_per_repeat: list[float] | None = None

    @property
    def model_mae_avg(self) -> float:
        """The model's MAE averaged over the targets."""
        return average(self.model_mae)

    @property
    def prior_mae_avg(self) -> float:
        """The prior's MAE averaged over the targets."""
        return average(self.prior_mae)

    def to_json(self) -> dict[str, Any]:
        """Write the estimate as JSON.

        Returns
        -------
        dict
            The fields set and the averages over targets.
        """
        out = {k: v for k, v in asdict(self).items() if v is not None}
        out.update(model_mae_avg=self.model_mae_avg, model_mse_avg=average(self.model_mse),
                   prior_mae_avg=self.prior_mae_avg)
        return out
