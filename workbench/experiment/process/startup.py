"""What a command sets up first: the progress lines of the ``workbench`` logger.

Kept light (no heavy imports) so that any module may use it; the lines go to standard
error.
"""

from __future__ import annotations

import logging
import sys
from typing import TextIO

__all__ = ["setup_logging"]

class _Stderr(logging.StreamHandler):
    """A handler writing to the *current* ``sys.stderr`` (which callers may replace)."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    @property
    def stream(self) -> TextIO:  # type: ignore[override]
        return sys.stderr

    @stream.setter
    def stream(self, value: TextIO) -> None:
        pass


def setup_logging() -> None:
    """Send the ``workbench`` logger's progress lines to standard error (once per process)."""
    logger = logging.getLogger("workbench")
    if not any(isinstance(h, _Stderr) for h in logger.handlers):
        handler = _Stderr()
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logger.propagate = False
    logging.getLogger("mlflow").setLevel(logging.WARNING)  # keep the per-trial lines readable
    # MLflow logs the traceback of a database error (a full disk, a locked file) that it
    # raises again at once: the command reports it in one line naming the store
    logging.getLogger("mlflow.store.db.utils").setLevel(logging.CRITICAL)
    # SQLAlchemy's pool logs (with a traceback) a cursor or connection that could not be
    # closed after its work failed or was interrupted ("Error closing cursor" after a Ctrl-C
    # in an MLflow SQLite read): the failure itself is reported, in one line
    logging.getLogger("sqlalchemy.pool").setLevel(logging.CRITICAL)
