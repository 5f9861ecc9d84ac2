"""Output locations the commands write: checked before any work, written all or nothing.

* :func:`check_file` / :func:`check_dir`: before anything is fitted, a location that cannot be
  written (a directory given as a file, a file given as a directory, a path under a file, a
  read-only directory) ends the command with one line (:class:`OutputError`, exit code 2).
  The check writes and removes a probe file in the nearest existing directory, so it sees
  what the write will see (read-only file systems, permissions, immutable directories).
* :func:`write_file`: :func:`workbench._io.atomic_write` with a one-line error: a failed write
  (a full disk included) leaves the old file, or none, and no temporary file.
* :func:`write_artifacts`: a family's tables and figures written into a hidden staging
  directory inside the target, then renamed into place, so a failure leaves none of them.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Protocol

from ..._io import atomic_write
from .errors import UsageError

__all__ = ["OutputError", "check_dir", "check_file", "write_artifacts", "write_file"]


class _Writable(Protocol):
    """What :func:`write_artifacts` writes: a family's ``Artifacts`` (tables and figures)."""

    def write(self, directory: Path) -> dict[str, Any]: ...


class OutputError(UsageError):
    """An output location that cannot be written."""


def _why(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


def _existing_ancestor(path: Path) -> Path:
    """Return the nearest ancestor of ``path`` (or ``path``) that exists (as anything)."""
    path = Path(os.path.abspath(path))
    while not os.path.lexists(path):
        path = path.parent
    return path


def _check_writable_dir(directory: Path, flag: str, target: str | os.PathLike) -> None:
    """Check that ``directory`` accepts a new file.

    Or its nearest existing ancestor, where the missing directories will be created.
    """
    existing = _existing_ancestor(directory)
    if not existing.is_dir():
        raise OutputError(f"{flag} {target}: {existing} is a file, not a directory")
    try:
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".workbench-probe-")
    except OSError as exc:
        raise OutputError(f"{flag} {target}: cannot write in {existing}: {_why(exc)}") from None
    os.close(fd)
    os.unlink(probe)


def check_file(path: str | os.PathLike, flag: str) -> Path:
    """Check that ``path`` can be written as a file.

    Parameters
    ----------
    path : str or path-like
        The output file.
    flag : str
        The option that gave it, named in the message.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputError
        A directory, a path under a file, or a directory that cannot be written.
    """
    p = Path(path)
    if str(path).endswith(os.sep) or p.is_dir():
        raise OutputError(f"{flag} {path}: is a directory; give a file name")
    _check_writable_dir(p.parent, flag, path)
    return p


def check_dir(path: str | os.PathLike, flag: str) -> Path:
    """Check that ``path`` is, or can be created as, a writable directory.

    Parameters
    ----------
    path : str or path-like
        The output directory.
    flag : str
        The option that gave it, named in the message.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputError
        A file, or a directory that cannot be written.
    """
    p = Path(path)
    if os.path.lexists(p) and not p.is_dir():
        raise OutputError(f"{flag} {path}: is a file; give a directory")
    _check_writable_dir(p, flag, path)
    return p


def write_file(path: str | os.PathLike, data: str | bytes, flag: str) -> Path:
    """Write ``data`` to ``path`` all or nothing.

    Parameters
    ----------
    path : str or path-like
        The file.
    data : str or bytes
        Its content.
    flag : str
        The option that gave the path, named in the message.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    OutputError
        One line, when the write fails (the old file, or none, is left).
    """
    try:
        return atomic_write(path, data)
    except OSError as exc:
        raise OutputError(f"{flag} {path}: cannot write: {_why(exc)}") from None


def write_artifacts(artifacts: _Writable, directory: str | os.PathLike, flag: str = "--out"
                    ) -> dict[str, Path]:
    """Write a family's tables and figures into ``directory``, all or nothing.

    Everything is written into a staging directory inside ``directory`` first and renamed
    into place once complete.

    Parameters
    ----------
    artifacts : Artifacts
        A family's outputs (:class:`~.families.base.Artifacts`).
    directory : str or path-like
        Where they go (created if missing).
    flag : str, default="--out"
        The option that gave the directory, named in the message.

    Returns
    -------
    dict of str to Path
        Name -> path written.

    Raises
    ------
    OutputError
        One line, when a write fails; none of the files is left then.
    """
    directory = Path(directory)
    created = [p for p in (directory, *directory.parents) if not os.path.lexists(p)]
    stage = None
    try:
        directory.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(dir=directory, prefix=".workbench-out-"))
        staged = artifacts.write(stage)
        for path in sorted(stage.iterdir()):  # every file (a table and a figure may share a name)
            os.replace(path, directory / path.name)
        return {name: directory / Path(path).name for name, path in staged.items()}
    except OSError as exc:
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        for p in created:  # the directories this call made, innermost first, if empty
            try:
                p.rmdir()
            except OSError:
                break
        raise OutputError(f"{flag} {directory}: cannot write: {_why(exc)}") from None
    finally:
        if stage is not None and stage.exists():
            shutil.rmtree(stage, ignore_errors=True)
