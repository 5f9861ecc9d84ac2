"""What ``evaluate``, ``sweep`` and ``reproduce`` produce: dataclasses with one ``to_json``.

Modules read fields, never string keys. :meth:`Result.to_json` keeps the JSON that
``--json`` has always written (``targets``, ``prior.test_mae[_avg]``, ``model.test_mae[_avg]``,
``model.test_mse``, ``model.cv_mae[_avg]``, ``model.cv_mse``, ``model.selected``,
``nested_cv_mae[_avg]``, ``best_params``, ``wall_s``, ...), so scripts that read it keep working.
With conformal intervals (``[intervals]``) ``model`` adds ``test_coverage[_avg]``,
``test_width[_avg]``, ``cv_coverage[_avg]`` and ``cv_width[_avg]``, and the result an
``intervals`` section (method, alpha, level, folds).

Every test error comes with a bootstrap interval over the test rows
(:mod:`~workbench.experiment.bootstrap`; a row is one experiment, shared by all its targets,
so the rows are resampled jointly): ``prior`` and ``model`` add ``test_mae_ci`` and ``test_mse_ci``
(per target ``[low, high]``) and ``test_mae_avg_ci``, ``test_mse_avg_ci`` (the average over
targets' ``[low, high]``); ``model`` adds the paired interval of its difference to the prior,
``test_mae_diff_ci`` and ``test_mae_diff_avg_ci`` (model - prior on the same resampled rows:
below 0, the model's error is the lower); the result a ``bootstrap`` section (method,
level, resamples, seed, rows). Only keys are added: a script that read the JSON before reads
it unchanged.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["CVEstimate", "ModelScores", "OuterFold", "Result", "Scores", "SweepSummary", "mae",
           "mse"]


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


def _avg(values: list[float]) -> float:
    return float(np.mean(values)) if len(values) else math.nan


@dataclass
class Scores:
    """Per-target test and CV errors of one system (the prior, or the model).

    With the bootstrap intervals of the test errors (:func:`~.bootstrap.bootstrap_test_scores`;
    empty: not computed): ``test_mae_ci`` one ``[low, high]`` per target, ``test_mae_avg_ci``
    the average over targets' ``[low, high]``; the same for ``test_mse``.
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
        return _avg(getattr(self, key))

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
        per_target, average = getattr(self, f"{key}_ci"), getattr(self, f"{key}_avg_ci")
        if not per_target or not average:
            return None
        return [*map(list, per_target), list(average)]

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
                out[f"{f.name}_avg"] = _avg(value)
        return out


#: The per-target interval figures of :class:`ModelScores` (empty lists: no intervals).
INTERVAL_KEYS = ("test_coverage", "test_width", "cv_coverage", "cv_width")


@dataclass
class ModelScores(Scores):
    """The model's scores plus what it chose per target.

    ``extra``: family-specific per-target figures (e.g. ``cv_mae_boosted``). With prediction
    intervals: per target the fraction of test rows inside their interval (``test_coverage``)
    and the mean width (``test_width``), and the same estimated by CV on the training rows
    (``cv_coverage``, ``cv_width``). With bootstrap intervals, those of model - prior test
    MAE (``test_mae_diff_ci``, ``test_mae_diff_avg_ci``), paired: both systems' errors on the
    same resampled rows.
    """

    selected: list[str] = field(default_factory=list)
    coefs: list[list[float]] = field(default_factory=list)
    extra: dict[str, list[float]] = field(default_factory=dict)
    test_coverage: list[float] = field(default_factory=list)
    test_width: list[float] = field(default_factory=list)
    cv_coverage: list[float] = field(default_factory=list)
    cv_width: list[float] = field(default_factory=list)
    #: The paired bootstrap interval of model - prior test MAE per target and of the average
    #: over targets (below 0: the model's error is the lower;
    #: :func:`~.bootstrap.bootstrap_test_scores`).
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
                out[f"{key}_avg"] = _avg(out[key])
            else:
                del out[key]
        return out


@dataclass
class CVEstimate:
    """A cross-validated estimate of the chosen model.

    Repeated K-fold CV on the training rows (``repeats`` > 0) or nested CV over all rows
    (``n_rows``).
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
        return _avg(self.model_mae)

    @property
    def prior_mae_avg(self) -> float:
        """The prior's MAE averaged over the targets."""
        return _avg(self.prior_mae)

    def to_json(self) -> dict[str, Any]:
        """Write the estimate as JSON.

        Returns
        -------
        dict
            The fields set and the averages over targets.
        """
        out = {k: v for k, v in asdict(self).items() if v is not None}
        out.update(model_mae_avg=self.model_mae_avg, model_mse_avg=_avg(self.model_mse),
                   prior_mae_avg=self.prior_mae_avg)
        return out


@dataclass
class OuterFold:
    """One outer fold of a sweep: its study's best settings refitted and scored."""

    unit: str
    fold: int
    study: str
    mae: float
    prior_mae: float
    selected: str
    n_train: int
    n_val: int
    params: dict[str, Any] | None
    target_mae: dict[str, float]
    target_prior_mae: dict[str, float]


@dataclass
class SweepSummary:
    """What a sweep adds to a result.

    Nested-CV estimates, the chosen parameters per target (a unit's choice repeated for each
    of its targets), the trial counts.
    """

    nested_cv_mae: list[float]
    nested_cv_prior_mae: list[float]
    best_params: list[dict[str, Any] | None]
    trials_per_study: int
    trials_counted: int
    studies: int
    outer_folds: list[OuterFold] = field(default_factory=list)

    @property
    def nested_cv_mae_avg(self) -> float:
        """The model's nested-CV MAE averaged over the targets."""
        return _avg(self.nested_cv_mae)

    @property
    def nested_cv_prior_mae_avg(self) -> float:
        """The prior's nested-CV MAE averaged over the targets."""
        return _avg(self.nested_cv_prior_mae)

    def to_json(self) -> dict[str, Any]:
        """Write the summary as JSON (keys at the result's top level).

        Returns
        -------
        dict
            The nested-CV estimates and averages, the chosen parameters, the trial counts.
        """
        return {"nested_cv_mae": self.nested_cv_mae, "nested_cv_mae_avg": self.nested_cv_mae_avg,
                "nested_cv_prior_mae": self.nested_cv_prior_mae,
                "nested_cv_prior_mae_avg": self.nested_cv_prior_mae_avg,
                "best_params": self.best_params,
                "trials": {"per_study": self.trials_per_study, "counted": self.trials_counted,
                           "studies": self.studies}}


@dataclass
class Result:
    """One ``evaluate`` (or a sweep's final evaluation).

    The model fitted on the training rows and scored once on the test rows. ``details``: the
    family's own JSON-ready section (e.g. ``{"hamiltonian": {...}}``); ``wall_s``: the whole
    command's wall time; ``unit``: the targets' (the dataset's).
    """

    name: str
    config: str | None
    family: str
    targets: list[str]
    n_train: int
    n_test: int
    prior: Scores
    model: ModelScores
    details: dict[str, Any] = field(default_factory=dict)
    repeated_cv: CVEstimate | None = None
    nested_cv_all: CVEstimate | None = None
    sweep: SweepSummary | None = None
    #: The prediction intervals' settings (method, alpha, level, ...); empty: none.
    intervals: dict[str, Any] = field(default_factory=dict)
    #: The test errors' bootstrap intervals' settings (method, level, n_resamples,
    #: random_state, n_rows; :func:`~.bootstrap.bootstrap_test_scores`); empty: none.
    bootstrap: dict[str, Any] = field(default_factory=dict)
    outputs: dict[str, str] = field(default_factory=dict)
    mlflow: dict[str, str] = field(default_factory=dict)
    wall_s: float = math.nan
    #: The targets' unit (the dataset's; ``None``: none), which every error shares (MSE: its
    #: square).
    unit: str | None = None

    def to_json(self) -> dict[str, Any]:
        """Write the result as the JSON ``--json`` writes (see the module docstring).

        Returns
        -------
        dict
            The result; optional sections only when present.
        """
        out: dict[str, Any] = {
            "name": self.name, "config": self.config, "family": self.family,
            "targets": self.targets, "unit": self.unit, "n_train": self.n_train,
            "n_test": self.n_test,
            "prior": self.prior.to_json(), "model": self.model.to_json(), **self.details}
        for key in ("repeated_cv", "nested_cv_all", "sweep"):
            part = getattr(self, key)
            if part is not None:
                out.update(part.to_json() if key == "sweep" else {key: part.to_json()})
        if self.intervals:
            out["intervals"] = self.intervals
        if self.bootstrap:
            out["bootstrap"] = self.bootstrap
        if self.outputs:
            out["outputs"] = self.outputs
        if self.mlflow:
            out["mlflow"] = self.mlflow
        out["wall_s"] = self.wall_s
        return out
