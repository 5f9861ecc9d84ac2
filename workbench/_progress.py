"""The progress lines of the core's estimators (their ``verbose``), through :mod:`logging`.

A fit with ``verbose=True`` reports each phase and step as an INFO record of its module's
logger (``workbench.<module>``, below the ``workbench`` logger whose lines the commands print
to standard error). Where the program has set up no logging at all (no handler on that logger
or above it), the line is printed to standard error instead, as scikit-learn's ``verbose``
prints: ``verbose=True`` is never silent, ``verbose=False`` always is. Reporting changes no
number.
"""

from __future__ import annotations

import logging
import sys
import time

__all__ = ["Progress"]


class Progress:
    """Report a fit's progress lines, or nothing.

    Parameters
    ----------
    logger : str
        The logger's name (the reporting module's ``__name__``).
    enabled : bool
        Whether lines are reported (the estimator's ``verbose``); false: every call does
        nothing.
    prefix : str, default=""
        Put before every line, e.g. ``"parametric: "``.

    Examples
    --------
    >>> say = Progress("workbench.example", enabled=False)
    >>> bool(say), say("nothing is reported")
    (False, None)
    """

    def __init__(self, logger: str, enabled: bool, prefix: str = "") -> None:
        self.logger = logger
        self.enabled = bool(enabled)
        self.prefix = prefix
        self.t0 = time.perf_counter()

    def __bool__(self) -> bool:
        return self.enabled

    def __call__(self, line: str) -> None:
        """Report ``line`` (after the prefix) if enabled."""
        if not self.enabled:
            return
        log = logging.getLogger(self.logger)
        if log.hasHandlers():
            log.info("%s%s", self.prefix, line)
        else:  # no logging set up: print, as scikit-learn's verbose does
            print(f"{self.prefix}{line}", file=sys.stderr, flush=True)

    def child(self, prefix: str) -> Progress:
        """The same reporter (its clock too) with ``prefix`` added to its own."""
        out = Progress(self.logger, self.enabled, self.prefix + prefix)
        out.t0 = self.t0
        return out

    def elapsed(self) -> str:
        """The seconds since this reporter was made, e.g. ``"12 s"``."""
        return f"{time.perf_counter() - self.t0:.0f} s"
