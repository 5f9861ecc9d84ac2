"""What a run's records are made of: the code's commit, a data set's hash, params and tags.

Params and tags are cut to MLflow's limits.
"""

from __future__ import annotations

import hashlib
import logging
import subprocess
import time
from pathlib import Path
from typing import Any

import pandas as pd

from ..._text import clip

__all__ = ["MAX_PARAM_LENGTH", "dataset_hash", "git_commit", "now_ms", "param_value",
           "tag_value"]

_logger = logging.getLogger("workbench.experiment.tracking")

#: MLflow's limit on a param value (``mlflow.utils.validation.MAX_PARAM_VAL_LENGTH``).
MAX_PARAM_LENGTH = 6000
_MAX_TAG_LENGTH = 8000


def git_commit(root: Path) -> str | None:
    """Return the commit checked out in ``root`` (``git rev-parse HEAD``).

    Parameters
    ----------
    root : Path
        A directory of the repository.

    Returns
    -------
    str or None
        The 40-digit hash; ``None`` outside a repository or without git.
    """
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=str(root), capture_output=True,
                             text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    sha = out.stdout.strip()
    if out.returncode != 0 or len(sha) != 40 or any(c not in "0123456789abcdef" for c in sha):
        return None
    return sha


def dataset_hash(*frames: pd.DataFrame | pd.Series) -> str:
    """Hash the values, index, column names and dtypes of each frame (SHA-256).

    Stable across processes: ``pandas.util.hash_pandas_object`` uses a fixed key.

    Parameters
    ----------
    *frames : DataFrame or Series
        The data.

    Returns
    -------
    str
        The hex digest.
    """
    h = hashlib.sha256()
    for i, frame in enumerate(frames):
        h.update(f"frame{i}:{type(frame).__name__}:{frame.shape}\n".encode())
        if isinstance(frame, pd.DataFrame):
            h.update(repr([(str(c), str(t)) for c, t in frame.dtypes.items()]).encode())
        else:
            h.update(repr((str(frame.name), str(frame.dtype))).encode())
        h.update(pd.util.hash_pandas_object(frame, index=True).to_numpy().tobytes())
    return h.hexdigest()


def now_ms() -> int:
    """Return the time now in milliseconds since the epoch, as MLflow records times.

    Returns
    -------
    int
        Milliseconds.
    """
    return int(time.time() * 1000)


def param_value(key: str, value: Any) -> tuple[str, bool]:
    """Render a param's value as text within MLflow's limit.

    Parameters
    ----------
    key : str
        The param's name, for the warning.
    value : object
        Its value.

    Returns
    -------
    text : str
        The value as text, cut to :data:`MAX_PARAM_LENGTH` with a note of its length.
    truncated : bool
        Whether it was cut (a warning is logged then).
    """
    text = str(value)
    if len(text) <= MAX_PARAM_LENGTH:
        return text, False
    note = f"...[truncated, {len(text)} chars]"
    _logger.warning("param %r is %d characters long; truncated to MLflow's limit of %d",
                    key, len(text), MAX_PARAM_LENGTH)
    return text[:MAX_PARAM_LENGTH - len(note)] + note, True


def tag_value(value: Any) -> str:
    """Render a tag's value as text within MLflow's limit.

    Parameters
    ----------
    value : object
        The tag's value.

    Returns
    -------
    str
        The value as text, cut to 8,000 characters (``...`` marking the cut).
    """
    text = str(value)
    return clip(text, _MAX_TAG_LENGTH)
