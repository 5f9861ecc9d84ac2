"""Models in the store: a fitted model logged as an MLflow pyfunc model, registered, loaded.

The ``workbench`` package travels with a logged model; a registered version gets an alias.
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import logging
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mlflow
import numpy as np
import pandas as pd
from mlflow.entities import LoggedModelOutput
from mlflow.exceptions import MlflowException

import workbench

from ..process.errors import TrackingError
from .records import tag_value
from .serving import WorkbenchModel, model_signature

if TYPE_CHECKING:
    from mlflow import MlflowClient
    from mlflow.models import ModelSignature
    from mlflow.pyfunc import PyFuncModel

__all__ = ["CHAMPION", "MODEL_REQUIREMENTS", "ModelRecords"]

#: The alias the newest registered version gets (aliases, not the deprecated stages).
CHAMPION = "champion"
#: Distributions pinned in a logged model's requirements (those installed).
MODEL_REQUIREMENTS = ("mlflow", "cloudpickle", "numpy", "pandas", "scipy", "scikit-learn",
                      "lightgbm", "joblib")


def _requirements() -> list[str]:
    reqs = []
    for dist in MODEL_REQUIREMENTS:
        try:
            reqs.append(f"{dist}=={importlib.metadata.version(dist)}")
        except importlib.metadata.PackageNotFoundError:
            pass
    return reqs


class _DropMessages(logging.Filter):
    """Drop log records containing one of ``texts`` (MLflow's notices for deliberate choices)."""

    def __init__(self, *texts: str) -> None:
        super().__init__()
        self.texts = texts

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        return not any(t in message for t in self.texts)


@contextlib.contextmanager
def _quiet(logger_name: str, *texts: str) -> Iterator[None]:
    log, flt = logging.getLogger(logger_name), _DropMessages(*texts)
    log.addFilter(flt)
    try:
        yield
    finally:
        log.removeFilter(flt)


def _save_model(tmp: Path, wrapped: WorkbenchModel, meta: mlflow.models.Model,
                signature: ModelSignature, example: pd.DataFrame,
                texts: Mapping[str, str] | None) -> Path:
    """Save ``wrapped`` as a pyfunc model directory in ``tmp``, the package as its code.

    The first 5 rows of ``example`` are the input example; ``texts`` (file name -> text) are
    written beside ``MLmodel``. Returns the model directory.
    """
    code = tmp / "code" / "workbench"
    shutil.copytree(Path(workbench.__file__).parent, code,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    local = tmp / "model"
    # cloudpickle is the deliberate choice here (the docs' "models from code" would need a
    # script per model): silence MLflow's notice about it for this call.
    with _quiet("mlflow.pyfunc", "serialized using CloudPickle", "Validating input example"):
        mlflow.pyfunc.save_model(
            str(local), python_model=wrapped, mlflow_model=meta,
            signature=signature, input_example=example.head(5),
            metadata={"workbench": {"inputs": wrapped.columns,
                                    "targets": wrapped.targets,
                                    "outputs": wrapped.outputs}},
            pip_requirements=_requirements(), code_paths=[str(code)])
    for file_name, text in (texts or {}).items():  # config.toml beside MLmodel
        (local / file_name).write_text(text, encoding="utf-8")
    return local


class ModelRecords:
    """The model half of :class:`~workbench.experiment.tracking.runs.Tracker`.

    The tracker gives it ``client``, ``experiment_id`` and ``_errors``.
    """

    @property
    def client(self) -> MlflowClient:
        """The tracker's :class:`mlflow.MlflowClient`."""
        raise NotImplementedError

    @property
    def experiment_id(self) -> str:
        """The tracker's experiment id."""
        raise NotImplementedError

    def _errors(self, store_call: bool = True) -> contextlib.AbstractContextManager[None]:
        raise NotImplementedError

    def log_model(self, run_id: str, model: Any, input_example: pd.DataFrame,
                  name: str = "model", *, targets: list[str] | None = None,
                  texts: Mapping[str, str] | None = None) -> str:
        """Log a fitted model as an MLflow pyfunc model linked to ``run_id``.

        The model is cloudpickled inside :class:`~.serving.WorkbenchModel` (checks the input
        table by column name, returns one column per target and ``<target>_lower/_upper`` when
        the model has intervals); the ``workbench`` package is stored with it (``code_paths``),
        so it loads with ``mlflow.pyfunc.load_model`` (and serves with ``mlflow models serve``)
        where only the pinned requirements are installed. The signature names
        ``input_example``'s columns and the outputs; the first 5 rows are the input example (the
        REST request's template). Requirements are pinned from the installed versions (no
        inference subprocess).

        Parameters
        ----------
        run_id : str
            The run the model comes from.
        model : fitted estimator
            ``predict(DataFrame)`` -> DataFrame or array; optionally ``predict_interval``.
        input_example : DataFrame
            Rows of the model's input columns.
        name : str, default="model"
            The logged model's name.
        targets : list of str, default=None
            The target names (``None``: the columns of ``model.predict``).
        texts : mapping, default=None
            File name -> text written in the model directory (e.g. ``{"config.toml": ...}``,
            credentials redacted by the caller).

        Returns
        -------
        str
            The model's URI, ``models:/<model_id>``.

        Raises
        ------
        TrackingError
            The store cannot take the model (it is then marked ``FAILED``).
        """
        example = pd.DataFrame(input_example)
        if targets is None:
            pred = model.predict(example.head(2))
            targets = ([str(c) for c in pred.columns] if isinstance(pred, pd.DataFrame)
                       else [f"y{j}" for j in range(np.asarray(pred).reshape(2, -1).shape[1])])
        wrapped = WorkbenchModel(model, list(example.columns), targets)
        signature = model_signature(wrapped.columns, wrapped.outputs)
        experiment_id = self.experiment_id
        with self._errors():
            logged = self.client.create_logged_model(experiment_id, name=name,
                                                     source_run_id=run_id)
        try:
            with tempfile.TemporaryDirectory(prefix="workbench-model-") as tmp:
                meta = mlflow.models.Model(artifact_path=logged.artifact_location, run_id=run_id,
                                           model_uuid=logged.model_id, model_id=logged.model_id)
                local = _save_model(Path(tmp), wrapped, meta, signature, example, texts)
                with self._errors():
                    self.client.log_model_artifacts(logged.model_id, str(local))
            with self._errors():
                self.client.log_outputs(run_id, [LoggedModelOutput(logged.model_id, step=0)])
                self.client.finalize_logged_model(logged.model_id, "READY")
        except BaseException:
            with contextlib.suppress(Exception):
                self.client.finalize_logged_model(logged.model_id, "FAILED")
            raise
        return f"models:/{logged.model_id}"

    def register_model(self, model_uri: str, name: str, *, run_id: str | None = None,
                       tags: Mapping[str, Any] | None = None, description: str | None = None,
                       alias: str = CHAMPION) -> str:
        """Register a logged model as a new version and point ``alias`` at it.

        Parameters
        ----------
        model_uri : str
            ``models:/<model_id>`` (from :meth:`log_model`).
        name : str
            The registered model (created if missing) in this store's Model Registry.
        run_id : str, default=None
            The run the version comes from.
        tags : mapping, default=None
            Tags of the version.
        description : str, default=None
            The version's description.
        alias : str, default=CHAMPION
            The alias set to the new version.

        Returns
        -------
        str
            The version number.

        Raises
        ------
        TrackingError
            The registered model cannot be created.
        """
        model_id = model_uri.removeprefix("models:/")
        with self._errors():
            try:
                self.client.create_registered_model(
                    name, description="Registered by workbench evaluate/sweep --register")
            except MlflowException as exc:
                if exc.error_code not in ("RESOURCE_ALREADY_EXISTS", "ALREADY_EXISTS"):
                    raise TrackingError(f"cannot register model {name!r}: {exc.message}") \
                        from None
            # the artifact location as source: MLflow's SQL registry would resolve a
            # models:/ source through the *global* tracking URI, not this client's store
            source = self.client.get_logged_model(model_id).artifact_location
            version = self.client.create_model_version(
                name, source=source, run_id=run_id, model_id=model_id,
                tags={"model_id": model_id,
                      **{str(k): tag_value(v) for k, v in (tags or {}).items()}},
                description=description)
            self.client.set_registered_model_alias(name, alias, version.version)
        return str(version.version)

    def model_artifact_uri(self, model_uri: str) -> str:
        """Return the artifact location of ``models:/<model_id>``.

        Loadable without a tracking URI, e.g.
        ``mlflow.pyfunc.load_model(tracker.model_artifact_uri(uri))``.

        Parameters
        ----------
        model_uri : str
            ``models:/<model_id>``.

        Returns
        -------
        str
            The artifact location.
        """
        model_id = model_uri.removeprefix("models:/").split("/")[0]
        with self._errors():
            return self.client.get_logged_model(model_id).artifact_location

    def load_model(self, model_uri: str) -> PyFuncModel:
        """Load a model of this store with ``mlflow.pyfunc.load_model`` (no global state used).

        Parameters
        ----------
        model_uri : str
            ``models:/<model_id>``, or any location MLflow loads from.

        Returns
        -------
        mlflow.pyfunc.PyFuncModel
            The loaded model.
        """
        if model_uri.startswith("models:/"):
            model_uri = self.model_artifact_uri(model_uri)
        with self._errors(store_call=False):  # files only: a Ctrl-C stops it at once
            return mlflow.pyfunc.load_model(model_uri)
