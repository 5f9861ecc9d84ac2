"""Errors the ``workbench`` command reports as one ``workbench: error: ...`` line, exit code 2.

Also what keeps such lines short and free of secrets (the core's
:func:`workbench._text.clip`, shared with the data readers; :func:`shorten`, :func:`listing`,
:func:`redact`). Kept in a module of their own (no heavy imports), so the command can catch
them without loading MLflow, Optuna or the estimators.
"""

from __future__ import annotations

import difflib
import errno
import importlib.util
import re
from collections.abc import Iterable
from typing import Any

from ..._text import clip

__all__ = ["ConfigError", "StorageError", "SweepTimedOut", "TrackingError", "UsageError",
           "disk_full", "driver_hint", "listing", "redact", "redact_config", "redact_urls",
           "shorten", "unknown_keys"]


class ConfigError(ValueError):
    """A config file that cannot be used; the message names the file, the key and the value."""


class UsageError(ValueError):
    """Bad command-line values."""


class StorageError(ValueError):
    """The Optuna storage cannot be used.

    A bad path, a missing driver, an unreachable server, a damaged journal.
    """


class TrackingError(RuntimeError):
    """The tracking store cannot be used (locked, corrupt, unreachable, ...)."""


class SweepTimedOut(Exception):
    """A sweep stopped by its timeout before every study had its trials.

    Not an error: the studies keep their trials and the same command resumes them. The
    command's MLflow run ends ``KILLED`` (stopped before its end, as by Ctrl-C; no model, no
    test metrics) and the command exits :attr:`code`, one line on standard error.
    """

    #: The exit code (that of coreutils' ``timeout``).
    code = 124


def shorten(value: Any, limit: int = 60) -> str:
    """Return ``repr(value)`` cut to ``limit`` characters.

    A million-digit number stays one short line.

    Parameters
    ----------
    value : object
        The value to show.
    limit : int, default=60
        The longest result.

    Returns
    -------
    str
        The repr, with its length noted when cut.
    """
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
    """Say what to do about a database driver that is not installed.

    SQLAlchemy 2.1 maps ``postgresql://`` to psycopg 3; ``postgresql+psycopg2://`` names
    psycopg2.

    Parameters
    ----------
    exc : ImportError
        The failed import of the driver.

    Returns
    -------
    str
        E.g. ``pip install psycopg[binary]``.
    """
    name = (exc.name or "").split(".")[0]
    hint = f"pip install {_DRIVER_PACKAGES.get(name, name or 'the driver')}"
    if name == "psycopg" and importlib.util.find_spec("psycopg2"):
        hint += ", or use the installed psycopg2: postgresql+psycopg2://..."
    return hint


def listing(names: Iterable, budget: int = 140, width: int = 30) -> str:
    """List names for an error line, within a character budget, with their count if cut.

    As in ``'a', 'b', ... (N in all)``.

    Parameters
    ----------
    names : iterable
        The names (shown as text).
    budget : int, default=140
        Characters the shown names may take.
    width : int, default=30
        Characters each name is cut to (:func:`clip`).

    Returns
    -------
    str
        As many names as fit, then how many there are in all.
    """
    names = [str(n) for n in names]
    shown: list[str] = []
    used = 0
    for name in names:
        item = repr(clip(name, width))
        if shown and used + len(item) + 2 > budget:
            break
        shown.append(item)
        used += len(item) + 2
    more = len(names) - len(shown)
    return ", ".join(shown) + (f", ... ({len(names)} in all)" if more else "")


def unknown_keys(unknown: Iterable, valid: Iterable) -> str:
    """Describe unknown keys, with the closest valid key and the valid ones.

    As in ``unknown key(s) ['x'] (did you mean 'y'?); valid keys are ...``.

    Parameters
    ----------
    unknown : iterable
        The keys not recognised.
    valid : iterable
        The keys allowed.

    Returns
    -------
    str
        One shortened line.
    """
    unknown, valid = sorted(map(str, unknown)), sorted(map(str, valid))
    text = f"unknown key(s) [{listing(unknown, budget=60)}]"
    close = [m for key in unknown[:3] for m in difflib.get_close_matches(key, valid, n=1)]
    if close:
        text += f" (did you mean {listing(dict.fromkeys(close), budget=60)}?)"
    return f"{text}; valid keys are {listing(valid)}"


#: What a full disk (or an exhausted quota) says: the OS, SQLite.
_DISK_FULL_TEXT = ("no space left on device", "database or disk is full",
                   "disk quota exceeded")


def disk_full(exc: BaseException) -> str | None:
    """Tell whether ``exc`` (or its cause) is a full disk, and where it was writing.

    Parameters
    ----------
    exc : BaseException
        An error: an ``OSError`` with ``errno`` ``ENOSPC`` or ``EDQUOT``, or one whose text
        says so (SQLite's ``database or disk is full``, an error MLflow wrapped).

    Returns
    -------
    str or None
        ``None`` when it is not a full disk; else the file being written (``""`` when not
        known).

    Examples
    --------
    >>> disk_full(OSError(28, "No space left on device", "/data/out.csv"))
    '/data/out.csv'
    >>> disk_full(ValueError("bad")) is None
    True
    """
    seen: BaseException | None = exc
    for _ in range(4):  # the error, its cause, ...
        if seen is None:
            break
        if isinstance(seen, OSError) and seen.errno in (errno.ENOSPC, errno.EDQUOT):
            return str(seen.filename2 or seen.filename or "")
        if any(s in str(seen).lower() for s in _DISK_FULL_TEXT):
            return ""
        seen = seen.__cause__ or seen.__context__
    return None


# --------------------------------------------------------------------------- secrets

_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*")
#: Query parameters of a URL that hold a credential (``...?password=...``).
_SECRET_QUERY = re.compile(r"(?i)([?&;](?:password|passwd|pwd|secret|token|access_token|"
                           r"api_key|apikey)=)[^&;#]*")
#: A URL in free text (a TOML comment, a message): up to a space or a quote.
_URL_TOKEN = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*://[^\s\"'`]+")


def redact(url: object) -> str:
    """Hide the credentials of a URL: its password and any credential in its query.

    The password is everything between the first ``:`` of the user part and the *last*
    ``@``, so a password holding ``/``, ``?``, ``#`` or ``@`` (unescaped, as people paste
    them) is hidden too; a URL with an ``@`` in its path may be redacted more than needed,
    never less.

    Parameters
    ----------
    url : object
        A URL (shown as text); text that is not a ``scheme://`` URL (a journal file path) is
        returned as given.

    Returns
    -------
    str
        The URL with ``***`` for the password (``scheme://user:***@host``) and query
        credentials (``?password=***``): safe to print, log or store.
    """
    text = str(url)
    head, sep, rest = text.partition("://")
    if not sep or not _SCHEME.fullmatch(head):
        return text
    at = rest.rfind("@")
    if at >= 0:
        user, colon, _ = rest[:at].partition(":")
        if colon and "/" not in user:
            rest = f"{user}:***{rest[at:]}"
    return head + sep + _SECRET_QUERY.sub(r"\1***", rest)


def redact_urls(text: str) -> str:
    """Apply :func:`redact` to every ``scheme://...`` in ``text`` (up to a space or a quote).

    Parameters
    ----------
    text : str
        Free text (a message, a TOML comment).

    Returns
    -------
    str
        The text with every URL's credentials hidden.
    """
    return _URL_TOKEN.sub(lambda m: redact(m.group(0)), str(text))


def _strings(value: object) -> Iterable[str]:
    """Yield every string in a parsed TOML value (tables and arrays walked)."""
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for item in value.values():
            yield from _strings(item)
    elif isinstance(value, list):
        for item in value:
            yield from _strings(item)


def _toml_basic(text: str) -> str:
    """Write ``text`` as it appears inside a TOML basic string ("..."), common escapes."""
    out = text.replace("\\", "\\\\").replace('"', '\\"')
    for char, escape in (("\b", "\\b"), ("\t", "\\t"), ("\n", "\\n"), ("\f", "\\f"),
                         ("\r", "\\r")):
        out = out.replace(char, escape)
    return out


def redact_config(text: str, name: str = "the config") -> str:
    """Hide every URL's credentials in a TOML config's text, the rest as written.

    Values such as ``[study] storage`` and ``[tracking] tracking_uri``, and URLs in comments.

    Parameters
    ----------
    text : str
        The config's text.
    name : str, default="the config"
        What the note names when the text cannot be redacted.

    Returns
    -------
    str
        The redacted text; a one-line note instead when a credential-bearing value cannot be
        found in the text (an unusual escape): it is never logged with the secret.
    """
    import tomllib  # (c) stdlib: `workbench --help` loads this module

    try:
        values = [s for s in _strings(tomllib.loads(text)) if redact(s) != s]
    except (tomllib.TOMLDecodeError, ValueError):
        values = []
    for value in sorted(set(values), key=len, reverse=True):
        found = False
        for form, safe in ((value, redact(value)),
                           (_toml_basic(value), _toml_basic(redact(value)))):
            if form in text:
                text, found = text.replace(form, safe), True
        if not found:
            return (f"# {name}: not shown (it holds a credential that could not be "
                    f"redacted)\n")
    return redact_urls(text)
