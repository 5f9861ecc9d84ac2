"""Checks every command makes before any work.

Its outputs can be written, the MLflow store and the Optuna storage can be used (a damaged
journal repaired first with ``--repair``); nothing is written until every check has passed.
"""

from __future__ import annotations

import argparse
import logging
import shlex
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import urlsplit

from ..process.errors import UsageError

if TYPE_CHECKING:
    from ..config import ExperimentConfig
    from ..tracking.runs import Tracker

__all__ = ["check_before_work", "check_outputs", "check_storage", "check_stores",
           "repair_hint"]

log = logging.getLogger("workbench")


def check_outputs(args: argparse.Namespace) -> None:
    """Check that every output can be written before anything is loaded or fitted.

    Every output location (``--json``, ``--out``) must be writable, and ``--register`` needs
    a store to register in.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Raises
    ------
    UsageError
        For ``--register`` without a store, or a name a registry refuses.
    OutputError
        For an output location that cannot be written.
    """
    from ..process.outputs import check_dir, check_file

    name = getattr(args, "register", None)
    if name is not None:
        if args.no_track:
            raise UsageError("--register needs the tracking store; drop --no-track")
        if not name.strip() or name != name.strip() or any(c in name for c in "/:@") \
                or name in (".", ".."):
            raise UsageError(f"--register {name!r}: a registered model's name cannot be "
                             "empty, start or end with a space, or contain '/', ':' or '@'")
    if args.json:
        check_file(args.json, "--json")
    if getattr(args, "out", None) is not None:
        check_dir(args.out, "--out")


def check_before_work(cfg: ExperimentConfig, args: argparse.Namespace,
                      storage: str | None = None, hint: str | None = None) -> Tracker | None:
    """Check the stores of a command that runs a config: its MLflow store, and ``storage``.

    The data are checked by loading them once (:func:`~workbench.experiment.runs.prepare.prepare`)
    before this is called.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config (its ``[tracking]``).
    args : argparse.Namespace
        The command's arguments (``--no-track``, ``--tracking-uri``, ``--repair``).
    storage : str, optional
        The Optuna storage the command will use.
    hint : str, optional
        The command line that repairs a damaged journal (:func:`repair_hint`).

    Returns
    -------
    Tracker or None
        The run's tracker (``None`` with ``--no-track``), its store created.
    """
    tracker = None
    if not args.no_track:
        from ..runs.record import tracker_for

        tracker = tracker_for(cfg, args.tracking_uri)
    return check_stores(tracker, storage, getattr(args, "repair", False), hint)


def check_stores(tracker: Tracker | None, storage: str | None, repair: bool,
                 hint: str | None) -> Tracker | None:
    """Check the MLflow store of ``tracker`` and the Optuna ``storage``, then create the store.

    The checks write nothing (but a ``repair``); the tracking store is created once both
    passed.

    Parameters
    ----------
    tracker : Tracker or None
        The run's tracker (``None``: no tracking).
    storage : str or None
        The Optuna storage (``None``: none).
    repair : bool
        Whether to repair a damaged journal file first (the one write of the checks).
    hint : str or None
        The command line that repairs a damaged journal.

    Returns
    -------
    Tracker or None
        ``tracker``.
    """
    if tracker is not None:
        from ..tracking.uris import check_store_uri

        check_store_uri(tracker.tracking_uri)  # writes nothing
    if storage is not None:
        check_storage(storage, repair, hint)
    if tracker is not None:
        from ..tracking.lifecycle import prepare_store

        prepare_store(tracker)  # one process at a time creates a new store
    return tracker


def check_storage(storage: str, repair: bool, hint: str | None) -> None:
    """Check that the Optuna storage can be used (nothing written).

    Parameters
    ----------
    storage : str
        A journal file path or an RDB URL.
    repair : bool
        Whether a damaged journal file is repaired first (the one write of the checks).
    hint : str or None
        The command line that repairs a damaged journal.
    """
    from ..storage import check_storage as check
    from ..storage import repair_journal

    if repair:
        done = repair_journal(storage, Path.cwd())
        log.info("%s", done if done is not None else
                 f"Optuna journal {storage} is not damaged: nothing to repair")
    check(storage, Path.cwd(), hint=hint)


def _hidden(word: str) -> str:
    """Return a command-line word, a URL with a password replaced."""
    try:
        if "://" in word and urlsplit(word).password:
            return "URI-WITH-PASSWORD"
    except ValueError:
        return "URI"
    return word


def repair_hint(args: argparse.Namespace) -> str:
    """Return what repairs a damaged journal: this command line with ``--repair``.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments (``args.argv``: the words it was given).

    Returns
    -------
    str
        The command line, passwords hidden.
    """
    return shlex.join(["workbench", *map(_hidden, args.argv), "--repair"])
