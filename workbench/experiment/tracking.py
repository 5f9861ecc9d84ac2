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
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import logging
import math
import os
import shutil
import socket
import subprocess
import tempfile
import time
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import mlflow
import numpy as np
import pandas as pd
from mlflow import MlflowClient

# MLflow prints "View run ... at <url>" to stdout whenever a run ends against a tracking server:
# one line per trial in a sweep. The workbench reports runs itself.
os.environ.setdefault("MLFLOW_SUPPRESS_PRINTING_URL_TO_STDOUT", "true")
from mlflow.entities import LoggedModelOutput, Metric, Param, RunTag
from mlflow.exceptions import MlflowException
from mlflow.pyfunc import PythonModel  # not mlflow.pyfunc.PythonModel: mypy sees a LazyLoader

__all__ = [
    "DEFAULT_STORE",
    "MAX_PARAM_LENGTH",
    "Tracker",
    "TrackingError",
    "dataset_hash",
    "default_artifact_root",
    "default_tracking_uri",
    "check_store_uri",
    "ensure_store",
    "git_commit",
    "resolve_tracking_uri",
]

_logger = logging.getLogger(__name__)

DEFAULT_STORE = "mlruns"
#: MLflow's limit on a param value (``mlflow.utils.validation.MAX_PARAM_VAL_LENGTH``).
MAX_PARAM_LENGTH = 6000
_MAX_TAG_LENGTH = 8000
PARENT_TAG = "mlflow.parentRunId"
SKIPPED_METRICS_TAG = "workbench.skipped_metrics"
TRUNCATED_PARAMS_TAG = "workbench.truncated_params"
_RUN_STATUSES = ("FINISHED", "FAILED", "KILLED")
#: MLflow 3's UI opens an experiment without this tag in its GenAI (traces) view; this value
#: opens it in the model-training view (runs, metrics, charts, models).
EXPERIMENT_KIND_TAG = "mlflow.experimentKind"
EXPERIMENT_KIND = "custom_model_development"
#: The alias the newest registered version gets (aliases, not the deprecated stages).
CHAMPION = "champion"
_SQLITE_HEADER = b"SQLite format 3\x00"
#: Distributions pinned in a logged model's requirements (those installed).
MODEL_REQUIREMENTS = ("mlflow", "cloudpickle", "numpy", "pandas", "scipy", "scikit-learn",
                      "lightgbm", "joblib")


# --------------------------------------------------------------------------- URIs


def default_tracking_uri(root: Path) -> str:
    """``sqlite:///<abs root>/mlruns/mlflow.db``."""
    return "sqlite:///" + str(Path(root).resolve() / DEFAULT_STORE / "mlflow.db")


def default_artifact_root(root: Path) -> str:
    """``file:///<abs root>/mlruns/artifacts``."""
    return (Path(root).resolve() / DEFAULT_STORE / "artifacts").as_uri()


def _split_sqlite(uri: str) -> tuple[str, str] | None:
    """``(path, query)`` of a ``sqlite:///`` URI (``path`` relative unless it starts with
    ``/``), ``None`` for other URIs and in-memory databases."""
    if not uri.startswith("sqlite:///"):
        return None
    path, sep, query = uri.removeprefix("sqlite:///").partition("?")
    if not path or path == ":memory:":
        return None
    return path, sep + query


def _absolute_sqlite(uri: str, base: Path) -> str:
    """``uri`` with a relative sqlite path made absolute against ``base``."""
    parts = _split_sqlite(uri)
    if parts is None or Path(parts[0]).is_absolute():
        return uri
    path, query = parts
    return "sqlite:///" + str((Path(base) / path).resolve()) + query


def resolve_tracking_uri(cli: str | None, config: str | None, root: Path) -> str:
    """The tracking URI to use: the CLI flag, else ``$MLFLOW_TRACKING_URI``, else the config
    value, else :func:`default_tracking_uri`. A relative sqlite path in the config
    (``sqlite:///mlruns/mlflow.db``) is relative to ``root``; in the CLI flag or the
    environment it is relative to the current directory, as the user typed it there."""
    if cli:
        return _absolute_sqlite(cli, Path.cwd())
    env = os.environ.get("MLFLOW_TRACKING_URI")
    if env:
        return _absolute_sqlite(env, Path.cwd())
    if config:
        return _absolute_sqlite(config, Path(root))
    return default_tracking_uri(root)


def _sqlite_path(uri: str) -> Path | None:
    parts = _split_sqlite(uri)
    return Path(parts[0]) if parts else None


def _describe_store(uri: str) -> str:
    path = _sqlite_path(uri)
    return f"SQLite database {path}" if path else f"tracking store {redact(uri)}"


# --------------------------------------------------------------------------- errors


from .errors import TrackingError, redact  # noqa: E402  (TrackingError kept importable here)


def _translate(exc: BaseException, uri: str) -> TrackingError | None:
    """A :class:`TrackingError` for store problems, ``None`` for other errors."""
    store = _describe_store(uri)
    if isinstance(exc, ImportError) and urlsplit(uri).scheme.split("+")[0] in (
            "postgresql", "mysql", "mssql", "sqlite"):  # the database's driver
        return TrackingError(f"{store}: its database driver is not installed ({exc})")
    if "supported uri schemes" in str(exc).lower():  # MLflow's registry: a 400-character line
        scheme = urlsplit(uri).scheme if "://" in uri else ""
        return TrackingError(f"{store}: MLflow has no tracking store for '{scheme}://'")
    text = f"{type(exc).__name__}: {exc}"
    cause = exc.__cause__ or exc.__context__
    if cause is not None:
        text += f" | {type(cause).__name__}: {cause}"
    low = text.lower()
    if "database is locked" in low:
        return TrackingError(
            f"{store} is locked by another process (SQLite 'database is locked' after waiting "
            "for the lock). Retry when the other writer is done; for many parallel writers use "
            "an MLflow server or a PostgreSQL store.")
    if "file is not a database" in low or "database disk image is malformed" in low:
        return TrackingError(
            f"{store} is not a valid SQLite database (corrupt, or another kind of file); it was "
            "left untouched. Restore it from a backup, move it away, or point the tracking URI "
            "at another file.")
    if "out-of-date database schema" in low:
        return TrackingError(
            f"{store} has an older MLflow schema: back it up, then run "
            f"'mlflow db upgrade {redact(uri)}'. ({exc})")
    if any(s in low for s in ("connection refused", "max retries exceeded",
                              "failed to establish a new connection", "name or service not known",
                              "connectionerror", "timed out")):
        return TrackingError(f"cannot reach the MLflow {store}: {exc}")
    if "sqlite3.databaseerror" in low or "sqlite3.operationalerror" in low:
        return TrackingError(f"{store} cannot be used: {exc}")
    return None


def _duplicate_row(exc: BaseException) -> bool:
    """Whether ``exc`` is a database's unique-constraint violation (SQLite, PostgreSQL,
    MySQL): a row another process inserted first."""
    text = f"{exc} {exc.__cause__ or exc.__context__ or ''}".lower()
    return any(s in text for s in ("unique constraint", "duplicate key", "duplicate entry",
                                   "integrityerror"))


def _check_sqlite_file(uri: str) -> None:
    """Create the parent directory of a sqlite store; refuse a file that is not SQLite
    (checked by its header, without writing to it)."""
    path = _sqlite_path(uri)
    if path is None:
        return
    _check_sqlite_location(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise TrackingError(f"SQLite database {path}: cannot create its directory: "
                            f"{exc.strerror or type(exc).__name__}") from None
    _check_sqlite_header(path)


def _check_sqlite_location(path: Path) -> None:
    """Without writing anything: ``path`` is not a directory, and its directory (or the
    nearest existing one, where it would be created) accepts new files: SQLite writes its
    journal and the first-use lock beside the database, even for an existing one."""
    import tempfile

    if path.is_dir():
        raise TrackingError(f"SQLite database {path} is a directory, not a database file")
    existing = Path(os.path.abspath(path)).parent
    while not os.path.lexists(existing):
        existing = existing.parent
    if not existing.is_dir():
        raise TrackingError(f"SQLite database {path}: {existing} is a file, not a directory")
    try:  # a probe sees what SQLite will see (permissions, read-only file systems)
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".workbench-probe-")
    except OSError as exc:
        raise TrackingError(f"SQLite database {path}: cannot write in {existing} "
                            f"({exc.strerror or type(exc).__name__}); SQLite writes its "
                            "journal beside the database") from None
    os.close(fd)
    os.unlink(probe)
    if path.is_file() and not os.access(path, os.R_OK | os.W_OK):
        raise TrackingError(f"SQLite database {path} cannot be read and written (its "
                            "permissions)")


def _check_sqlite_header(path: Path) -> None:
    if path.is_file() and path.stat().st_size > 0:
        with path.open("rb") as fh:
            header = fh.read(len(_SQLITE_HEADER))
        if header != _SQLITE_HEADER:
            raise TrackingError(
                f"SQLite database {path} is not a valid SQLite database (corrupt, or another "
                "kind of file); it was left untouched. Restore it from a backup, move it away, "
                "or point the tracking URI at another file.")


#: URI schemes MLflow itself has a tracking store for (plug-ins add theirs as entry points).
_MLFLOW_SCHEMES = ("", "file", "http", "https", "databricks", "databricks-uc", "uc")


def _store_schemes() -> list[str]:
    from importlib.metadata import entry_points

    from mlflow.store.db.db_types import DATABASE_ENGINES

    plugins = [e.name for e in entry_points(group="mlflow.tracking_store")]
    return [*_MLFLOW_SCHEMES, *DATABASE_ENGINES, *plugins]


def _check_scheme_and_driver(uri: str) -> None:
    """Without connecting: MLflow has a store for the URI's scheme, and a database URI's
    driver is installed."""
    from mlflow.store.db.db_types import DATABASE_ENGINES

    shown = redact(uri)
    try:
        scheme = urlsplit(uri).scheme.lower()
    except ValueError:
        raise TrackingError(f"tracking URI {shown} is not a valid URI") from None
    base = scheme.split("+")[0]
    if len(base) == 1 and uri[1:2] == ":":  # a Windows drive letter: a path
        base = ""
    known = _store_schemes()
    if base not in known and scheme not in known:
        raise TrackingError(
            f"tracking URI {shown}: MLflow has no tracking store for '{scheme}://'; use "
            "sqlite:///PATH, postgresql://, mysql://, mssql://, http(s)://SERVER or a "
            "directory")
    if base not in DATABASE_ENGINES:
        return
    import sqlalchemy.exc
    from sqlalchemy.engine import make_url

    try:
        make_url(uri).get_dialect().import_dbapi()
    except ImportError as exc:
        from .errors import driver_hint

        raise TrackingError(f"tracking store {shown}: its database driver is not installed "
                            f"({exc}); {driver_hint(exc)}") from None
    except sqlalchemy.exc.NoSuchModuleError:
        raise TrackingError(f"tracking store {shown}: SQLAlchemy has no database driver "
                            f"'{scheme}'") from None
    except sqlalchemy.exc.ArgumentError:
        raise TrackingError(f"tracking URI {shown} is not a valid database URL") from None


def check_store_uri(uri: str) -> None:
    """Before any work, writing nothing: the tracking store at ``uri`` can be used. Its
    scheme has an MLflow store, a database's driver is installed, a SQLite database's
    directory can be written (and the file is SQLite), a server accepts connections.
    Raises :class:`TrackingError` (one line, no password)."""
    _check_scheme_and_driver(uri)
    path = _sqlite_path(uri)
    if path is not None:
        _check_sqlite_location(path)
        _check_sqlite_header(path)
    _check_server(uri)


def _check_server(uri: str, timeout: float = 5.0) -> None:
    """Fail fast when an http(s) tracking server does not accept connections (MLflow itself
    retries for minutes)."""
    parts = urlsplit(uri)
    if parts.scheme not in ("http", "https") or not parts.hostname:
        return
    port = parts.port or (443 if parts.scheme == "https" else 80)
    try:
        with socket.create_connection((parts.hostname, port), timeout=timeout):
            pass
    except OSError as exc:
        raise TrackingError(f"cannot reach the MLflow tracking server {redact(uri)}: {exc}") \
            from exc


# --------------------------------------------------------------------------- helpers


def git_commit(root: Path) -> str | None:
    """``git rev-parse HEAD`` in ``root``; ``None`` outside a repository or without git."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=str(root), capture_output=True,
                             text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    sha = out.stdout.strip()
    if out.returncode != 0 or len(sha) != 40 or any(c not in "0123456789abcdef" for c in sha):
        return None
    return sha


def dataset_hash(*frames: pd.DataFrame | pd.Series) -> str:
    """SHA-256 over the values, index, column names and dtypes of each frame (stable across
    processes: ``pandas.util.hash_pandas_object`` uses a fixed key)."""
    h = hashlib.sha256()
    for i, frame in enumerate(frames):
        h.update(f"frame{i}:{type(frame).__name__}:{frame.shape}\n".encode())
        if isinstance(frame, pd.DataFrame):
            h.update(repr([(str(c), str(t)) for c, t in frame.dtypes.items()]).encode())
        else:
            h.update(repr((str(frame.name), str(frame.dtype))).encode())
        h.update(pd.util.hash_pandas_object(frame, index=True).to_numpy().tobytes())
    return h.hexdigest()


def _now_ms() -> int:
    return int(time.time() * 1000)


def _param_value(key: str, value: Any) -> tuple[str, bool]:
    text = str(value)
    if len(text) <= MAX_PARAM_LENGTH:
        return text, False
    note = f"...[truncated, {len(text)} chars]"
    _logger.warning("param %r is %d characters long; truncated to MLflow's limit of %d",
                    key, len(text), MAX_PARAM_LENGTH)
    return text[:MAX_PARAM_LENGTH - len(note)] + note, True


def _tag_value(value: Any) -> str:
    text = str(value)
    return text if len(text) <= _MAX_TAG_LENGTH else text[:_MAX_TAG_LENGTH - 3] + "..."


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

    def __init__(self, *texts: str):
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


class _PyfuncModel(PythonModel):
    """An MLflow pyfunc wrapper holding a fitted model (pickled with cloudpickle by MLflow;
    the ``workbench`` package travels with it as ``code_paths``). Kept so that models logged
    before :class:`~.serving.WorkbenchModel` still load; new models use the latter."""

    def __init__(self, model):
        self.model = model

    # A DataFrame type hint: MLflow then neither infers a schema from it nor warns about a
    # missing hint; the logged signature (inferred from the input example) validates inputs.
    def predict(self, context, model_input: pd.DataFrame, params: dict[str, Any] | None = None):
        return self.model.predict(model_input)


# --------------------------------------------------------------------------- tracker


class Tracker:
    """Log runs of one experiment to one tracking store through an explicit client.

    Parameters
    ----------
    tracking_uri : str
        E.g. :func:`default_tracking_uri` or :func:`resolve_tracking_uri`'s result.
    experiment_name : str
        Created on first use (with ``artifact_location=artifact_root``) if missing.
    artifact_root : str, default=None
        Artifact location for a new experiment. ``None``: ``artifacts/`` next to a SQLite
        database file, the server's default otherwise. An existing experiment keeps its own.

    The client is created on first use; constructing a ``Tracker`` touches nothing.
    """

    def __init__(self, tracking_uri: str, experiment_name: str, artifact_root: str | None = None):
        self.tracking_uri = str(tracking_uri)
        self.experiment_name = experiment_name
        if artifact_root is None and (path := _sqlite_path(self.tracking_uri)):
            artifact_root = (path.resolve().parent / "artifacts").as_uri()
        self.artifact_root = artifact_root
        self._client: MlflowClient | None = None
        self._experiment_id: str | None = None
        self._skipped: dict[str, set[str]] = {}

    def __repr__(self) -> str:
        return (f"Tracker({redact(self.tracking_uri)!r}, {self.experiment_name!r}, "
                f"artifact_root={self.artifact_root!r})")

    def __getstate__(self):  # picklable for worker processes; the client is rebuilt there
        state = self.__dict__.copy()
        state["_client"] = None
        return state

    @contextlib.contextmanager
    def _errors(self) -> Iterator[None]:
        """Re-raise store problems as :class:`TrackingError`."""
        try:
            yield
        except TrackingError:
            raise
        except Exception as exc:
            err = _translate(exc, self.tracking_uri)
            if err is None:
                raise
            raise err from exc

    @property
    def client(self) -> MlflowClient:
        """The :class:`mlflow.MlflowClient` (created, with its store, on first use)."""
        if self._client is None:
            _check_scheme_and_driver(self.tracking_uri)
            _check_sqlite_file(self.tracking_uri)
            _check_server(self.tracking_uri)
            with self._errors():
                self._client = MlflowClient(self.tracking_uri)
        return self._client

    @property
    def experiment_id(self) -> str:
        """The experiment's id; the experiment is created if it does not exist."""
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
                        if _translate(exc, self.tracking_uri) is not None:
                            raise
                        _logger.debug("create_experiment(%r) failed (%s); looking it up again",
                                      self.experiment_name, exc)
                    exp = client.get_experiment_by_name(self.experiment_name)
                    if exp is None:
                        raise TrackingError(f"could not create experiment "
                                            f"{self.experiment_name!r} in "
                                            f"{_describe_store(self.tracking_uri)}")
            if exp.lifecycle_stage != "active":
                raise TrackingError(
                    f"experiment {self.experiment_name!r} (id {exp.experiment_id}) in "
                    f"{_describe_store(self.tracking_uri)} is deleted; restore it "
                    f"('mlflow experiments restore --experiment-id {exp.experiment_id}') or use "
                    "another name")
            if EXPERIMENT_KIND_TAG not in exp.tags:  # an experiment from before the tag
                with self._errors():
                    client.set_experiment_tag(exp.experiment_id, EXPERIMENT_KIND_TAG,
                                              EXPERIMENT_KIND)
            self._experiment_id = exp.experiment_id
        return self._experiment_id

    # ----------------------------------------------------------------- runs

    def start_run(self, name: str, *, parent_run_id: str | None = None,
                  tags: Mapping[str, Any] | None = None,
                  params: Mapping[str, Any] | None = None) -> str:
        """Create a run (a child of ``parent_run_id`` if given) and return its id."""
        all_tags = {str(k): _tag_value(v) for k, v in (tags or {}).items()}
        if parent_run_id:
            all_tags[PARENT_TAG] = parent_run_id
        experiment_id = self.experiment_id
        with self._errors():
            run = self.client.create_run(experiment_id, run_name=name, tags=all_tags)
        run_id = run.info.run_id
        if params:
            self.log_params(run_id, params)
        return run_id

    def end_run(self, run_id: str, status: str = "FINISHED") -> None:
        """Mark the run ``FINISHED``, ``FAILED`` or ``KILLED``."""
        if status not in _RUN_STATUSES:
            raise ValueError(f"status must be one of {_RUN_STATUSES}, got {status!r}")
        with self._errors():
            self.client.set_terminated(run_id, status=status)

    @contextlib.contextmanager
    def run(self, name: str, parent_run_id: str | None = None,
            tags: Mapping[str, Any] | None = None,
            params: Mapping[str, Any] | None = None) -> Iterator[str]:
        """``with tracker.run("fold-0", parent_run_id=pid) as run_id:`` ... ends the run
        ``FINISHED``, or ``FAILED`` (``KILLED`` on ``KeyboardInterrupt``) and re-raises."""
        run_id = self.start_run(name, parent_run_id=parent_run_id, tags=tags, params=params)
        try:
            yield run_id
        except BaseException as exc:
            status = "KILLED" if isinstance(exc, KeyboardInterrupt) else "FAILED"
            try:
                self.end_run(run_id, status)
            except Exception as end_exc:  # never mask the original error
                _logger.warning("could not mark run %s %s: %s", run_id, status, end_exc)
            raise
        else:
            self.end_run(run_id, "FINISHED")

    # ----------------------------------------------------------------- params, metrics, tags

    def _log_batch(self, run_id: str, *, metrics=(), params=(), tags=()) -> None:
        # MlflowClient.log_batch splits into the store's batch limits itself
        with self._errors():
            self.client.log_batch(run_id, metrics=list(metrics), params=list(params),
                                  tags=list(tags))

    def log_params(self, run_id: str, params: Mapping[str, Any]) -> None:
        """Log params (values as strings; longer than 6000 characters: truncated, with a note
        in the value and the key in the tag ``workbench.truncated_params``)."""
        items, truncated = [], []
        for key, value in params.items():
            text, cut = _param_value(str(key), value)
            items.append(Param(str(key), text))
            if cut:
                truncated.append(str(key))
        tags = [RunTag(TRUNCATED_PARAMS_TAG, _tag_value(",".join(truncated)))] if truncated else []
        self._log_batch(run_id, params=items, tags=tags)

    def log_metrics(self, run_id: str, metrics: Mapping[str, float],
                    step: int | None = None) -> None:
        """Log metrics in one batch; NaN/inf values are skipped and their names recorded in
        the tag ``workbench.skipped_metrics``."""
        ts, items, skipped = _now_ms(), [], []
        for key, value in metrics.items():
            value = float(value)
            if math.isfinite(value):
                items.append(Metric(str(key), value, ts, int(step or 0)))
            else:
                skipped.append(str(key))
        tags = []
        if skipped:
            seen = self._skipped.setdefault(run_id, set())
            seen.update(f"{k}@{int(step or 0)}" if step is not None else k for k in skipped)
            _logger.warning("run %s: skipped non-finite metrics %s", run_id, skipped)
            tags = [RunTag(SKIPPED_METRICS_TAG, _tag_value(",".join(sorted(seen))))]
        self._log_batch(run_id, metrics=items, tags=tags)

    def set_tags(self, run_id: str, tags: Mapping[str, Any]) -> None:
        """Set tags (values as strings)."""
        self._log_batch(run_id, tags=[RunTag(str(k), _tag_value(v)) for k, v in tags.items()])

    # ----------------------------------------------------------------- artifacts

    def log_dict(self, run_id: str, obj: Any, artifact_file: str) -> None:
        """``obj`` as JSON (``.json``) or YAML (``.yaml``/``.yml``)."""
        with self._errors():
            self.client.log_dict(run_id, obj, artifact_file)

    def log_text(self, run_id: str, text: str, artifact_file: str) -> None:
        with self._errors():
            self.client.log_text(run_id, text, artifact_file)

    def log_file(self, run_id: str, path: str | os.PathLike,
                 artifact_path: str | None = None) -> None:
        """Copy a local file (or directory) into the run's artifacts under ``artifact_path``."""
        path = Path(path)
        with self._errors():
            if path.is_dir():
                self.client.log_artifacts(run_id, str(path), artifact_path)
            else:
                self.client.log_artifact(run_id, str(path), artifact_path)

    def log_figure(self, run_id: str, fig, artifact_file: str) -> None:
        """A matplotlib figure, saved in the format of ``artifact_file``'s suffix (PNG)."""
        with self._errors():
            self.client.log_figure(run_id, fig, artifact_file)

    # ----------------------------------------------------------------- models

    def log_model(self, run_id: str, model, input_example: pd.DataFrame,
                  name: str = "model", *, targets: list[str] | None = None,
                  texts: Mapping[str, str] | None = None) -> str:
        """Log a fitted model (``predict(DataFrame)`` -> DataFrame or array; optionally
        ``predict_interval``) as an MLflow pyfunc model linked to ``run_id``; returns its URI
        ``models:/<model_id>``.

        The model is cloudpickled inside :class:`~.serving.WorkbenchModel` (checks the input
        table by column name, returns one column per target and ``<target>_lower/_upper``
        when the model has intervals); the ``workbench`` package is stored with it
        (``code_paths``), so it loads with ``mlflow.pyfunc.load_model`` (and serves with
        ``mlflow models serve``) where only the pinned requirements are installed. The
        signature names ``input_example``'s columns and the outputs; the first 5 rows are
        the input example (the REST request's template). ``targets``: the target names
        (default: the columns of ``model.predict``). ``texts``: file name -> text written
        in the model directory (e.g. ``{"config.toml": ...}``, credentials redacted by the
        caller). Requirements are pinned from the installed versions (no inference
        subprocess)."""
        import workbench

        from .serving import WorkbenchModel, model_signature

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
                code = Path(tmp) / "code" / "workbench"
                shutil.copytree(Path(workbench.__file__).parent, code,
                                ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
                local = Path(tmp) / "model"
                # cloudpickle is the deliberate choice here (the docs' "models from code" would
                # need a script per model): silence MLflow's notice about it for this call.
                meta = mlflow.models.Model(artifact_path=logged.artifact_location, run_id=run_id,
                                           model_uuid=logged.model_id, model_id=logged.model_id)
                with _quiet("mlflow.pyfunc", "serialized using CloudPickle",
                            "Validating input example"):
                    mlflow.pyfunc.save_model(
                        str(local), python_model=wrapped, mlflow_model=meta,
                        signature=signature, input_example=example.head(5),
                        metadata={"workbench": {"inputs": wrapped.columns,
                                                "targets": wrapped.targets,
                                                "outputs": wrapped.outputs}},
                        pip_requirements=_requirements(), code_paths=[str(code)])
                for file_name, text in (texts or {}).items():  # config.toml beside MLmodel
                    (local / file_name).write_text(text, encoding="utf-8")
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
        """Register ``models:/<model_id>`` (from :meth:`log_model`) as a new version of the
        registered model ``name`` (created if missing) in this store's Model Registry, with
        ``tags``, and point ``alias`` at it; returns the version."""
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
                      **{str(k): _tag_value(v) for k, v in (tags or {}).items()}},
                description=description)
            self.client.set_registered_model_alias(name, alias, version.version)
        return str(version.version)

    def log_dataset(self, run_id: str, frame: pd.DataFrame, *, name: str, context: str,
                    source: str | None = None, targets: str | None = None) -> str:
        """Record ``frame`` as an input dataset of the run (MLflow's name, digest and schema;
        the runs table's "Dataset" column), with ``mlflow.data.context`` = ``context``;
        returns MLflow's digest."""
        # mlflow.data.from_pandas is this function, set on mlflow.data at import: no stub sees it
        from mlflow.data.pandas_dataset import from_pandas
        from mlflow.entities import DatasetInput, InputTag

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
                if not _duplicate_row(exc):
                    raise
                # Another process created the same dataset row (experiment, name, digest)
                # between MLflow's lookup and its insert (two first runs at once): the row
                # exists now, and the second attempt links this run to it.
                _logger.debug("log_inputs raced another process (%s); trying again", exc)
                self.client.log_inputs(run_id, inputs)
        return dataset.digest

    def model_artifact_uri(self, model_uri: str) -> str:
        """The artifact location of ``models:/<model_id>`` (loadable without a tracking
        URI, e.g. ``mlflow.pyfunc.load_model(tracker.model_artifact_uri(uri))``)."""
        model_id = model_uri.removeprefix("models:/").split("/")[0]
        with self._errors():
            return self.client.get_logged_model(model_id).artifact_location

    def load_model(self, model_uri: str):
        """``mlflow.pyfunc.load_model`` for a model of this store (no global state used)."""
        if model_uri.startswith("models:/"):
            model_uri = self.model_artifact_uri(model_uri)
        with self._errors():
            return mlflow.pyfunc.load_model(model_uri)


def ensure_store(tracking_uri: str, experiment_name: str,
                 artifact_root: str | None = None) -> str:
    """Create the store (schema) and the experiment once, e.g. before starting parallel
    workers; returns the experiment id."""
    return Tracker(tracking_uri, experiment_name, artifact_root).experiment_id

