"""Errors the ``workbench`` command reports as one ``workbench: error: ...`` line, exit code 2.

Kept in a module of their own (no heavy imports), so the command can catch them without
loading MLflow, Optuna or the estimators.
"""

from __future__ import annotations

__all__ = ["ConfigError", "TrackingError", "UsageError", "shorten"]


class ConfigError(ValueError):
    """A config file that cannot be used; the message names the file, the key and the value."""


class UsageError(ValueError):
    """Bad command-line values."""


class TrackingError(RuntimeError):
    """The tracking store cannot be used (locked, corrupt, unreachable, ...)."""


def shorten(value, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a million-digit number stays one short line)."""
    try:
        text = repr(value)
    except ValueError:  # an int beyond Python's str-conversion limit
        return f"<an integer of {value.bit_length()} bits>"
    return text if len(text) <= limit else f"{text[:limit - 14]}... ({len(text)} chars)"
