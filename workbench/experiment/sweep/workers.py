"""The processes of ``workbench sweep --workers N``: each runs the search on the shared
storage (:func:`search_in_workers`), started by the fork server where there is one (no fork
of the command's process, which has threads), set up by
:func:`workbench.parallel.init_worker` (serial fits, one BLAS thread, SIGTERM when the
command's process ends, which fails and queues its running trial)."""

from __future__ import annotations

import multiprocessing
import os
import sys
from pathlib import Path
from typing import Callable

import optuna

from ...parallel import one_thread_env
from .storage import open_storage

__all__ = ["search_in_workers", "worker_context"]

#: Exit codes of a process ended by SIGINT / SIGTERM (128 + the signal number).
EXIT_SIGINT, EXIT_SIGTERM = 130, 143


def _worker(search: Callable, cfg, storage_url: str, index: int, show: bool, parent: int,
            on_trial) -> None:
    from ...parallel import init_worker
    from ..signals import handle_signals

    # its fits serial (the sweep's processes are the parallelism), one BLAS thread, and a
    # SIGTERM when the command's process ends (its running trial is failed and queued)
    init_worker(parent, pool=False)
    try:
        with handle_signals():  # Ctrl-C reaches the whole group: the parent reports it
            if show:  # this process's per-trial lines to its standard error
                from ..startup import setup_logging

                setup_logging()
            search(cfg, storage_url, progress=show, worker=index, on_trial=on_trial)
    except KeyboardInterrupt as exc:  # its running trial is failed and queued again
        sys.exit(getattr(exc, "code", EXIT_SIGINT))


def worker_context():
    """The multiprocessing context of sweep workers: the fork server where there is one
    (started early by the command, :func:`workbench.parallel.start_fork_server`, or now),
    else spawn."""
    from ...parallel import start_fork_server
    from ..startup import SWEEP_WORKER_MODULES

    if start_fork_server(SWEEP_WORKER_MODULES):  # a no-op when it runs already
        return multiprocessing.get_context("forkserver")
    return multiprocessing.get_context("spawn")


def search_in_workers(search: Callable, cfg, storage_url: str, workers: int,
                       progress: bool, names: list[str], root: Path,
                       on_trial=None) -> None:
    """``search(cfg, storage_url, progress=, worker=, on_trial=)`` (a module-level function:
    workers come from the fork server, or are spawned) in ``workers`` processes, after
    creating the studies ``names`` once. An interrupt of this process ends the workers
    (their running trials are queued again)."""
    if workers == 1:
        search(cfg, storage_url, progress=progress, on_trial=on_trial)
        return
    # Create the storage and studies once, before workers race to do it.
    storage = open_storage(storage_url, root, stale_after_s=cfg.study.stale_after_s)
    for name in names:
        optuna.create_study(study_name=name, storage=storage, direction="minimize",
                            load_if_exists=True)
    procs = []
    try:
        ctx = worker_context()
        procs = [ctx.Process(target=_worker, args=(search, cfg, storage_url, i, bool(progress),
                                                   os.getpid(), on_trial))
                 for i in range(workers)]
        with one_thread_env():  # one BLAS/OpenMP thread per worker
            for p in procs:
                p.start()
        for p in procs:
            p.join()
    except BaseException:
        for p in procs:  # interrupted: the workers fail and queue their trials, then exit
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join(timeout=30)
            if p.is_alive():
                p.kill()
        raise
    failed = [p.exitcode for p in procs if p.exitcode != 0]
    if failed:
        raise RuntimeError(f"{len(failed)} of {workers} sweep workers exited with codes {failed}")


