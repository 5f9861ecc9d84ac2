"""Signals of a command: SIGINT and SIGTERM end it cleanly.

* :func:`handle_signals`: they raise :class:`Interrupted` (a ``KeyboardInterrupt``) in the
  main thread, so the command unwinds, ends its runs ``KILLED`` and exits 130 / 143 with the
  one line :data:`MESSAGE` (no traceback). Where Python would swallow it (raised inside a
  finalizer, or in another thread) it is delivered to the main thread again.
* :func:`interrupts_deferred`: bookkeeping that must not stop half-way (a trial being asked
  or told, an append to the Optuna journal under its lock, a new store's migration) gets
  the signal as it ends.
* :func:`ignoring_signals`: a run's end is written even if a second Ctrl-C arrives.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any

__all__ = ["Interrupted", "MESSAGE", "handle_signals", "ignoring_signals",
           "interrupts_deferred"]

MESSAGE = "interrupted; run the same command to resume"


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM received by the command.

    Parameters
    ----------
    signum : int
        The signal's number.

    Attributes
    ----------
    code : int
        The command's exit code, 128 + the signal's number.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.code = 128 + signum


_DEFERRING = [0]  # depth of the main thread's enclosing ``interrupts_deferred`` blocks
_PENDING: list[int] = []  # a signal that arrived inside them


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Defer a SIGINT or SIGTERM that arrives inside the block until the outermost block is left.

    Under :func:`handle_signals`. For bookkeeping that must not stop half-way: a trial asked
    from the storage but not yet running, or run but not yet told; an append to the Optuna
    journal under its file lock; a new store's migration. In other threads the block does
    nothing (signals interrupt the main thread only).

    Yields
    ------
    None
        While the block runs.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _DEFERRING[0] += 1
    try:
        yield
    finally:
        _DEFERRING[0] -= 1
    if _DEFERRING[0] == 0 and _PENDING:  # the block completed: the signal now
        raise Interrupted(_PENDING.pop())


@contextlib.contextmanager
def handle_signals() -> Iterator[None]:
    """Make SIGINT and SIGTERM raise :class:`Interrupted` in the main thread.

    Once: further signals are ignored while the command cleans up; inside
    :func:`interrupts_deferred`, when that block is left. Any other code (e.g. MLflow's
    requests and their retries, a database call) is interrupted where it is: its stores roll
    back what was not committed.

    Python runs the handler wherever the main thread is, also inside a finalizer
    (``__del__``, a weakref callback: matplotlib and SHAP run many while drawing), where the
    exception is printed and dropped (``sys.unraisablehook``) and the command would go on
    to exit 0. An :class:`Interrupted` dropped there, or ending another thread
    (``threading.excepthook``), is delivered to the main thread again, silently.

    Yields
    ------
    None
        While the block runs; the previous handlers are restored after it.
    """
    fired: list[int] = []

    def handler(signum: int, frame: FrameType | None) -> None:
        if fired:
            return
        if _DEFERRING[0]:
            _PENDING.append(signum)
            fired.append(signum)
            return
        fired.append(signum)
        raise Interrupted(signum)

    def redeliver(exc: BaseException | None) -> bool:
        if not isinstance(exc, Interrupted):
            return False
        fired.clear()  # the main thread has not seen it: let the handler raise it again
        # a real signal (it wakes a main thread blocked waiting), from another thread once
        # this hook has returned (raised inside the hook, it would be dropped again); raised
        # in a finalizer again, it comes back here
        timer = threading.Timer(0.01, signal.pthread_kill,
                                (threading.main_thread().ident, exc.code - 128))
        timer.daemon = True
        timer.start()
        return True

    def unraisable(info: Any) -> None:
        try:
            if not redeliver(info.exc_value):
                old_unraisable(info)
        except Interrupted as exc:  # the timer's, while still in the hook
            redeliver(exc)

    def thread_ended(args: Any) -> None:
        if not redeliver(args.exc_value):
            old_excepthook(args)

    signals = (signal.SIGINT, signal.SIGTERM)
    old = {s: signal.signal(s, handler) for s in signals}
    old_unraisable, old_excepthook = sys.unraisablehook, threading.excepthook
    sys.unraisablehook, threading.excepthook = unraisable, thread_ended
    try:
        yield
    finally:
        _PENDING.clear()
        sys.unraisablehook, threading.excepthook = old_unraisable, old_excepthook
        for s, h in old.items():
            signal.signal(s, h)


@contextlib.contextmanager
def ignoring_signals() -> Iterator[None]:
    """Ignore SIGINT and SIGTERM while the block runs, so that a run's end is written.

    Even if a second Ctrl-C arrives. In other threads the block does nothing.

    Yields
    ------
    None
        While the block runs.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
