"""MLflow tracking for experiments: runs (nested), params, metrics, artifacts and models.

Part of the experiment layer: it imports MLflow, the core (:mod:`workbench`) never imports it.

Everything goes through an explicit :class:`mlflow.MlflowClient` bound to one tracking URI;
MLflow's global state (tracking URI, active run, experiment) is neither read nor changed
(models are saved with ``mlflow.pyfunc.save_model`` and uploaded through the client, so no
active run is needed).

The default store is a SQLite file plus a local artifact directory inside the project::

    <root>/mlruns/mlflow.db          runs, params, metrics, tags   (sqlite:///...)
    <root>/mlruns/artifacts/         figures, tables, models        (file:///...)

Several processes may write to the same SQLite store; create it once with
:func:`ensure_store` before starting them (parallel schema migrations race). MLflow waits up
to 20 s for a locked database during normal operations (hard-coded ``busy_timeout``); the
first connection of a process uses SQLite's connect timeout (5 s, or ``?timeout=<s>`` in the
URI, e.g. ``sqlite:////abs/mlflow.db?timeout=30``). Store problems (locked or corrupt
database, unreachable server, out-of-date schema) raise :class:`TrackingError` naming the
store; the store itself is never deleted or rewritten.

One module per concern: :mod:`.uris` (where the store is, checked before any work),
:mod:`.store_template` (a new SQLite store copied from an empty one, not migrated again),
:mod:`.translate` (store errors as one line), :mod:`.runs` (:class:`~.runs.Tracker`: runs,
params, metrics, tags, artifacts, input datasets and models, in one class),
:mod:`.views` (what MLflow's UI opens: its server's command line, its addresses, the
shared runs view),
:mod:`.models` (a logged model's directory and pinned requirements), :mod:`.records`
(hashes, commits, MLflow's value limits), :mod:`.lifecycle` (runs
never left RUNNING: heartbeats, the reaper, the store's first use), :mod:`.serving` (the
logged pyfunc model), :mod:`.predict` (``workbench predict``) and :mod:`.compare`
(``workbench compare``: two runs' paired errors).

May import: process, scoring. The only home that imports MLflow (a test checks).
"""

from __future__ import annotations

import os

# MLflow prints "View run ... at <url>" to stdout whenever a run ends against a tracking server:
# one line per trial in a sweep. The workbench reports runs itself.
os.environ.setdefault("MLFLOW_SUPPRESS_PRINTING_URL_TO_STDOUT", "true")

#: MLflow's retries of a tracking server's requests, bounded: MLflow's own defaults retry for
#: about four minutes with a two-minute timeout per request. Five retries with back-off 0, 2,
#: 4, 8 and 16 s wait out a server restarted within about 30 s; a server away for longer ends
#: the command in one line naming it. Values already in the environment are kept.
HTTP_RETRIES = {"MLFLOW_HTTP_REQUEST_MAX_RETRIES": "5",
                "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR": "1",
                "MLFLOW_HTTP_REQUEST_TIMEOUT": "60"}
for _name, _value in HTTP_RETRIES.items():
    os.environ.setdefault(_name, _value)

#: The modules a tracked run's records import (SHAP's plots, MLflow's datasets and models,
#: the logged model's wrapper): ``evaluate`` loads them in the background while the model
#: fits. Named here, as MLflow's modules are nowhere else.
RECORD_MODULES = ("shap", "mlflow.data.pandas_dataset", "mlflow.pyfunc", "mlflow.models",
                  "workbench.experiment.tracking.serving")
