"""What ``evaluate``, ``sweep`` and ``reproduce`` produce: dataclasses with one ``to_json``.

Modules read fields, never string keys. :meth:`Result.to_json` keeps the JSON that
``--json`` has always written (``targets``, ``prior.test_mae[_avg]``, ``model.test_mae[_avg]``,
``model.test_mse``, ``model.cv_mae[_avg]``, ``model.cv_mse``, ``model.selected``,
``nested_cv_mae[_avg]``, ``best_params``, ``wall_s``, ...), so scripts that read it keep working.
With conformal intervals (``[intervals]``) ``model`` adds ``test_coverage[_avg]``,
``test_width[_avg]``, ``cv_coverage[_avg]`` and ``cv_width[_avg]``, and the result an
``intervals`` section (method, alpha, level, folds).

Every test error comes with a bootstrap interval over the test rows
(:mod:`~workbench.experiment.scoring.bootstrap`; a row is one experiment, shared by all its targets,
so the rows are resampled jointly): ``prior`` and ``model`` add ``test_mae_ci`` and ``test_mse_ci``
(per target ``[low, high]``) and ``test_mae_avg_ci``, ``test_mse_avg_ci`` (the average over
targets' ``[low, high]``); ``model`` adds the paired interval of its difference to the prior,
``test_mae_diff_ci`` and ``test_mae_diff_avg_ci`` (model - prior on the same resampled rows:
below 0, the model's error is the lower); the result a ``bootstrap`` section (method,
level, resamples, seed, rows). Only keys are added: a script that read the JSON before reads
it unchanged.

The score records a result holds (:class:`~workbench.experiment.scoring.scores.Scores`,
:class:`~workbench.experiment.scoring.scores.ModelScores`,
:class:`~workbench.experiment.scoring.scores.CVEstimate`) and the per-target errors live in
:mod:`workbench.experiment.scoring.scores`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from .scores import CVEstimate, ModelScores, Scores, average

__all__ = ["OuterFold", "Result", "SweepSummary"]


@dataclass
class OuterFold:
    """One outer fold of a sweep: its study's best settings refitted and scored.

    The study searched on the fold's training rows (inner CV); its best trial's settings are
    refitted on them and scored on the fold's validation rows, which no trial saw.

    Parameters
    ----------
    block : str
        The study block: the targets the study chose settings for together (the family's
        :meth:`~workbench.experiment.families.base.ModelFamily.blocks`).
    fold : int
        The outer fold's index (over all ``[cv] repeats``).
    study : str
        The study's name (``<sweep>.<block>.outer<fold>``).
    mae : float
        The refitted model's MAE on the validation rows, averaged over the block's targets.
    prior_mae : float
        The prior's, likewise.
    selected : str
        What the refitted model predicts with (comma-separated per target; ``"prior"`` when
        no trial completed: the prior then stands).
    n_train, n_val : int
        The fold's training and validation rows.
    params : dict or None
        The best trial's settings (``None``: no trial completed).
    target_mae, target_prior_mae : dict of str to float
        Per target of the block, the model's and the prior's MAE on the validation rows.
    """

    block: str
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

    Nested-CV estimates, the chosen parameters per target (a block's choice repeated for each
    of its targets), the trial counts; every list one value per target.

    Parameters
    ----------
    nested_cv_mae : list of float
        The model's MAE over the outer folds' validation rows (the mean over the folds): the
        sweep's estimate of the error of its whole search.
    nested_cv_prior_mae : list of float
        The prior's, on the same rows.
    best_params : list of dict or None
        The settings the final study chose (``None``: no trial completed).
    trials_per_study : int
        The trials each study was given (``[study] trials``).
    trials_counted : int
        The trials that used a study's budget, over all studies (stale trials re-queued and
        surplus ones not counted).
    studies : int
        The studies: per block, one per outer fold and the final one.
    outer_folds : list of OuterFold, default=[]
        Each outer fold's refit and scores.
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
        return average(self.nested_cv_mae)

    @property
    def nested_cv_prior_mae_avg(self) -> float:
        """The prior's nested-CV MAE averaged over the targets."""
        return average(self.nested_cv_prior_mae)

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

    The model fitted on the training rows and scored once on the test rows;
    :meth:`to_json` writes it as ``--json`` does.

    Parameters
    ----------
    name : str
        What ran: the config's name (``reproduce``: a system's, e.g. ``"peer"``).
    config : str or None
        The config file (``None``: the config has no file).
    family : str
        The model family (``[model] family``).
    targets : list of str
        The targets, the order of every per-target list.
    n_train, n_test : int
        The training and test rows.
    prior : Scores
        The prior's (the scientific model's) errors.
    model : ModelScores
        The model's errors and choices.
    details : dict, default={}
        The family's own JSON-ready section (e.g. ``{"hamiltonian": {...}}``), written at
        the JSON's top level.
    repeated_cv : CVEstimate, default=None
        The repeated CV of ``[evaluation] cv_repeats`` (``None``: not run).
    nested_cv_all : CVEstimate, default=None
        The nested CV over all rows of ``[evaluation] nested_folds`` (``None``: not run).
    sweep : SweepSummary, default=None
        What a sweep adds (``None``: not a sweep).
    intervals : dict, default={}
        The prediction intervals' settings (method, alpha, level, ...; empty: none).
    bootstrap : dict, default={}
        The test errors' bootstrap intervals' settings (method, level, n_resamples,
        random_state, n_rows; :func:`~workbench.experiment.scoring.bootstrap.bootstrap_test_scores`;
        empty: none).
    outputs : dict of str to str, default={}
        The files ``--out`` wrote, by name (empty: none).
    mlflow : dict of str to str, default={}
        Where the run was recorded (tracking URI, experiment, run, model, registered
        version; empty: not tracked).
    wall_s : float, default=nan
        The whole command's wall time, in seconds.
    unit : str, default=None
        The targets' unit (the dataset's; ``None``: none), which every error shares (MSE: its
        square).
    folds : str, default=""
        Which CV folds made the model's choices, e.g. ``"5 forward-chaining by `date`"``,
        ``"5 by groups `device`"``, ``"5 shuffled"`` (:func:`~.folds.describe_folds`; empty:
        not known).
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
    intervals: dict[str, Any] = field(default_factory=dict)
    bootstrap: dict[str, Any] = field(default_factory=dict)
    outputs: dict[str, str] = field(default_factory=dict)
    mlflow: dict[str, str] = field(default_factory=dict)
    wall_s: float = math.nan
    unit: str | None = None
    folds: str = ""

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
            "n_test": self.n_test, **({"folds": self.folds} if self.folds else {}),
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
