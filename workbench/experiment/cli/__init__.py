"""The ``workbench`` command: a thin shell over functions the tests call directly.

One module per concern: :mod:`.parser` (the command line), :mod:`.argtypes` (its value
types), :mod:`.preflight` (every check before work starts), :mod:`.commands` (one handler
per command) and :mod:`.ui` (the servers of ``workbench ui``). Each command imports what it
needs when it runs: ``workbench --help`` and ``workbench simulate`` never load MLflow,
Optuna or SHAP (nor, for ``--help``, scikit-learn). Progress and messages go through
:mod:`logging` (logger ``workbench``, to standard error).

May import: process, config, splits, scoring, figures, families, tracking, storage, runs,
sweep, paper (it is the top).
"""

from __future__ import annotations

import sys

from ..process.errors import (
    ConfigError,
    StorageError,
    SweepTimedOut,
    TrackingError,
    UsageError,
    clip,
    disk_full,
    redact_urls,
)
from ..process.startup import setup_logging
from . import commands
from .parser import build_parser

__all__ = ["MAX_ERROR_LINE", "error_line", "main"]

#: Most characters of the error line ``workbench: error: ...``.
MAX_ERROR_LINE = 299


def main(argv: list[str] | None = None) -> int:
    """Run the ``workbench`` command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: the process's, ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code: 0, 2 for an error reported in one line (a full disk included),
        124 for a sweep stopped by its timeout, 130/143 when interrupted.
    """
    commands.mark_start()
    args = build_parser().parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    setup_logging()
    from ...datasets import DatasetError, DataUnavailableError
    from ..process.signals import MESSAGE, handle_signals

    try:
        with handle_signals():  # SIGINT/SIGTERM: runs end KILLED, one line, exit 130/143
            code: int = args.func(args)
            return code
    except DataUnavailableError as exc:  # the benchmark's manual download steps, as written
        print(f"workbench: error: {exc}", file=sys.stderr)
        return 2
    except (ConfigError, DatasetError, TrackingError, UsageError, StorageError) as exc:
        print(error_line(exc), file=sys.stderr)
        return 2
    except SweepTimedOut as exc:  # resumable: one line saying how
        print(f"workbench: {exc}", file=sys.stderr)
        return exc.code
    except Exception as exc:  # a full disk anywhere (the cases known are one line already)
        where = disk_full(exc)
        if where is None:
            raise
        print(error_line(f"no space left on the device{f' writing {where}' if where else ''}"
                         "; free space, then run the command again"), file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"workbench: {MESSAGE}", file=sys.stderr)
        return getattr(exc, "code", 130)


def error_line(exc: BaseException | str) -> str:
    """One line ``workbench: error: <message>``, passwords redacted.

    Messages are written short; this is the last guard.

    Parameters
    ----------
    exc : BaseException or str
        The error, or its message.

    Returns
    -------
    str
        The line, at most :data:`MAX_ERROR_LINE` characters.
    """
    text = redact_urls(" ".join(str(exc).split()))
    line = f"workbench: error: {text}"
    return clip(line, MAX_ERROR_LINE)
