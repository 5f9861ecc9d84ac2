"""The Optuna storage adapter of ``workbench sweep``: journal files and databases.

Shaped like ``optuna.storages``: this public front over one private module per concern,
``_journal`` (the journal file, failing safe), ``_repair`` (``--repair``), ``_rdb``
(databases) and ``_heartbeat`` (heartbeats and retries).

* :func:`open_storage` / :func:`check_storage`: an RDB URL (with Optuna's heartbeat, a grace
  period and one retry of a stale trial) or a journal file, checked before any work; problems
  are one :class:`~workbench.experiment.process.errors.StorageError` line without the password.
* The journal file fails safe: a damaged line is found before anything is appended
  (:class:`JournalDamaged`, naming the command that repairs it) and :func:`repair_journal`
  recovers every complete record into a new file (``workbench sweep --repair``).
* What the scheduler needs of Optuna's internals and storages: :func:`beat`,
  :func:`heartbeat_enabled`, :func:`fail_stale_trials`, :func:`set_trial_attr`,
  :func:`retry`; and the
  ``optuna-dashboard`` command line (:func:`dashboard_command`).

May import: process. The only home that touches Optuna's storages and private names (a test
checks).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import optuna

from ..process.errors import StorageError
from ..process.outputs import OutputError, check_file
from ._heartbeat import (
    beat,
    fail_stale_trials,
    heartbeat_enabled,
    heartbeat_interval,
    retry,
    set_trial_attr,
)
from ._journal import JournalDamaged, JournalFile, find_damage, journal_file
from ._rdb import check_rdb, rdb_storage
from ._repair import Repair, repair_journal

__all__ = ["JournalDamaged", "Repair", "StorageError", "beat", "check_storage",
           "dashboard_command", "fail_stale_trials", "heartbeat_enabled", "heartbeat_interval",
           "open_storage", "repair_journal", "retry", "set_trial_attr"]


def open_storage(storage: str, root: Path, *, stale_after_s: float = 600,
                 hint: str | None = None) -> optuna.storages.BaseStorage:
    """Open the Optuna storage ``storage``: an RDB URL, else a journal file.

    An RDB storage has Optuna's heartbeat, grace period ``stale_after_s`` and one retry of a
    stale trial; a journal file is checked for damage before anything is appended.

    Parameters
    ----------
    storage : str
        An RDB URL (``scheme://...``) or a journal file's path.
    root : Path
        The directory a relative journal path resolves against.
    stale_after_s : float, default=600
        Seconds without a heartbeat after which a running trial counts as dead.
    hint : str, optional
        The command that repairs a damaged journal, named in its error.

    Returns
    -------
    optuna.storages.BaseStorage
        The storage.

    Raises
    ------
    StorageError
        One line, without the URL's password (:class:`JournalDamaged` for a damaged journal).
    """
    if "://" in storage:
        return rdb_storage(storage, stale_after_s)
    path = journal_file(storage, root)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        backend = JournalFile(str(path), storage)
    except OSError as exc:
        raise StorageError(f"cannot use Optuna journal file {path}: "
                           f"{exc.strerror or type(exc).__name__}") from None
    backend.check(hint)
    try:
        return optuna.storages.JournalStorage(backend)
    except StorageError:
        raise
    except Exception as exc:  # a well-formed record that Optuna cannot replay
        damage = find_damage(path, storage, hint, replay=True)
        raise damage or StorageError(f"Optuna journal {storage} cannot be replayed "
                                     f"({type(exc).__name__})") from None


def check_storage(storage: str, root: Path, *, hint: str | None = None) -> None:
    """Check, before any work and writing nothing, that the Optuna storage can be used.

    A journal file that exists is checked as :func:`open_storage` checks it; a missing one
    must be creatable (it is not created here); a database must accept a connection (its
    tables are not created here).

    Parameters
    ----------
    storage : str
        An RDB URL or a journal file's path.
    root : Path
        The directory a relative journal path resolves against.
    hint : str, optional
        The command that repairs a damaged journal, named in its error.

    Raises
    ------
    StorageError
        One line, without the URL's password.
    """
    if "://" in storage:
        check_rdb(storage)
        return
    path = journal_file(storage, root)
    try:  # its directory takes new files (the journal's lock is created there)
        check_file(path, "Optuna journal")
    except OutputError as exc:
        raise StorageError(str(exc)) from None
    if path.exists():
        if not os.access(path, os.R_OK | os.W_OK):
            raise StorageError(f"Optuna journal {storage} cannot be read and written "
                               "(its permissions)")
        open_storage(storage, root, hint=hint)



def dashboard_command(storage: str, port: int, root: Path) -> list[str]:
    """Build the ``optuna-dashboard`` command line serving the studies of ``storage``.

    ``storage`` is a journal file (relative to ``root``) or an RDB URL; the dashboard
    listens on 127.0.0.1:``port``.
    """
    cmd = [sys.executable, "-c", "from optuna_dashboard._cli import main; main()",
           "--host", "127.0.0.1", "--port", str(port)]  # the package has no __main__
    if "://" in storage:
        return cmd + [storage]
    path = Path(storage)
    path = path if path.is_absolute() else root / path
    return cmd + ["--storage-class", "JournalFileStorage", str(path)]
