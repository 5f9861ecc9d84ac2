"""Where the MLflow store is: tracking URIs and the checks run before any work.

The default SQLite store is in the project, and a relative path is resolved where the user
typed it. The checks: a scheme MLflow has a store for, an installed database driver, a
writable SQLite location, a server that answers. Light: MLflow and SQLAlchemy are imported
only by the checks that need them.
"""

from __future__ import annotations

import os
import socket
import tempfile
from pathlib import Path
from urllib.parse import urlsplit

from ..process.errors import TrackingError, driver_hint, redact

__all__ = ["DEFAULT_STORE", "check_store_uri", "default_artifact_root", "default_tracking_uri",
           "describe_store", "resolve_tracking_uri", "sqlite_path"]

DEFAULT_STORE = "mlruns"
_SQLITE_HEADER = b"SQLite format 3\x00"


def default_tracking_uri(root: Path) -> str:
    """Return the default tracking URI of a project.

    Parameters
    ----------
    root : Path
        The project's directory.

    Returns
    -------
    str
        ``sqlite:///<abs root>/mlruns/mlflow.db``.
    """
    return "sqlite:///" + str(Path(root).resolve() / DEFAULT_STORE / "mlflow.db")


def default_artifact_root(root: Path) -> str:
    """Return the default artifact root of a project.

    Parameters
    ----------
    root : Path
        The project's directory.

    Returns
    -------
    str
        ``file:///<abs root>/mlruns/artifacts``.
    """
    return (Path(root).resolve() / DEFAULT_STORE / "artifacts").as_uri()


def _split_sqlite(uri: str) -> tuple[str, str] | None:
    """Split a ``sqlite:///`` URI into ``(path, query)``.

    ``path`` is relative unless it starts with ``/``; ``None`` for other URIs and in-memory
    databases.
    """
    if not uri.startswith("sqlite:///"):
        return None
    path, sep, query = uri.removeprefix("sqlite:///").partition("?")
    if not path or path == ":memory:":
        return None
    return path, sep + query


def _absolute_sqlite(uri: str, base: Path) -> str:
    """Make a relative sqlite path of ``uri`` absolute against ``base``."""
    parts = _split_sqlite(uri)
    if parts is None or Path(parts[0]).is_absolute():
        return uri
    path, query = parts
    return "sqlite:///" + str((Path(base) / path).resolve()) + query


def resolve_tracking_uri(cli: str | None, config: str | None, root: Path) -> str:
    """Choose the tracking URI to use.

    The CLI flag, else ``$MLFLOW_TRACKING_URI``, else the config value, else
    :func:`default_tracking_uri`. A relative sqlite path in the config
    (``sqlite:///mlruns/mlflow.db``) is relative to ``root``; in the CLI flag or the
    environment it is relative to the current directory, as the user typed it there.

    Parameters
    ----------
    cli : str or None
        ``--tracking-uri``.
    config : str or None
        The config's ``tracking_uri``.
    root : Path
        The project's directory (the config's).

    Returns
    -------
    str
        The tracking URI, sqlite paths absolute.
    """
    if cli:
        return _absolute_sqlite(cli, Path.cwd())
    env = os.environ.get("MLFLOW_TRACKING_URI")
    if env:
        return _absolute_sqlite(env, Path.cwd())
    if config:
        return _absolute_sqlite(config, Path(root))
    return default_tracking_uri(root)


def sqlite_path(uri: str) -> Path | None:
    """Return the database file of a ``sqlite:///`` URI.

    Parameters
    ----------
    uri : str
        A tracking URI.

    Returns
    -------
    Path or None
        ``None`` for other stores and in-memory databases.
    """
    parts = _split_sqlite(uri)
    return Path(parts[0]) if parts else None


def is_database(uri: str) -> bool:
    """Tell whether a tracking URI is a database MLflow opens in this process (SQLAlchemy).

    Parameters
    ----------
    uri : str
        A tracking URI.

    Returns
    -------
    bool
        ``True`` for ``sqlite``, ``postgresql``, ``mysql`` and ``mssql`` (any driver).
    """
    return urlsplit(str(uri)).scheme.split("+")[0] in ("sqlite", "postgresql", "mysql", "mssql")


def describe_store(uri: str) -> str:
    """Name the store as messages name it.

    Parameters
    ----------
    uri : str
        A tracking URI.

    Returns
    -------
    str
        Its SQLite file, else its URI without a password.
    """
    path = sqlite_path(uri)
    return f"SQLite database {path}" if path else f"tracking store {redact(uri)}"


def prepare_store_location(uri: str) -> None:
    """Check the store, then create a SQLite store's directory.

    What a client needs before its first use of the store.

    Parameters
    ----------
    uri : str
        A tracking URI.

    Raises
    ------
    TrackingError
        As :func:`check_store_uri`, or the directory cannot be created.
    """
    check_store_uri(uri)
    path = sqlite_path(uri)
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise TrackingError(f"SQLite database {path}: cannot create its directory: "
                            f"{exc.strerror or type(exc).__name__}") from None


def _check_sqlite_location(path: Path) -> None:
    """Check a SQLite database's location without writing anything.

    ``path`` is not a directory, and its directory (or the nearest existing one, where it
    would be created) accepts new files: SQLite writes its journal and the first-use lock
    beside the database, even for an existing one.
    """
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
    from importlib.metadata import entry_points  # (c) stdlib, slow to import: this module is light

    from mlflow.store.db.db_types import DATABASE_ENGINES  # (b) MLflow: not for evaluate --no-track

    plugins = [e.name for e in entry_points(group="mlflow.tracking_store")]
    return [*_MLFLOW_SCHEMES, *DATABASE_ENGINES, *plugins]


def _check_scheme_and_driver(uri: str) -> None:
    """Check without connecting that MLflow has a store for the URI's scheme.

    And that a database URI's driver is installed.
    """
    from mlflow.store.db.db_types import DATABASE_ENGINES  # (b) MLflow: not for evaluate --no-track

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
    import sqlalchemy.exc  # (b) SQLAlchemy: database URIs only
    from sqlalchemy.engine import make_url  # (b) SQLAlchemy: database URIs only

    try:
        make_url(uri).get_dialect().import_dbapi()
    except ImportError as exc:
        raise TrackingError(f"tracking store {shown}: its database driver is not installed "
                            f"({exc}); {driver_hint(exc)}") from None
    except sqlalchemy.exc.NoSuchModuleError:
        raise TrackingError(f"tracking store {shown}: SQLAlchemy has no database driver "
                            f"'{scheme}'") from None
    except sqlalchemy.exc.ArgumentError:
        raise TrackingError(f"tracking URI {shown} is not a valid database URL") from None


def check_store_uri(uri: str) -> None:
    """Check, before any work and writing nothing, that the tracking store at ``uri`` can be used.

    Its scheme has an MLflow store, a database's driver is installed, a SQLite database's
    directory can be written (and the file is SQLite), a server accepts connections.

    Parameters
    ----------
    uri : str
        A tracking URI.

    Raises
    ------
    TrackingError
        One line, no password.
    """
    _check_scheme_and_driver(uri)
    path = sqlite_path(uri)
    if path is not None:
        _check_sqlite_location(path)
        _check_sqlite_header(path)
    _check_server(uri)


def _check_server(uri: str, timeout: float = 5.0) -> None:
    """Fail fast when an http(s) tracking server refuses connections (MLflow retries long)."""
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
