"""What MLflow's UI opens: its server's command line, its addresses and the shared runs view.

Every workbench experiment stores one runs view (:meth:`~.runs.Tracker.share_view`, the
columns :func:`metric_view` builds: the test MAE per target side by side); :func:`ui_url`
is the address of the UI, of an experiment's runs page or of that view, and
:func:`experiment_views` lists the view's address for each experiment of a store
(``workbench ui``), which starts the server :func:`ui_command` writes, in the
environment :func:`ui_env` returns.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import Any

from ..process.errors import redact
from .uris import sqlite_path

__all__ = ["RUNS_VIEW", "SHARED_VIEW_PREFIX", "experiment_views", "metric_view", "ui_command",
           "ui_env", "ui_url"]

_logger = logging.getLogger("workbench.experiment.tracking")

#: MLflow 3's UI loads a runs view (columns, filter, order) from the experiment tag
#: ``<prefix><key>`` when its URL has ``?viewStateShareKey=<key>`` (a "shared view").
SHARED_VIEW_PREFIX = "mlflow.sharedViewState."
#: The shared view every workbench experiment gets (:meth:`Tracker.share_view`).
RUNS_VIEW = "workbench"


def ui_url(port: int, experiment_id: str | None = None, view: str | None = None,
           host: str = "127.0.0.1") -> str:
    """Build the address of MLflow's UI in its model-training view.

    MLflow's UI opens its GenAI view unless the URL says ``workflowType=machine_learning`` (or
    the user's browser remembers the toggle); the experiment's ``mlflow.experimentKind`` tag
    does not decide it.

    Parameters
    ----------
    port : int
        The UI server's port.
    experiment_id : str, default=None
        An experiment: its runs page (``None``: the experiments list).
    view : str, default=None
        A runs view stored under that key (:meth:`~.runs.Tracker.share_view`).
    host : str, default="127.0.0.1"
        The UI server's host.

    Returns
    -------
    str
        The URL.
    """
    from urllib.parse import urlencode

    query = {"workflowType": "machine_learning"}
    if experiment_id is None:
        return f"http://{host}:{port}/#/experiments?{urlencode(query)}"
    if view:
        query = {"viewStateShareKey": view, **query}
    return f"http://{host}:{port}/#/experiments/{experiment_id}/runs?{urlencode(query)}"


def metric_view(targets: list[str], metric: str = "test_mae",
                search_filter: str = "") -> dict[str, Any]:
    """Build the runs view :meth:`~.runs.Tracker.share_view` stores by default.

    Parameters
    ----------
    targets : list of str
        The targets.
    metric : str, default="test_mae"
        The metric shown: columns ``<metric>/<target>`` per target and ``<metric>_avg``.
    search_filter : str, default=""
        MLflow's run search syntax; empty: every run.

    Returns
    -------
    dict
        The view, runs ordered by the average (best first).
    """
    columns = [f"metrics.`{metric}/{t}`" for t in targets] + [f"metrics.`{metric}_avg`"]
    return {"selectedColumns": columns, "searchFilter": search_filter,
            "orderByKey": f"metrics.`{metric}_avg`", "orderByAsc": True}


def experiment_views(uri: str, port: int) -> list[tuple[str, str]]:
    """List the UI's address of each experiment in the store with the workbench's runs view.

    That view shows its runs' test MAE per target side by side. None are listed if the store
    cannot be read now (the UI reports that itself).

    Parameters
    ----------
    uri : str
        The tracking URI.
    port : int
        The port the MLflow UI listens on (127.0.0.1).

    Returns
    -------
    list of (str, str)
        Each experiment's name and the address of its runs view.
    """
    from mlflow import MlflowClient  # (MLflow only when listing: ui_url is light)

    path = sqlite_path(uri)
    if uri.startswith("sqlite:") and (path is None or not path.is_file()):
        return []  # nothing stored yet; reading would create the database
    try:
        experiments = MlflowClient(uri).search_experiments()
    except Exception as exc:  # a locked or unreachable store: the UI shows the problem
        _logger.debug("could not list the experiments of %s: %s", redact(uri), exc)
        return []
    return [(e.name, ui_url(port, e.experiment_id, RUNS_VIEW)) for e in experiments
            if SHARED_VIEW_PREFIX + RUNS_VIEW in e.tags]


def ui_env() -> dict[str, str]:
    """Return the environment of the servers ``workbench ui`` starts.

    This process's, with MLflow's server jobs off unless
    ``MLFLOW_SERVER_ENABLE_JOB_EXECUTION`` is set: they serve MLflow's GenAI features, which
    workbench does not use, and start a job runner and seven worker processes, each
    importing MLflow, with every server.

    Returns
    -------
    dict
        The environment variables.
    """
    env = dict(os.environ)
    env.setdefault("MLFLOW_SERVER_ENABLE_JOB_EXECUTION", "false")
    return env


def ui_command(tracking_uri: str, port: int, workers: int = 1) -> list[str]:
    """Return the ``mlflow server`` command line serving ``tracking_uri`` on 127.0.0.1.

    One server process is the default: it serves a user's browser and starts in about half
    the time of MLflow's default of four on a small machine.

    Parameters
    ----------
    tracking_uri : str
        The store to serve.
    port : int
        The port.
    workers : int, default=1
        Server processes.

    Returns
    -------
    list of str
        The command line (with the artifact root beside an SQLite store).
    """
    cmd = [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", tracking_uri,
           "--host", "127.0.0.1", "--port", str(port), "--workers", str(workers)]
    if tracking_uri.startswith("sqlite:///"):
        path = sqlite_path(tracking_uri)  # None for an in-memory database: no folder
        if path is not None:
            root = path.parent / "artifacts"
            cmd += ["--default-artifact-root", root.resolve().as_uri()]
    return cmd
