"""The processes of ``workbench sweep --workers N``: each runs the search on the shared
storage, as a task on the command's worker processes (:mod:`workbench.parallel`: forked
before the command starts any thread, one BLAS thread and serial fits each, ended with the
command). The one mechanism for every parallel part of a command."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Mapping

from ...parallel import Task, map_tasks
from ..signals import handle_signals
from ..startup import setup_logging
from .scheduler import open_study
from .storage import open_storage

__all__ = ["search_in_workers", "sweep_task"]


def sweep_task(search: Callable, cfg, storage_url: str, index: int, show: bool,
               on_trial, dataset=None) -> None:
    """One sweep worker: ``search(cfg, storage_url, progress=show, worker=index,
    on_trial=on_trial)`` in a worker process. A SIGTERM (the command ending its workers) or
    Ctrl-C (it reaches the whole process group) fails and queues the running trial, then
    ends the task."""
    with handle_signals():
        if show:  # this process's per-trial lines to its standard error
            setup_logging()
        search(cfg, storage_url, progress=show, worker=index, on_trial=on_trial,
               dataset=dataset)


def search_in_workers(search: Callable, cfg, storage_url: str, workers: int,
                      progress: bool, names: list[str], root: Path,
                      on_trial=None, attrs: Mapping[str, Mapping[str, Any]] | None = None,
                      dataset=None) -> None:
    """``search(cfg, storage_url, progress=, worker=, on_trial=)`` in ``workers`` worker
    processes (the enclosing :func:`workbench.parallel.worker_pool`'s, which must hold at
    least ``workers``; without one, a pool of its own), after creating the studies
    ``names`` once (with their user attributes ``attrs[name]``). An interrupt ends the
    workers (their running trials are queued again); a worker's error is raised here."""
    if workers == 1:
        search(cfg, storage_url, progress=progress, on_trial=on_trial, dataset=dataset)
        return
    # Create the storage and studies once, before workers race to do it.
    storage = open_storage(storage_url, root, stale_after_s=cfg.study.stale_after_s)
    for name in names:
        open_study(name, storage, attrs=(attrs or {}).get(name))
    map_tasks([Task(sweep_task, search, cfg, storage_url, i, bool(progress), on_trial, dataset)
               for i in range(workers)], workers)
