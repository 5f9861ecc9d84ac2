"""Lifecycle of the MLflow runs of ``evaluate`` and ``sweep``: never left RUNNING.

(Signals: :mod:`~workbench.experiment.process.signals`; an interrupted command's run ends
``KILLED``.)

* :func:`live_run`: :meth:`Tracker.run` with this process's host, pid and a heartbeat.
* :func:`command_run`: the command's parent run, created before any work (a sweep's search is
  visible in MLflow while it runs), with a heartbeat tag that a background thread refreshes;
  ``FINISHED``, ``KILLED`` (interrupt) or ``FAILED`` (error) at the end.
* :func:`reap_stale_runs`: a run whose process died without a word (SIGKILL, power loss) is
  marked ``FAILED`` by the next command on the store: at once if its process was on this host
  and is gone, else once its heartbeat is older than :data:`RUN_GRACE_S`.
* :func:`prepare_store`: a new SQLite store is created and migrated by one process at a time
  (a file lock beside the database), so concurrent first commands do not race in alembic;
  an unusable store is one line before anything is written (a new store starts as a copy
  of an empty one: :func:`~.store_template.store_template`).
* :class:`TrialRecorder`: a sweep's trials become child runs as they finish.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any

from ...parallel import pid_alive
from ..process.errors import TrackingError
from ..process.signals import interrupts_deferred
from .uris import check_store_uri, sqlite_path

if TYPE_CHECKING:  # mlflow is imported only where a run is touched
    from optuna.study import Study
    from optuna.trial import FrozenTrial

    from .runs import Tracker

__all__ = ["TrialRecorder", "command_run", "live_run", "prepare_store", "reap_stale_runs"]

#: Seconds between a live run's heartbeats, and after which a silent run counts as dead.
RUN_HEARTBEAT_S = float(os.environ.get("WORKBENCH_RUN_HEARTBEAT_S", 30))
RUN_GRACE_S = 4 * RUN_HEARTBEAT_S
HOST_TAG, PID_TAG, HEARTBEAT_TAG = "workbench.host", "workbench.pid", "workbench.heartbeat"


# --------------------------------------------------------------------------- stores


@contextlib.contextmanager
def _first_use_lock(uri: str) -> Iterator[None]:
    """Hold an exclusive lock on ``<db>.lock`` beside a SQLite store (no-op for other stores)."""
    path = sqlite_path(uri)
    if path is None or path.is_dir():
        yield
        return

    lock = path.with_name(path.name + ".lock")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fh = open(lock, "a")
    except OSError as exc:
        raise TrackingError(f"SQLite database {path}: cannot create its lock {lock.name}: "
                            f"{exc.strerror or type(exc).__name__}") from None
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def prepare_store(tracker: Tracker) -> str:
    """Create (and migrate) the tracking store and the experiment, one process at a time.

    Parameters
    ----------
    tracker : Tracker
        The store and experiment to prepare.

    Returns
    -------
    str
        The experiment id.

    Raises
    ------
    TrackingError
        Before anything is written when the store cannot be used (an unknown scheme, a
        missing database driver, a read-only directory, an unreachable server).
    """
    check_store_uri(tracker.tracking_uri)
    # a Ctrl-C waits for a new store's migration (a half-migrated database would not open)
    with interrupts_deferred(), _first_use_lock(tracker.tracking_uri):
        return tracker.experiment_id


# --------------------------------------------------------------------------- runs


def reap_stale_runs(tracker: Tracker, grace_s: float | None = None) -> list[str]:
    """Mark ``FAILED`` the RUNNING runs of the tracker's experiment whose process is gone.

    A run's process is gone when it ran on this host under a pid that is dead, or when its
    heartbeat is older than ``grace_s``; RUNNING children of runs that are no longer running
    are marked too.

    Parameters
    ----------
    tracker : Tracker
        The store and experiment.
    grace_s : float, default=None
        Heartbeat age after which a run counts as dead; :data:`RUN_GRACE_S` when ``None``.

    Returns
    -------
    list of str
        The run ids marked.
    """
    grace = RUN_GRACE_S if grace_s is None else grace_s
    client, host, now = tracker.client, socket.gethostname(), time.time()
    with tracker._errors():
        running = client.search_runs([tracker.experiment_id],
                                     filter_string="attributes.status = 'RUNNING'",
                                     max_results=5000)
    reaped = []
    for run in running:
        tags = run.data.tags
        if HEARTBEAT_TAG not in tags:
            continue
        pid = tags.get(PID_TAG, "")
        dead = (tags.get(HOST_TAG) == host and pid.isdigit() and int(pid) != os.getpid()
                and not pid_alive(int(pid)))
        silent = now - float(tags[HEARTBEAT_TAG]) > grace
        if dead or silent:
            why = "its process is gone" if dead else f"no heartbeat for {grace:.0f} s"
            tracker.set_tags(run.info.run_id, {"workbench.failed": why})
            tracker.end_run(run.info.run_id, "FAILED")
            reaped.append(run.info.run_id)
    live = {r.info.run_id for r in running} - set(reaped)
    for run in running:  # children started just before their parent's process died
        parent = run.data.tags.get("mlflow.parentRunId")
        if parent and parent not in live and run.info.run_id not in reaped:
            tracker.end_run(run.info.run_id, "FAILED")
            reaped.append(run.info.run_id)
    return reaped


@contextlib.contextmanager
def every(interval: float, beat: Callable[..., object], name: str = "heartbeat"
          ) -> Iterator[None]:
    """Call ``beat()`` every ``interval`` seconds from a daemon thread while the block runs.

    A heartbeat that beats while the work goes on. A failed beat is skipped: the grace
    periods that read heartbeats cover several.

    Parameters
    ----------
    interval : float
        Seconds between beats.
    beat : callable
        Called without arguments.
    name : str, default="heartbeat"
        The thread's name.

    Yields
    ------
    None
        While the block runs.
    """
    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(interval):
            try:
                beat()
            except Exception:
                pass

    thread = threading.Thread(target=loop, daemon=True, name=name)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=10)


@contextlib.contextmanager
def live_run(tracker: Tracker, name: str, *, tags: Mapping[str, Any] | None = None,
             interval: float | None = None) -> Iterator[str]:
    """Run :meth:`Tracker.run` with this process's host, pid and a heartbeat tag.

    The run ends ``FINISHED``, ``KILLED`` on ``KeyboardInterrupt``, ``FAILED`` otherwise; a
    background thread refreshes the heartbeat while the block runs (:func:`reap_stale_runs`
    reads the tags).

    Parameters
    ----------
    tracker : Tracker
        The store and experiment.
    name : str
        The run's name.
    tags : mapping, default=None
        More tags of the run.
    interval : float, default=None
        Seconds between heartbeats; :data:`RUN_HEARTBEAT_S` when ``None``.

    Yields
    ------
    str
        The run id.
    """
    all_tags = dict(tags or {})
    all_tags.update({HOST_TAG: socket.gethostname(), PID_TAG: str(os.getpid()),
                     HEARTBEAT_TAG: f"{time.time():.0f}"})
    with tracker.run(name, tags=all_tags) as run_id, \
            every(interval or RUN_HEARTBEAT_S, name="run-heartbeat",
                  beat=lambda: tracker.set_tags(run_id, {HEARTBEAT_TAG: f"{time.time():.0f}"})):
        yield run_id


@contextlib.contextmanager
def command_run(tracker: Tracker | None, kind: str, name: str,
                tags: Mapping[str, Any] | None = None) -> Iterator[str | None]:
    """Run the parent run of one ``evaluate``/``sweep``.

    The store is prepared, stale runs are reaped, then the run lives while the block runs.

    Parameters
    ----------
    tracker : Tracker or None
        The store and experiment; ``None`` without tracking.
    kind : str
        The command (``evaluate`` or ``sweep``), tagged ``workbench.kind``.
    name : str
        The config's name.
    tags : mapping, default=None
        More tags of the run.

    Yields
    ------
    str or None
        The run id (``None`` without tracking).
    """
    if tracker is None:
        yield None
        return
    prepare_store(tracker)
    reap_stale_runs(tracker)
    with live_run(tracker, f"{kind} {name}",
                  tags={"workbench.kind": kind, **dict(tags or {})}) as run_id:
        yield run_id


class TrialRecorder:
    """Record each finished trial as a child run of ``parent_run_id`` (an Optuna callback).

    Picklable, for worker processes.

    Parameters
    ----------
    tracker : Tracker
        The store and experiment.
    parent_run_id : str
        The sweep's run.
    """

    def __init__(self, tracker: Tracker, parent_run_id: str) -> None:
        self.tracker, self.parent_run_id = tracker, parent_run_id

    def __call__(self, study: Study, trial: FrozenTrial) -> None:
        """Log ``trial`` of ``study`` as a child run.

        Three requests per trial (create, one batch, end): it runs between trials.

        Parameters
        ----------
        study : optuna.study.Study
            The sweep's study.
        trial : optuna.trial.FrozenTrial
            The finished trial.
        """
        from mlflow.entities import Metric, Param  # (b) MLflow: not for evaluate --no-track

        t, now = trial, int(time.time() * 1000)
        run = self.tracker.start_run(
            f"{study.study_name} #{t.number}", parent_run_id=self.parent_run_id,
            tags={"workbench.kind": "trial", "study": study.study_name, "trial": t.number,
                  "state": t.state.name, "worker": t.user_attrs.get("worker", "")})
        metrics = [Metric("fold_mae", float(m), now, step)
                   for step, m in enumerate(t.user_attrs.get("fold_mae", []))]
        if t.value is not None:
            metrics.append(Metric("inner_cv_mae", float(t.value), now, 0))
        if "prior_cv_mae" in t.user_attrs:
            metrics.append(Metric("prior_inner_cv_mae", float(t.user_attrs["prior_cv_mae"]),
                                  now, 0))
        metrics = [m for m in metrics if m.value == m.value and abs(m.value) != float("inf")]
        params = [Param(str(k), str(v)) for k, v in t.params.items()]
        with self.tracker._errors():
            self.tracker.client.log_batch(run, metrics=metrics, params=params)
        self.tracker.end_run(run, "FINISHED" if t.state.name in ("COMPLETE", "PRUNED")
                             else "FAILED")
