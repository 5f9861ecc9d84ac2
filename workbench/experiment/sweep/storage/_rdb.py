"""Database (RDB) storages.

Opened with Optuna's heartbeat, a grace period and one retry of a stale trial; checked
before any work; problems as one line without the password.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from pathlib import Path

import optuna
from optuna.exceptions import ExperimentalWarning

from ...errors import StorageError, driver_hint, redact
from ...outputs import OutputError, check_file
from ._heartbeat import heartbeat_interval, retry_callback

__all__ = ["check_rdb", "rdb_storage"]


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
            return optuna.storages.RDBStorage(
                url, engine_kwargs=_engine_kwargs(url) or None,
                heartbeat_interval=heartbeat_interval(stale_after_s),
                grace_period=max(1, int(stale_after_s)),
                heartbeat_stale_trial_callback=retry_callback())

