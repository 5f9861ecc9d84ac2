"""MLflow's and the databases' errors as one-line :class:`TrackingError` s naming the store.

A locked or corrupt SQLite file, an old schema, an unreachable server, a missing driver.
"""

from __future__ import annotations

import re
from urllib.parse import urlsplit

from ..process.errors import TrackingError, disk_full, redact
from .uris import describe_store, is_database

__all__ = ["duplicate_row", "translate"]


def translate(exc: BaseException, uri: str) -> TrackingError | None:
    """Translate a store problem into a one-line :class:`TrackingError`.

    Parameters
    ----------
    exc : BaseException
        An error raised by MLflow or a database driver.
    uri : str
        The tracking URI, named in the message (without a password).

    Returns
    -------
    TrackingError or None
        ``None`` for errors that are not store problems.
    """
    store = describe_store(uri)
    if isinstance(exc, ImportError) and is_database(uri):  # the database's driver
        return TrackingError(f"{store}: its database driver is not installed ({exc})")
    if "supported uri schemes" in str(exc).lower():  # MLflow's registry: a 400-character line
        scheme = urlsplit(uri).scheme if "://" in uri else ""
        return TrackingError(f"{store}: MLflow has no tracking store for '{scheme}://'")
    full = disk_full(exc)
    if full is not None:
        return TrackingError(
            f"{store}: the disk is full (no space left on the device); free space, then run "
            "the command again (the next command marks a run left RUNNING as FAILED)"
            + (f". Writing {full}" if full else ""))
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
    answered = _ERROR_STATUS.search(low)  # retried on a 500, 503, ... until MLflow gave up
    if answered or (any(s in low for s in _UNREACHABLE) and _reason(low) == "connection dropped"
                    and _answers(uri)):
        what = (f"answered HTTP {answered.group(1)} to" if answered
                else "answers, but dropped the connection of")
        return TrackingError(
            f"the MLflow {store} {what} {_request(text)} ({_retried()}): the server failed "
            "(its log says why: a full disk?); a run left RUNNING is marked FAILED by the next "
            "command on the store")
    if any(s in low for s in _UNREACHABLE):
        return TrackingError(
            f"cannot reach the MLflow {store} ({_reason(low)}; {_retried()}); a run it holds "
            "is marked FAILED by the next command on the store. Run the command again when "
            "the server answers")
    if "sqlite3.databaseerror" in low or "sqlite3.operationalerror" in low:
        return TrackingError(f"{store} cannot be used: {exc}")
    return None


#: What a request to a server that is away fails with (requests, urllib3, MLflow).
_UNREACHABLE = ("connection refused", "max retries exceeded", "failed to establish a new "
                "connection", "name or service not known", "connectionerror", "timed out",
                "remotedisconnected", "connection aborted", "connection reset")
#: The reason shown for each kind of failure, in the order looked for.
_REASONS = (("connection refused", "connection refused"),
            ("name or service not known", "unknown host"),
            ("timed out", "no answer in time"),
            ("remotedisconnected", "connection dropped"),
            ("connection aborted", "connection dropped"),
            ("connection reset", "connection dropped"))


#: urllib3's reason when every try of a request got an error status MLflow retries on.
_ERROR_STATUS = re.compile(r"too many (\d{3}) error responses")
#: The path of the failed request in urllib3's message.
_URL_PATH = re.compile(r"with url: (/\S*?)(?: \(caused by|$)", re.IGNORECASE)


def _request(text: str) -> str:
    """Name the failed request (``text``: the error's text).

    An artifact upload by the artifact's path, else the API endpoint.
    """
    found = _URL_PATH.search(text)
    if found is None:
        return "a request"
    path = found.group(1)
    if "/mlflow-artifacts/artifacts/" in path:
        return f"the upload of artifact {path.split('/artifacts/', 2)[-1][-60:]}"
    return f"the request {path.split('/mlflow/')[-1][:60]}"


def _answers(uri: str, timeout: float = 2.0) -> bool:
    """Tell whether the tracking server at ``uri`` answers its ``/health`` (200) now."""
    import urllib.request

    parts = urlsplit(uri)
    if parts.scheme not in ("http", "https") or not parts.hostname:
        return False
    netloc = parts.hostname + (f":{parts.port}" if parts.port else "")
    try:
        with urllib.request.urlopen(f"{parts.scheme}://{netloc}{parts.path.rstrip('/')}/health",
                                    timeout=timeout) as response:
            return bool(response.status == 200)
    except (OSError, ValueError):
        return False


def _reason(low: str) -> str:
    """Say in a few words why a request failed (``low``: the error's text, lower case)."""
    return next((reason for key, reason in _REASONS if key in low), "no connection")


def _retried() -> str:
    """Say how long MLflow retried a request (its environment variables)."""
    from mlflow.environment_variables import (  # (b) MLflow: a store error came from it
        MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR,
        MLFLOW_HTTP_REQUEST_MAX_RETRIES,
    )

    retries = MLFLOW_HTTP_REQUEST_MAX_RETRIES.get()
    factor = MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR.get()
    waited = sum(min(factor * 2 ** (n - 1), 120) for n in range(2, retries + 1))
    return f"MLflow retried for {waited:.0f} s, {retries} retries"


def duplicate_row(exc: BaseException) -> bool:
    """Tell whether ``exc`` is a database's unique-constraint violation.

    SQLite, PostgreSQL and MySQL: a row another process inserted first.

    Parameters
    ----------
    exc : BaseException
        The error.

    Returns
    -------
    bool
        Whether it is a duplicate row.
    """
    text = f"{exc} {exc.__cause__ or exc.__context__ or ''}".lower()
    return any(s in text for s in ("unique constraint", "duplicate key", "duplicate entry",
                                   "integrityerror"))
