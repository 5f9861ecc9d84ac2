"""Errors the ``workbench`` command reports as one ``workbench: error: ...`` line, exit code 2.

Kept in a module of their own (no heavy imports), so the command can catch them without
loading MLflow, Optuna or the estimators.
"""

from __future__ import annotations

__all__ = ["ConfigError", "StorageError", "TrackingError", "UsageError", "driver_hint", "shorten"]


class ConfigError(ValueError):
    """A config file that cannot be used; the message names the file, the key and the value."""


class UsageError(ValueError):
    """Bad command-line values."""


class StorageError(ValueError):
    """The Optuna storage cannot be used (bad path, missing driver, unreachable server, a
    damaged journal)."""


class TrackingError(RuntimeError):
    """The tracking store cannot be used (locked, corrupt, unreachable, ...)."""


def shorten(value, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a million-digit number stays one short line)."""
    try:
        text = repr(value)
    except ValueError:  # an int beyond Python's str-conversion limit
        return f"<an integer of {value.bit_length()} bits>"
    return text if len(text) <= limit else f"{text[:limit - 14]}... ({len(text)} chars)"


#: The pip package of a database driver module SQLAlchemy imports.
_DRIVER_PACKAGES = {"psycopg": "psycopg[binary]", "psycopg2": "psycopg2-binary",
                    "MySQLdb": "mysqlclient", "pymysql": "pymysql", "pg8000": "pg8000",
                    "pyodbc": "pyodbc", "asyncpg": "asyncpg", "pymssql": "pymssql"}


def driver_hint(exc: ImportError) -> str:
    """What to do about a database driver that is not installed (SQLAlchemy 2.1 maps
    ``postgresql://`` to psycopg 3; ``postgresql+psycopg2://`` names psycopg2)."""
    import importlib.util

    name = (exc.name or "").split(".")[0]
    hint = f"pip install {_DRIVER_PACKAGES.get(name, name or 'the driver')}"
    if name == "psycopg" and importlib.util.find_spec("psycopg2"):
        hint += ", or use the installed psycopg2: postgresql+psycopg2://..."
    return hint
