"""A new SQLite store's first contents: a copy of an empty one kept in the user cache.

MLflow's chain of schema migrations (2-3.5 CPU-s, a disk sync each) then runs once per
machine and MLflow version, not once per store. The template is checked before every copy
(a damaged one is dropped) and never replaces an existing file; any failure leaves the new
store to MLflow, as without a template.
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import logging
import os
import shutil
import sqlite3
import tempfile
import threading
from pathlib import Path

__all__ = ["copy_store_template", "keep_store_template", "store_template"]

_logger = logging.getLogger("workbench.experiment.tracking")


def store_template() -> Path:
    """Where the empty SQLite store of the installed MLflow version is kept.

    ``$XDG_CACHE_HOME/workbench/mlflow-stores/mlflow-<version>.db`` (default
    ``~/.cache/workbench``): the schema MLflow migrated a new database to, without MLflow's
    ``Default`` experiment (each store gets its own on first use, its artifacts beside it).
    A new SQLite store starts as a copy (:meth:`~.runs.Tracker.client`); deleting the file
    is safe.

    Returns
    -------
    Path
        The template's path (it may not exist yet).
    """
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    version = importlib.metadata.version("mlflow")
    return Path(base) / "workbench" / "mlflow-stores" / f"mlflow-{version}.db"


def copy_store_template(path: Path) -> bool:
    """Create the new store ``path`` as a copy of :func:`store_template`; whether it did.

    The copy appears whole or not at all (a hard link of a finished and checked copy, never
    over an existing file); without a template, or where the copy fails, MLflow creates the
    store (a damaged template is deleted: the store MLflow creates is kept instead).

    Parameters
    ----------
    path : Path
        The new store's database file (its directory exists).

    Returns
    -------
    bool
        Whether ``path`` exists now (copied here, or made meanwhile by another process).
    """
    template = store_template()
    if not template.is_file():
        return False
    # a name of its own, opened exclusively: created with the user's umask, as SQLite would
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.new")
    try:
        with open(template, "rb") as src, open(tmp, "xb") as dst:
            shutil.copyfileobj(src, dst)
            dst.flush()
            os.fsync(dst.fileno())
        _check_copy(tmp)
        os.link(tmp, path)
        return True
    except sqlite3.Error as exc:  # a damaged template: MLflow creates this one, kept next
        _logger.debug("store template %s dropped: %s", template, exc)
        with contextlib.suppress(OSError):
            os.unlink(template)
        return False
    except OSError as exc:  # no hard links here, a full disk, or a store made meanwhile
        _logger.debug("new store %s not copied from %s: %s", path, template, exc)
        return path.exists()
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _check_copy(path: Path) -> None:
    """Raise :class:`sqlite3.Error` unless ``path`` is a whole database with a schema version."""
    db = sqlite3.connect(path)
    try:
        if (db.execute("PRAGMA quick_check").fetchall() != [("ok",)]
                or len(db.execute("SELECT version_num FROM alembic_version").fetchall()) != 1):
            raise sqlite3.DatabaseError(f"{path} is not an empty MLflow store")
    finally:
        db.close()


def keep_store_template(path: Path) -> None:
    """Keep an empty copy of the store MLflow just created at ``path`` as the template.

    Copied with SQLite's backup (consistent while others write), kept only if MLflow's
    ``Default`` experiment is all it holds (then deleted from the copy), and moved into place
    whole. Never fails the command: the next new store is then migrated by MLflow again.

    Parameters
    ----------
    path : Path
        The database file of a store MLflow has just created.
    """
    template = store_template()
    if template.exists():
        return
    try:
        template.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=template.parent, prefix=".mlflow-", suffix=".db")
        os.close(fd)
    except OSError as exc:
        _logger.debug("no store template in %s: %s", template.parent, exc)
        return
    try:
        src, dst = sqlite3.connect(path), sqlite3.connect(tmp)
        try:
            src.backup(dst)
            experiments = dst.execute("SELECT experiment_id FROM experiments").fetchall()
            runs = dst.execute("SELECT count(*) FROM runs").fetchone()[0]
            if experiments != [(0,)] or runs:
                return  # another process used the store already
            dst.execute("DELETE FROM experiments WHERE experiment_id = 0")
            dst.commit()
        finally:
            src.close()
            dst.close()
        os.replace(tmp, template)
    except (OSError, sqlite3.Error) as exc:
        _logger.debug("no store template from %s: %s", path, exc)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
