"""TOML text as ``workbench init`` writes it: strings, arrays, comments, a template's head.

Kept apart from :mod:`~workbench.experiment.runs.init` (which decides what a first config says)
as the part that only knows TOML's syntax.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Sequence

__all__ = ["split_template", "toml_comment", "toml_string", "toml_strings"]


def toml_string(value: str) -> str:
    """Write ``value`` as a TOML basic string.

    Parameters
    ----------
    value : str
        Any text.

    Returns
    -------
    str
        ``"..."`` with quotes, backslashes and control characters escaped.
    """
    out = []
    for ch in value:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ch in "\b\t\n\f\r":
            out.append({"\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_strings(key: str, values: Sequence[str], width: int = 92) -> str:
    """Write ``key = ["a", "b"]``, wrapped over several lines when it is long.

    Parameters
    ----------
    key : str
        The TOML key.
    values : sequence of str
        The array's strings.
    width : int, default=92
        The longest line.

    Returns
    -------
    str
        The key and its array of basic strings.
    """
    items = [toml_string(v) for v in values]
    line = f"{key} = [{', '.join(items)}]"
    if len(line) <= width:
        return line
    lines, current = [], "    "
    for item in items:
        if current.strip() and len(current) + len(item) + 1 > width:
            lines.append(current.rstrip())
            current = "    "
        current += item + ", "
    lines.append(current.rstrip())
    return f"{key} = [\n" + "\n".join(lines) + "\n]"


def toml_comment(text: str) -> str:
    """Make ``text`` fit for a TOML comment (no control characters).

    Parameters
    ----------
    text : str
        Any text.

    Returns
    -------
    str
        ``text`` with every unprintable character replaced by ``?``.
    """
    return "".join(ch if ch.isprintable() else "?" for ch in text)


#: A line opening a table (``[name]``, ``[[name]]``), possibly after spaces, with a comment.
_TABLE = re.compile(r"\s*\[\[?[^\[\]]+\]\]?\s*(#.*)?")


def split_template(template: str) -> tuple[str, str]:
    """Split a template into its top-level keys and the rest.

    The first part holds the top-level keys (with the comments among them) and goes above
    ``[data]``, where its keys stay top-level; the rest starts at the first table (with the
    comment lines just above it).

    Parameters
    ----------
    template : str
        The template's text.

    Returns
    -------
    top : str
        The top-level part (``""`` when the template has none).
    rest : str
        The template from its first table on.
    """
    lines = template.splitlines(keepends=True)
    for i, line in enumerate(lines):
        head = "".join(lines[:i])
        if not _TABLE.fullmatch(line.rstrip("\r\n")):
            continue
        try:  # a line like a table inside a multi-line string or array is not one
            keys = tomllib.loads(head)
        except tomllib.TOMLDecodeError:
            continue
        if not keys:
            return "", template
        while i > 0 and lines[i - 1].lstrip().startswith("#"):
            i -= 1
        return "".join(lines[:i]), "".join(lines[i:])
    return template, ""
