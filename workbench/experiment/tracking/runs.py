"""Runs in the store: :class:`Tracker`, an explicit MLflow client bound to one experiment.

One tracking URI and one experiment: runs, nested runs, params, metrics, tags, artifacts,
input datasets; its models from :class:`~.models.ModelRecords`, its artifacts from
:class:`~.artifacts.ArtifactRecords`.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from mlflow import MlflowClient
from mlflow.entities import Metric, Param, RunTag
from mlflow.exceptions import MlflowException

from ..process.errors import SweepTimedOut, TrackingError, redact
from ..process.signals import ignoring_signals, interrupts_deferred
from .artifacts import ArtifactRecords
from .models import ModelRecords
from .records import now_ms, param_value, tag_value
from .translate import duplicate_row, translate
from .uris import describe_store, is_database, prepare_store_location, sqlite_path
from .views import RUNS_VIEW, SHARED_VIEW_PREFIX

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


class Tracker(ModelRecords, ArtifactRecords):
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

        Raises
        ------
        TrackingError
            The store cannot be used.
        """
        if self._client is None:
            prepare_store_location(self.tracking_uri)
            with self._errors():
                self._client = MlflowClient(self.tracking_uri)
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
