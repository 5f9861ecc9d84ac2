"""What a model family reports of a fitted model.

:class:`Artifacts` holds a fitted model's figures, tables and data; :class:`ResultMethods` is
the part of the family interface (:class:`~workbench.experiment.families.base.ModelFamily`)
that labels, scores and draws a fitted model, with defaults for a family whose one model
predicts every target together.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from ..._io import atomic_write
from ..figures import save_figure
from ..scoring.scores import ModelScores, Scores, mae, mse

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import ExperimentConfig

__all__ = ["Artifacts", "ResultMethods"]


@dataclass
class Artifacts:
    """A fitted model's extra outputs.

    Parameters
    ----------
    figures : dict
        Name -> matplotlib Figure.
    tables : dict
        Name -> DataFrame, written as CSV without the index.
    data : dict
        JSON-ready data.
    """

    figures: dict[str, Any] = field(default_factory=dict)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)

    def write(self, directory: str | Path, *, tables: bool = True, figures: bool = True,
              data: bool = True) -> dict[str, Any]:
        """Write the tables as CSV (no index column), the figures as PNG, the data as JSON.

        As ``<directory>/<name>.csv``, ``<name>.png`` and ``<name>.json``.

        Parameters
        ----------
        directory : str or Path
            Created if missing.
        tables, figures, data : bool, default=True
            Whether to write the tables, the figures, the data.

        Returns
        -------
        dict
            Name -> path written (a figure's, where a table or data share its name).
        """
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        written: dict[str, Any] = {}
        for name, value in (self.data.items() if data else ()):
            written[name] = atomic_write(directory / f"{name}.json",
                                         json.dumps(value, indent=2, default=str))
        for name, table in (self.tables.items() if tables else ()):
            written[name] = atomic_write(directory / f"{name}.csv", table.to_csv(index=False))
        for name, fig in (self.figures.items() if figures else ()):
            written[name] = save_figure(fig, directory / f"{name}.png")
        return written


class ResultMethods:
    """The results part of a model family: per-target labels, scores, figures and tables.

    :class:`~workbench.experiment.families.base.ModelFamily` inherits it; a family overrides
    what its fitted model reports differently.
    """

    @property
    def writes_outputs(self) -> bool:
        """Whether :meth:`outputs` has tables and figures for ``evaluate --out``.

        True when the family overrides it.
        """
        return type(self).outputs is not ResultMethods.outputs

    def selected(self, model: Any, targets: list[str]) -> list[str]:
        """Say what the fitted model chose per target.

        Parameters
        ----------
        model : estimator
            The family's fitted model.
        targets : list of str
            Its targets.

        Returns
        -------
        list of str
            One label per target (default: its ``selected_`` or "model").
        """
        return list(getattr(model, "selected_", ["model"] * len(targets)))

    def scores(self, ds: Dataset, model: Any, Y_train: pd.DataFrame, prior_test: Any,
               y_test: Any, pred: Any) -> tuple[Scores, ModelScores, dict[str, Any]]:
        """Score the prior and a fitted model, and collect the family's details.

        Default: no CV inside the model, so the prior's CV error is its training error (it
        is not fitted) and the model's CV error is unknown (NaN) unless ``[evaluation]``
        asks for a repeated CV.

        Parameters
        ----------
        ds : Dataset
            The dataset.
        model : estimator
            The family's fitted model.
        Y_train : DataFrame
            The training rows' targets.
        prior_test, y_test, pred : ndarray
            The test rows' prior, measured targets and predictions.

        Returns
        -------
        prior : Scores
            The prior's scores.
        model : ModelScores
            The model's scores.
        details : dict
            The family's JSON-ready details.
        """
        prior_train = ds.prior.loc[Y_train.index].to_numpy()
        nan = [float("nan")] * len(ds.target_names)
        prior = Scores(test_mae=mae(y_test, prior_test), test_mse=mse(y_test, prior_test),
                       cv_mae=mae(Y_train, prior_train), cv_mse=mse(Y_train, prior_train))
        scores = ModelScores(test_mae=mae(y_test, pred), test_mse=mse(y_test, pred),
                             cv_mae=list(nan), cv_mse=list(nan),
                             selected=self.selected(model, ds.target_names))
        return prior, scores, {}

    def run_metrics(self, details: dict[str, Any]) -> dict[str, float]:
        """Give the MLflow metrics a tracked run has beyond every run's scores.

        Parameters
        ----------
        details : dict
            The family's section of the result (:meth:`scores`' details).

        Returns
        -------
        dict of str to float
            Metric name -> value (default: none).
        """
        return {}

    def begin_artifacts(self, cfg: ExperimentConfig, ds: Dataset, model: Any, setting: str,
                        quick: bool = False) -> Callable[..., Artifacts]:
        """Start the figures and tables a tracked run has beyond :meth:`outputs`.

        They come beside the MAE/MSE bars every run has and the family's :meth:`outputs`
        (which a run logs too); they are computed before the run is recorded
        (``workbench.experiment.runs.run_outputs.compute_outputs``).

        In two halves: start what can run on the worker processes (e.g. learning-curve
        fits) and return a function ``finish(emit=None)`` that waits for it, draws the
        figures and returns the :class:`Artifacts`, so the run's other figures are drawn
        meanwhile. ``emit(name, figure)``, if given, receives every figure as soon as it is
        drawn.

        Parameters
        ----------
        cfg : ExperimentConfig
            The run's config.
        ds : Dataset
            The run's dataset.
        model : estimator
            The family's fitted model.
        setting : str
            What the figures' titles say the run was.
        quick : bool, default=False
            Fewer points and rows (tests).

        Returns
        -------
        callable
            ``finish(emit=None) -> Artifacts``. Default: nothing started, nothing beyond
            :meth:`outputs`.
        """
        def finish(emit: Callable[[str, Any], None] | None = None) -> Artifacts:
            return Artifacts()

        return finish

    def outputs(self, model: Any, ds: Dataset, setting: str) -> Artifacts | None:
        """Make what ``evaluate --out DIR`` writes.

        Parameters
        ----------
        model : estimator
            The family's fitted model.
        ds : Dataset
            The dataset it was fitted on.
        setting : str
            What the figures' titles say the run was.

        Returns
        -------
        Artifacts or None
            ``None``: the family writes nothing (the default).
        """
        return None
