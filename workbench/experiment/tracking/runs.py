"""Runs in the store: :class:`Tracker`, an explicit MLflow client bound to one experiment.

One tracking URI and one experiment: runs, nested runs, params, metrics, tags, artifacts
(files, texts, JSON, figures), input datasets and models (logged, registered, loaded; the
model directory is made by :func:`~.models.save_pyfunc_model`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import tempfile
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mlflow
import numpy as np
import pandas as pd
from mlflow import MlflowClient
from mlflow.data.pandas_dataset import from_pandas  # mlflow.data.from_pandas: no stub sees it
from mlflow.entities import DatasetInput, InputTag, LoggedModelOutput, Metric, Param, RunTag
from mlflow.exceptions import MlflowException

from ..process.errors import SweepTimedOut, TrackingError, redact
from ..process.signals import ignoring_signals, interrupts_deferred
from .models import CHAMPION, save_pyfunc_model
from .records import now_ms, param_value, tag_value
from .serving import WorkbenchModel, model_signature
from .store_template import copy_store_template, keep_store_template
from .translate import duplicate_row, translate
from .uris import describe_store, is_database, prepare_store_location, sqlite_path
from .views import RUNS_VIEW, SHARED_VIEW_PREFIX

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from mlflow.pyfunc import PyFuncModel

__all__ = ["Tracker", "ensure_store"]

_logger = logging.getLogger("workbench.experiment.tracking")

PARENT_TAG = "mlflow.parentRunId"
SKIPPED_METRICS_TAG = "workbench.skipped_metrics"
TRUNCATED_PARAMS_TAG = "workbench.truncated_params"
_RUN_STATUSES = ("FINISHED", "FAILED", "KILLED")
#: MLflow 3's UI opens an experiment without this tag in its GenAI (traces) view; this value
#: opens it in the model-training view (runs, metrics, charts, models).
EXPERIMENT_KIND_TAG = "mlflow.experimentKind"
EXPERIMENT_KIND = "custom_model_development"
#: Significant digits of a logged metric (a test MAE over 41 rows: far below its noise).
METRIC_DIGITS = 7


class Tracker:
    """Log runs of one experiment to one tracking store through an explicit client.

    The client is created on first use; constructing a ``Tracker`` touches nothing.

    Parameters
    ----------
    tracking_uri : str
        E.g. :func:`default_tracking_uri` or :func:`resolve_tracking_uri`'s result.
    experiment_name : str
        Created on first use (with ``artifact_location=artifact_root``) if missing.
    artifact_root : str, default=None
        Artifact location for a new experiment. ``None``: ``artifacts/`` next to a SQLite
        database file, the server's default otherwise. An existing experiment keeps its own.
    """

    def __init__(self, tracking_uri: str, experiment_name: str,
                 artifact_root: str | None = None) -> None:
        self.tracking_uri = str(tracking_uri)
        self.experiment_name = experiment_name
        if artifact_root is None and (path := sqlite_path(self.tracking_uri)):
            artifact_root = (path.resolve().parent / "artifacts").as_uri()
        self.artifact_root = artifact_root
        self._client: MlflowClient | None = None
        self._experiment_id: str | None = None
        self._skipped: dict[str, set[str]] = {}

    def __repr__(self) -> str:
        """Show the store (password redacted), the experiment and the artifact root."""
        return (f"Tracker({redact(self.tracking_uri)!r}, {self.experiment_name!r}, "
                f"artifact_root={self.artifact_root!r})")

    def __getstate__(self) -> dict[str, Any]:
        """Drop the client for pickling: worker processes rebuild it on first use."""
        state = self.__dict__.copy()
        state["_client"] = None
        return state

    @contextlib.contextmanager
    def _errors(self, store_call: bool = True) -> Iterator[None]:
        """Re-raise store problems as :class:`TrackingError`.

        On a database store a Ctrl-C waits for a ``store_call`` to end
        (:func:`interrupts_deferred`): raised inside SQLAlchemy it left the connection holding
        the database's lock while the exception lived; the run's end waited 20 s for it.
        """
        deferred = store_call and is_database(self.tracking_uri)
        with interrupts_deferred() if deferred else contextlib.nullcontext():
            try:
                yield
            except TrackingError:
                raise
            except Exception as exc:
                err = translate(exc, self.tracking_uri)
                if err is None:
                    raise
                raise err from exc

    @property
    def client(self) -> MlflowClient:
        """The :class:`mlflow.MlflowClient`, created (with its store) on first use.

        A new SQLite store starts as a copy of :func:`~.store_template.store_template` (MLflow's
        migrations run once per machine and MLflow version; the first store they make is
        kept as the template).

        Raises
        ------
        TrackingError
            The store cannot be used.
        """
        if self._client is None:
            prepare_store_location(self.tracking_uri)
            path = sqlite_path(self.tracking_uri)
            new = path is not None and not path.exists() and not copy_store_template(path)
            with self._errors():
                self._client = MlflowClient(self.tracking_uri)
            if new and path is not None:  # MLflow created and migrated it: keep an empty copy
                keep_store_template(path)
        return self._client

    @property
    def experiment_id(self) -> str:
        """The experiment's id; the experiment is created if it does not exist.

        Raises
        ------
        TrackingError
            The experiment cannot be created, or is deleted.
        """
        if self._experiment_id is None:
            client = self.client
            with self._errors():
                exp = client.get_experiment_by_name(self.experiment_name)
                if exp is None:
                    try:
                        client.create_experiment(self.experiment_name,
                                                 artifact_location=self.artifact_root,
                                                 tags={EXPERIMENT_KIND_TAG: EXPERIMENT_KIND})
                    except MlflowException as exc:
                        # Another process may have created it meanwhile: look it up again.
                        if translate(exc, self.tracking_uri) is not None:
                            raise
                        _logger.debug("create_experiment(%r) failed (%s); looking it up again",
                                      self.experiment_name, exc)
                    exp = client.get_experiment_by_name(self.experiment_name)
                    if exp is None:
                        raise TrackingError(f"could not create experiment "
                                            f"{self.experiment_name!r} in "
                                            f"{describe_store(self.tracking_uri)}")
            if exp.lifecycle_stage != "active":
                raise TrackingError(
                    f"experiment {self.experiment_name!r} (id {exp.experiment_id}) in "
                    f"{describe_store(self.tracking_uri)} is deleted; restore it "
                    f"('mlflow experiments restore --experiment-id {exp.experiment_id}') or use "
                    "another name")
            if EXPERIMENT_KIND_TAG not in exp.tags:  # else MLflow's UI opens its GenAI view
                with self._errors():
                    client.set_experiment_tag(exp.experiment_id, EXPERIMENT_KIND_TAG,
                                              EXPERIMENT_KIND)
            self._experiment_id = exp.experiment_id
        return self._experiment_id

    # ----------------------------------------------------------------- runs

    def start_run(self, name: str, *, parent_run_id: str | None = None,
                  tags: Mapping[str, Any] | None = None,
                  params: Mapping[str, Any] | None = None,
                  start_time: float | None = None) -> str:
        """Create a run (a child of ``parent_run_id`` if given) and return its id.

        Parameters
        ----------
        name : str
            The run's name.
        parent_run_id : str, default=None
            The parent run.
        tags, params : mapping, default=None
            Tags and params to log with it.
        start_time : float, default=None
            When the run's work began (seconds since the epoch; ``None``: now), for a run logged
            after the work it records.

        Returns
        -------
        str
        """
        all_tags = {str(k): tag_value(v) for k, v in (tags or {}).items()}
        if parent_run_id:
            all_tags[PARENT_TAG] = parent_run_id
        experiment_id = self.experiment_id
        with self._errors():
            run = self.client.create_run(
                experiment_id, run_name=name, tags=all_tags,
                start_time=None if start_time is None else int(start_time * 1000))
        run_id = run.info.run_id
        if params:
            self.log_params(run_id, params)
        return run_id

    def end_run(self, run_id: str, status: str = "FINISHED",
                end_time: float | None = None) -> None:
        """Mark the run ``FINISHED``, ``FAILED`` or ``KILLED`` (``status``).

        ``end_time``: when its work ended (seconds since the epoch; ``None``: now).

        Raises
        ------
        ValueError
            An unknown status.
        """
        if status not in _RUN_STATUSES:
            raise ValueError(f"status must be one of {_RUN_STATUSES}, got {status!r}")
        with self._errors():
            self.client.set_terminated(
                run_id, status=status,
                end_time=None if end_time is None else int(end_time * 1000))

    @contextlib.contextmanager
    def run(self, name: str, parent_run_id: str | None = None,
            tags: Mapping[str, Any] | None = None,
            params: Mapping[str, Any] | None = None) -> Iterator[str]:
        """Run a block inside a run: ``with tracker.run("fold-0", parent_run_id=pid) as run_id:``.

        The run ends ``FINISHED``, or ``FAILED`` (``KILLED`` on ``KeyboardInterrupt`` or a
        sweep's timeout, :class:`~workbench.experiment.process.errors.SweepTimedOut`) and the error
        is re-raised. The arguments are :meth:`start_run`'s.

        Yields
        ------
        str
            The run id.
        """
        run_id = self.start_run(name, parent_run_id=parent_run_id, tags=tags, params=params)
        try:
            yield run_id
        except BaseException as exc:
            stopped = isinstance(exc, (KeyboardInterrupt, SweepTimedOut))
            status = "KILLED" if stopped else "FAILED"
            with ignoring_signals():  # a second Ctrl-C does not stop the end being written
                try:
                    self.end_run(run_id, status)
                except Exception as end_exc:  # never mask the original error
                    # the store is away: its own error says so once, and the next command
                    # on the store marks the run FAILED
                    away = isinstance(end_exc, TrackingError) and isinstance(exc, TrackingError)
                    _logger.log(logging.DEBUG if away else logging.WARNING,
                                "could not mark run %s %s: %s", run_id, status, end_exc)
            raise
        else:
            with ignoring_signals():
                self.end_run(run_id, "FINISHED")

    # ----------------------------------------------------------------- params, metrics, tags

    def _log_batch(self, run_id: str, *, metrics: Sequence[Metric] = (),
                   params: Sequence[Param] = (), tags: Sequence[RunTag] = ()) -> None:
        # MlflowClient.log_batch splits into the store's batch limits itself
        """Log metrics, params and tags in one request (MLflow splits it to the store's limits)."""
        with self._errors():
            self.client.log_batch(run_id, metrics=list(metrics), params=list(params),
                                  tags=list(tags))

    def log_params(self, run_id: str, params: Mapping[str, Any]) -> None:
        """Log params, values as strings.

        A value longer than 6000 characters is truncated, with a note in the value and the key
        in the tag ``workbench.truncated_params``.

        Parameters
        ----------
        run_id : str
            The run.
        params : mapping
            Name to value.
        """
        items, truncated = [], []
        for key, value in params.items():
            text, cut = param_value(str(key), value)
            items.append(Param(str(key), text))
            if cut:
                truncated.append(str(key))
        tags = [RunTag(TRUNCATED_PARAMS_TAG, tag_value(",".join(truncated)))] if truncated else []
        self._log_batch(run_id, params=items, tags=tags)

    def log_metrics(self, run_id: str, metrics: Mapping[str, float],
                    step: int | None = None) -> None:
        """Log metrics in one batch, each to :data:`METRIC_DIGITS` significant digits.

        MLflow's runs table then shows it whole, not cut to ``0.31870539...``; ``result.json``
        keeps every digit. NaN/inf values are skipped and their names recorded in the tag
        ``workbench.skipped_metrics``.

        Parameters
        ----------
        run_id : str
            The run.
        metrics : mapping
            Name to value.
        step : int, default=None
            The metrics' step (0 when ``None``).
        """
        ts, items, skipped = now_ms(), [], []
        for key, value in metrics.items():
            value = float(value)
            if math.isfinite(value):
                value = float(f"{value:.{METRIC_DIGITS}g}")
                items.append(Metric(str(key), value, ts, int(step or 0)))
            else:
                skipped.append(str(key))
        tags = []
        if skipped:
            seen = self._skipped.setdefault(run_id, set())
            seen.update(f"{k}@{int(step or 0)}" if step is not None else k for k in skipped)
            _logger.warning("run %s: skipped non-finite metrics %s", run_id, skipped)
            tags = [RunTag(SKIPPED_METRICS_TAG, tag_value(",".join(sorted(seen))))]
        self._log_batch(run_id, metrics=items, tags=tags)

    def share_view(self, state: Mapping[str, Any], key: str = RUNS_VIEW) -> None:
        """Store a runs view of the experiment for MLflow's UI.

        An experiment tag, read when the runs page's URL has ``?viewStateShareKey=<key>`` (see
        :func:`~.views.ui_url`). Replaces the view of the same key.

        Parameters
        ----------
        state : mapping
            The view as the UI keeps it, e.g. ``selectedColumns`` (``"metrics.`test_mae_avg`"``,
            ...), ``searchFilter``, ``orderByKey``, ``orderByAsc``.
        key : str, default=RUNS_VIEW
            The view's key.
        """
        name, value = SHARED_VIEW_PREFIX + key, json.dumps(dict(state))
        with self._errors():
            try:
                self.client.set_experiment_tag(self.experiment_id, name, value)
            except MlflowException as exc:
                if not duplicate_row(exc):
                    raise
                # Another process inserted the same tag between MLflow's lookup and its
                # insert (two runs of a new experiment at once): it exists now, and the
                # second attempt updates it.
                _logger.debug("share_view raced another process (%s); trying again", exc)
                self.client.set_experiment_tag(self.experiment_id, name, value)

    def set_tags(self, run_id: str, tags: Mapping[str, Any]) -> None:
        """Set tags of a run, values as strings.

        Parameters
        ----------
        run_id : str
            The run.
        tags : mapping
            Name to value.
        """
        self._log_batch(run_id, tags=[RunTag(str(k), tag_value(v)) for k, v in tags.items()])

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
                local = save_pyfunc_model(Path(tmp), wrapped, meta, signature, example, texts)
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


def ensure_store(tracking_uri: str, experiment_name: str,
                 artifact_root: str | None = None) -> str:
    """Create the store (schema) and the experiment once, e.g. before starting parallel workers.

    Parameters
    ----------
    tracking_uri, experiment_name, artifact_root
        As in :class:`Tracker`.

    Returns
    -------
    str
        The experiment id.
    """
    return Tracker(tracking_uri, experiment_name, artifact_root).experiment_id
