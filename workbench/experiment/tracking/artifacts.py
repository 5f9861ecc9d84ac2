"""Artifacts of runs: files, texts, JSON, figures and input datasets.

The artifact half of :class:`~workbench.experiment.tracking.runs.Tracker`, beside its model
half (:class:`~.models.ModelRecords`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd
from mlflow.data.pandas_dataset import from_pandas  # mlflow.data.from_pandas: no stub sees it
from mlflow.entities import DatasetInput, InputTag
from mlflow.exceptions import MlflowException

from .translate import duplicate_row

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from mlflow import MlflowClient

__all__ = ["ArtifactRecords"]

_logger = logging.getLogger("workbench.experiment.tracking")


class ArtifactRecords:
    """The artifact half of :class:`~workbench.experiment.tracking.runs.Tracker`.

    The tracker gives it ``client`` and ``_errors``.
    """

    @property
    def client(self) -> MlflowClient:
        """The tracker's :class:`mlflow.MlflowClient`."""
        raise NotImplementedError

    def _errors(self, store_call: bool = True) -> contextlib.AbstractContextManager[None]:
        raise NotImplementedError

    def log_dict(self, run_id: str, obj: Any, artifact_file: str) -> None:
        """Log ``obj`` as JSON (``.json``) or YAML (``.yaml``/``.yml``).

        Parameters
        ----------
        run_id : str
            The run.
        obj : object
            JSON-ready data.
        artifact_file : str
            Its path among the run's artifacts.
        """
        with self._errors():
            self.client.log_dict(run_id, obj, artifact_file)

    def log_text(self, run_id: str, text: str, artifact_file: str) -> None:
        """Log ``text`` as an artifact file.

        Parameters
        ----------
        run_id : str
            The run.
        text : str
            The file's text.
        artifact_file : str
            Its path among the run's artifacts.
        """
        with self._errors():
            self.client.log_text(run_id, text, artifact_file)

    def log_file(self, run_id: str, path: str | os.PathLike,
                 artifact_path: str | None = None) -> None:
        """Copy a local file (or directory) into the run's artifacts.

        Parameters
        ----------
        run_id : str
            The run.
        path : path-like
            The file or directory.
        artifact_path : str, default=None
            The directory among the run's artifacts (``None``: the top).
        """
        path = Path(path)
        with self._errors():
            if path.is_dir():
                self.client.log_artifacts(run_id, str(path), artifact_path)
            else:
                self.client.log_artifact(run_id, str(path), artifact_path)

    def log_figure(self, run_id: str, fig: Figure, artifact_file: str) -> None:
        """Log a matplotlib figure, saved in the format of ``artifact_file``'s suffix (PNG).

        Parameters
        ----------
        run_id : str
            The run.
        fig : matplotlib.figure.Figure
            The figure.
        artifact_file : str
            Its path among the run's artifacts.
        """
        with self._errors():
            self.client.log_figure(run_id, fig, artifact_file)

    def log_dataset(self, run_id: str, frame: pd.DataFrame, *, name: str, context: str,
                    source: str | None = None, targets: str | None = None) -> str:
        """Record ``frame`` as an input dataset of the run.

        MLflow's name, digest and schema (the runs table's "Dataset" column), tagged
        ``mlflow.data.context``.

        Parameters
        ----------
        run_id : str
            The run.
        frame : DataFrame
            The data.
        name : str
            The dataset's name.
        context : str
            Its role, e.g. ``train`` or ``test``.
        source : str, default=None
            Where it came from.
        targets : str, default=None
            Its target column.

        Returns
        -------
        str
            MLflow's digest of the data.
        """
        with warnings.catch_warnings():  # a local path "can be interpreted in multiple ways"
            warnings.simplefilter("ignore", UserWarning)
            # its hint omits None, its default (None: "the code location")
            dataset = from_pandas(frame, source=source,  # type: ignore[arg-type]
                                  name=name, targets=targets)
        inputs = [DatasetInput(dataset._to_mlflow_entity(),
                               tags=[InputTag("mlflow.data.context", context)])]
        with self._errors():
            try:
                self.client.log_inputs(run_id, inputs)
            except MlflowException as exc:
                if not duplicate_row(exc):
                    raise
                # Another process created the same dataset row (experiment, name, digest)
                # between MLflow's lookup and its insert (two first runs at once): the row
                # exists now, and the second attempt links this run to it.
                _logger.debug("log_inputs raced another process (%s); trying again", exc)
                self.client.log_inputs(run_id, inputs)
        return dataset.digest
