"""Database (RDB) storages.

Opened with Optuna's heartbeat, a grace period and one retry of a stale trial; checked
before any work; problems as one line without the password. A database that stops
answering mid-sweep (restarted, failed over, a dropped connection) is waited for: each
storage call is tried again after :data:`RETRY_DELAYS_S`, then ends in one line naming the
store.
"""

from __future__ import annotations

import contextlib
import functools
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import optuna
from optuna.exceptions import ExperimentalWarning, StorageInternalError

from ..process.errors import StorageError, driver_hint, redact
from ..process.outputs import OutputError, check_file
from ._heartbeat import heartbeat_interval, retry_callback

__all__ = ["RETRY_DELAYS_S", "check_rdb", "rdb_storage"]

#: Seconds waited before each new try of a storage call the database did not answer (about
#: 30 s in all: a restarted or failed-over server is back well within it).
RETRY_DELAYS_S = (0.5, 1.0, 2.0, 4.0, 8.0, 15.0)

#: The storage calls retried: every one that reads or writes the database, with the private
#: ones Optuna's cache in front of it calls (``_CachedStorage``).
_RETRIED = (
    "_create_new_trial", "_get_best_trial_id", "_get_trials", "_set_trial_param",
    "create_new_study", "delete_study", "set_study_user_attr", "set_study_system_attr",
    "get_study_id_from_name", "get_study_name_from_id", "get_study_directions",
    "get_study_user_attrs", "get_study_system_attrs", "get_all_studies", "create_new_trial",
    "set_trial_param", "get_trial_id_from_study_id_trial_number", "get_trial_number_from_id",
    "get_trial_param", "set_trial_state_values", "set_trial_intermediate_value",
    "set_trial_user_attr", "set_trial_system_attr", "get_trial", "get_all_trials",
    "get_n_trials", "get_best_trial", "get_trial_params", "get_trial_user_attrs",
    "get_trial_system_attrs", "record_heartbeat", "_get_stale_trial_ids",
)

_F = TypeVar("_F", bound=Callable[..., Any])


@contextlib.contextmanager
def _rdb_errors(shown: str) -> Iterator[None]:
    """Database problems as one :class:`StorageError` line (without the password)."""
    import sqlalchemy.exc  # (b) SQLAlchemy: database storages only, not a journal

    try:
        yield
    except ImportError as exc:  # missing driver (psycopg2, pymysql, ...)
        raise StorageError(f"Optuna storage {shown}: its database driver is not installed "
                           f"({exc}); {driver_hint(exc)}") from None
    except sqlalchemy.exc.NoSuchModuleError as exc:
        raise StorageError(f"Optuna storage {shown}: unknown database kind ({exc})") from None
    except sqlalchemy.exc.ArgumentError as exc:
        raise StorageError(f"Optuna storage {shown} is not a valid database URL "
                           f"({exc})") from None
    except (sqlalchemy.exc.OperationalError, sqlalchemy.exc.InterfaceError) as exc:
        reason = str(getattr(exc, "orig", exc)).strip().splitlines()
        raise StorageError(f"cannot connect to Optuna storage {shown}: "
                           f"{reason[0][:150] if reason else type(exc).__name__}") from None


def _unreachable(exc: StorageInternalError) -> str | None:
    """Say why the database did not answer, or ``None`` when ``exc`` is not about reaching it.

    Optuna raises :class:`StorageInternalError` for every SQLAlchemy error; a lost or refused
    connection is worth another try, bad data is not. The lost connection may be the context
    of the error raised (a query made after it in the same transaction fails as
    ``PendingRollbackError``).
    """
    import sqlalchemy.exc  # (b) SQLAlchemy: database storages only, not a journal

    lost = (sqlalchemy.exc.OperationalError, sqlalchemy.exc.InterfaceError,
            sqlalchemy.exc.PendingRollbackError)
    cause, seen = exc.__cause__, 0
    while cause is not None and seen < 5:
        if isinstance(cause, lost) or (isinstance(cause, sqlalchemy.exc.DBAPIError)
                                       and cause.connection_invalidated):
            reason = str(getattr(cause, "orig", cause)).strip().splitlines()
            return reason[0][:150] if reason else type(cause).__name__
        cause, seen = cause.__cause__ or cause.__context__, seen + 1
    return None


def _retried(method: _F) -> _F:
    """Wrap a storage call so that it waits for a database that does not answer.

    It is tried again after each of :data:`RETRY_DELAYS_S`, then ends in a
    :class:`StorageError` of one line naming the store.
    """
    @functools.wraps(method)
    def call(self: RetryingRDBStorage, *args: Any, **kwargs: Any) -> Any:
        for delay in (*RETRY_DELAYS_S, None):
            try:
                return method(self, *args, **kwargs)
            except StorageInternalError as exc:
                reason = _unreachable(exc)
                if reason is None:
                    raise
                if delay is None:
                    raise StorageError(
                        f"Optuna storage {self.shown} did not answer for "
                        f"{sum(RETRY_DELAYS_S):.0f} s ({reason}); run the same command to "
                        "resume once it is back") from None
            time.sleep(delay)
        raise AssertionError("unreachable")

    return call  # type: ignore[return-value]


class RetryingRDBStorage(optuna.storages.RDBStorage):
    """Optuna's RDB storage, waiting for a database that stops answering for a while.

    Each call that reaches the database is tried again after each of
    :data:`RETRY_DELAYS_S` when the connection is lost or refused (SQLAlchemy then replaces
    the pool's connections), and ends in a :class:`StorageError` of one line naming the
    store (without its password) when the database is still away. A transaction is
    committed whole or not at all, so a call tried again does not write twice, unless the
    connection dropped between a commit and its answer (rare; not handled).

    Parameters
    ----------
    url : str
        The database URL.
    shown : str
        The URL as errors show it (password redacted).
    **kwargs
        Optuna's :class:`~optuna.storages.RDBStorage` arguments.
    """

    def __init__(self, url: str, shown: str, **kwargs: Any) -> None:
        self.shown = shown
        super().__init__(url, **kwargs)


for _name in _RETRIED:
    setattr(RetryingRDBStorage, _name, _retried(getattr(optuna.storages.RDBStorage, _name)))


def _engine_kwargs(url: str) -> dict:
    if url.startswith("postgresql"):  # an unreachable host fails in seconds, not minutes
        return {"connect_args": {"connect_timeout": 10}}
    return {}


def _sqlite_file(url: str, shown: str) -> Path | None:
    if not url.startswith("sqlite:///"):
        return None
    db = Path(url[len("sqlite:///"):].partition("?")[0])
    if db.is_dir():
        raise StorageError(f"Optuna storage {shown} is a directory, not a database file")
    return db


def check_rdb(url: str) -> None:
    """Check that the database accepts a connection.

    Nothing is created; a new SQLite file's directory must be writable.
    """
    import sqlalchemy  # (b) SQLAlchemy: database storages only, not a journal

    shown = redact(url)
    db = _sqlite_file(url, shown)
    if db is not None:
        try:
            check_file(db, "Optuna storage")
        except OutputError as exc:
            raise StorageError(str(exc)) from None
        if not db.exists():
            return  # connecting would create it
    with _rdb_errors(shown):
        engine = sqlalchemy.create_engine(url, **_engine_kwargs(url))
        try:
            with engine.connect():
                pass
        finally:
            engine.dispose()


def rdb_storage(url: str, stale_after_s: float) -> optuna.storages.RDBStorage:
    shown = redact(url)
    db = _sqlite_file(url, shown)
    if db is not None:
        db.parent.mkdir(parents=True, exist_ok=True)
    with _rdb_errors(shown):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExperimentalWarning)  # heartbeat_interval
            return RetryingRDBStorage(
                url, shown, engine_kwargs=_engine_kwargs(url) or None,
                heartbeat_interval=heartbeat_interval(stale_after_s),
                grace_period=max(1, int(stale_after_s)),
                heartbeat_stale_trial_callback=retry_callback())

