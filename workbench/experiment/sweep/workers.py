"""The processes of ``workbench sweep --workers N``.

Each runs the search on the shared storage, as a task on the command's worker processes
(:mod:`workbench.parallel`: forked before the command starts any thread, one BLAS thread and
serial fits each, ended with the command). The one mechanism for every parallel part of a
command.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping

from ...parallel import Task, map_tasks
from ..process.signals import Interrupted, handle_signals
from ..process.startup import setup_logging
from ..storage import open_storage
from .scheduler import open_study

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import ExperimentConfig

__all__ = ["search_in_workers", "sweep_task"]


def sweep_task(search: Callable[..., None], cfg: ExperimentConfig, storage_url: str,
               index: int, show: bool, on_trial: Callable[..., None] | None,
               dataset: Dataset | None = None) -> None:
    """Run one sweep worker in a worker process.

    It calls ``search(cfg, storage_url, progress=show, worker=index, on_trial=on_trial,
    dataset=dataset)``. A SIGTERM (the command ending its workers) or Ctrl-C (it reaches
    the whole process group) fails and queues the running trial, then ends the process:
    the command is ending, and a worker left waiting for its next task would keep it from
    exiting.
    """
    try:
        with handle_signals():
            if show:  # this process's per-trial lines to its standard error
                setup_logging()
            search(cfg, storage_url, progress=show, worker=index, on_trial=on_trial,
                   dataset=dataset)
    except Interrupted as exc:  # the running trial is queued again already
        os._exit(exc.code)


def search_in_workers(search: Callable[..., None], cfg: ExperimentConfig, storage_url: str,
                      workers: int, progress: bool, names: list[str], root: Path,
                      on_trial: Callable[..., None] | None = None,
                      attrs: Mapping[str, Mapping[str, Any]] | None = None,
                      dataset: Dataset | None = None) -> None:
    """Run ``search(cfg, storage_url, progress=, worker=, on_trial=)`` in ``workers`` processes.

    The processes are the enclosing :func:`workbench.parallel.worker_pool`'s, which must
    hold at least ``workers`` (without one, a pool of its own); the studies ``names`` are
    created once before (with their user attributes ``attrs[name]``). An interrupt ends the
    workers (their running trials are queued again); a worker's error is raised here.
    """
    if workers == 1:
        search(cfg, storage_url, progress=progress, on_trial=on_trial, dataset=dataset)
        return
    # Create the storage and studies once, before workers race to do it.
    storage = open_storage(storage_url, root, stale_after_s=cfg.study.stale_after_s)
    for name in names:
        open_study(name, storage, attrs=(attrs or {}).get(name))
    map_tasks([Task(sweep_task, search, cfg, storage_url, i, bool(progress), on_trial, dataset)
               for i in range(workers)], workers)
