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

from ..process.errors import ConfigError
from .toml_text import toml_comment, toml_string

__all__ = ["apply_overrides", "dump_config", "format_overrides", "parse_override",
           "parse_overrides"]


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


def _value(value: Any) -> str:
    """Write one value as TOML (tables inside arrays inline)."""
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def _key(key: str) -> str:
    """Write a key bare where TOML allows it, else quoted."""
    bare = key.replace("_", "").replace("-", "").isalnum() and key.isascii()
    return key if bare else toml_string(key)


def dump_config(raw: Mapping[str, Any], header: str = "") -> str:
    """Write a config's tables as TOML (what a run logs as the config it ran).

    Parameters
    ----------
    raw : mapping
        The config's tables (after :func:`apply_overrides`).
    header : str, default=""
        A comment written first (e.g. the file and the overrides it came from).

    Returns
    -------
    str
        TOML that ``tomllib`` reads back to ``raw``.
    """
    lines = [f"# {toml_comment(line)}" for line in header.splitlines()]

    def table(prefix: list[str], tab: Mapping[str, Any]) -> None:
        plain = {k: v for k, v in tab.items() if not isinstance(v, Mapping)}
        if prefix and (plain or not any(isinstance(v, Mapping) for v in tab.values())):
            lines.append("")
            lines.append("[" + ".".join(_key(p) for p in prefix) + "]")
        lines.extend(f"{_key(k)} = {_value(v)}" for k, v in plain.items())
        for k, v in tab.items():
            if isinstance(v, Mapping):
                table([*prefix, k], v)

    table([], raw)
    return "\n".join(lines) + "\n"
