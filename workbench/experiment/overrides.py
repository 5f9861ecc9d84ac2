"""Config overrides: ``SECTION.KEY=VALUE`` from the command line, or a mapping from Python.

An override replaces one value of a config's tables before they are checked, so the typed
schema checks it like a value written in the file: an unknown key is an error listing the
valid keys, a bad value one line naming the key. ``VALUE`` is read as TOML (``2``, ``0.5``,
``true``, ``"huber"``, ``["ridge", "lightgbm"]``, ``{ low = 1, high = 3 }``); a bare word
that is not TOML (``huber``) is a string.
"""

from __future__ import annotations

import copy
import json
import tomllib
from collections.abc import Iterable, Mapping
from typing import Any

from .errors import ConfigError

__all__ = ["apply_overrides", "format_overrides", "parse_override", "parse_overrides"]


def parse_override(text: str) -> tuple[str, Any]:
    """Split ``SECTION.KEY=VALUE`` into its dotted key and its value.

    Parameters
    ----------
    text : str
        One override, e.g. ``"model.n_stages=2"``.

    Returns
    -------
    key : str
        The dotted key (``"model.n_stages"``).
    value : object
        The value read as TOML, or the text itself where it is not TOML.

    Raises
    ------
    ConfigError
        For text without ``=`` or with an empty key or key part.
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key or any(not part.strip() for part in key.split(".")):
        raise ConfigError(f"--set {text!r}: give SECTION.KEY=VALUE, e.g. model.n_stages=2")
    try:
        parsed = tomllib.loads(f"v = {value.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        parsed = value.strip()
    return ".".join(part.strip() for part in key.split(".")), parsed


def parse_overrides(texts: Iterable[str]) -> dict[str, Any]:
    """Read several ``SECTION.KEY=VALUE`` overrides (a later one for a key wins).

    Parameters
    ----------
    texts : iterable of str
        The overrides as given on the command line.

    Returns
    -------
    dict
        Dotted key -> value, in the order given.
    """
    return dict(parse_override(text) for text in texts)


def apply_overrides(raw: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """Return a copy of a config's tables with each dotted key set to its value.

    Tables named on the way that do not exist yet are created (e.g.
    ``model.targets.eeig1.n_stages``); whether a key is valid is left to the config's schema.

    Parameters
    ----------
    raw : mapping
        The config's tables, as read from TOML.
    overrides : mapping
        Dotted key (``"model.n_stages"``) -> value.

    Returns
    -------
    dict
        The tables with the overrides applied; ``raw`` is not changed.

    Raises
    ------
    ConfigError
        Where a key passes through a value that is not a table (``name.x`` with ``name`` a
        string).
    """
    out = copy.deepcopy(dict(raw))
    for dotted, value in overrides.items():
        *path, last = dotted.split(".")
        table = out
        for depth, part in enumerate(path):
            table = table.setdefault(part, {})
            if not isinstance(table, dict):
                where = ".".join(path[:depth + 1])
                raise ConfigError(f"--set {dotted}: {where} is a value, not a table")
        table[last] = copy.deepcopy(value)
    return out


def format_overrides(overrides: Mapping[str, Any]) -> str:
    """Write overrides as the command line gives them, for messages and run records.

    Parameters
    ----------
    overrides : mapping
        Dotted key -> value.

    Returns
    -------
    str
        ``'model.n_stages=2 model.loss="huber"'`` (values as JSON, which TOML reads alike
        for numbers, booleans, strings and lists).
    """
    return " ".join(f"{key}={json.dumps(value)}" for key, value in overrides.items())
