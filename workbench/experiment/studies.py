"""Optuna studies in shared storage, and the processes that work on them.

The storage/scheduling half of ``workbench sweep`` (:mod:`workbench.experiment.search` holds
the family-specific objectives): storages, samplers and pruners, the trial scheduler that
leaves every study with exactly its budget of counted trials, and worker processes.

Each trial records its worker and a heartbeat; a running trial whose process is gone (same
host) or whose heartbeat is older than ``stale_after_s`` is marked failed and not counted, and
a trial started beyond the budget is marked ``surplus`` and not run. So every study finishes
exactly ``trials`` counted trials, none lost or repeated.
"""

from __future__ import annotations

import multiprocessing
import os
import socket
import sys
import time
import zlib
from pathlib import Path
from typing import Callable, TextIO

import optuna
from optuna.trial import FrozenTrial, TrialState

__all__ = ["open_storage", "run_studies", "run_study"]

THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def open_storage(storage: str, root: Path):
    """An Optuna storage: an RDB URL as is, else a journal file (relative to ``root``)."""
    if "://" in storage:
        return storage
    path = Path(storage)
    path = path if path.is_absolute() else root / path
    path.parent.mkdir(parents=True, exist_ok=True)
    backend = optuna.storages.journal.JournalFileBackend(str(path))
    return optuna.storages.JournalStorage(backend)




def _sampler(cfg, name: str, worker: int = 0):
    """Seeded per study and per worker (workers with one seed would propose the same
    configurations)."""
    seed = (cfg.cv.seed + zlib.crc32(name.encode()) + 7919 * worker) % 2**31
    if cfg.study.sampler == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    return optuna.samplers.TPESampler(seed=seed)


def _pruner(cfg):
    name = cfg.study.pruner
    if name == "median":  # reported values: running mean of the inner folds' MAE
        return optuna.pruners.MedianPruner(n_startup_trials=3)
    if name == "wilcoxon":  # reported values: each inner fold's MAE
        return optuna.pruners.WilcoxonPruner(p_threshold=0.1)
    return optuna.pruners.NopPruner()




def _counted(t: FrozenTrial) -> bool:
    """Whether a trial uses one of the study's ``trials`` (stale and surplus ones do not)."""
    attrs = t.user_attrs
    if attrs.get("surplus"):
        return False
    if t.state == TrialState.FAIL:
        return "finished_by" in attrs  # failed in the objective, not marked stale by others
    return True


def _fail_stale(study: optuna.Study, stale_after_s: float) -> None:
    host, now = socket.gethostname(), time.time()
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        worker = t.user_attrs.get("worker", "")
        w_host, _, w_pid = worker.rpartition(":")
        dead = w_host == host and w_pid.isdigit() and not _alive(int(w_pid))
        started = t.datetime_start.timestamp() if t.datetime_start else now
        old = now - t.user_attrs.get("heartbeat", started) > stale_after_s
        if dead or old:
            try:
                study.tell(t.number, state=TrialState.FAIL)
            except (RuntimeError, ValueError):  # finished meanwhile
                pass


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _best_value(study: optuna.Study) -> float | None:
    try:
        return study.best_value
    except ValueError:
        return None


def run_study(study: optuna.Study, objective: Callable, n_trials: int, *,
              timeout: float | None = None, stale_after_s: float = 600,
              progress: TextIO | None = None, wait: bool = True) -> None:
    """Run trials until the study holds ``n_trials`` counted trials (or ``timeout`` s pass).

    With ``wait``, return only once no counted trial is still running elsewhere (so the study
    is complete); without, return as soon as the budget is taken."""
    worker = f"{socket.gethostname()}:{os.getpid()}"
    start = time.perf_counter()
    while timeout is None or time.perf_counter() - start < timeout:
        _fail_stale(study, stale_after_s)
        counted = [t for t in study.get_trials(deepcopy=False) if _counted(t)]
        if len(counted) >= n_trials:
            if wait and any(t.state == TrialState.RUNNING for t in counted):
                time.sleep(0.2)  # another worker's last trials: leave the study complete
                continue
            return
        trial = study.ask()
        trial.set_user_attr("worker", worker)
        trial.set_user_attr("heartbeat", time.time())
        earlier = [t for t in study.get_trials(deepcopy=False) if t.number < trial.number]
        if sum(_counted(t) for t in earlier) >= n_trials:  # another worker filled the budget
            trial.set_user_attr("surplus", True)
            study.tell(trial, state=TrialState.FAIL)
            continue
        state, value, note = TrialState.COMPLETE, None, ""
        try:
            value = objective(trial)
        except optuna.TrialPruned as exc:
            state, note = TrialState.PRUNED, str(exc)
        except Exception as exc:  # a failed configuration is recorded, never chosen
            state, note = TrialState.FAIL, f"{type(exc).__name__}: {exc}"
            trial.set_user_attr("error", note[:2000])
        trial.set_user_attr("finished_by", worker)
        study.tell(trial, value if state == TrialState.COMPLETE else None, state=state)
        if progress:
            best = _best_value(study)
            shown = f"MAE {value:.4f}" if value is not None else note[:60]
            print(f"[{study.study_name}] trial {trial.number:>3} {state.name.lower():<8} "
                  f"{shown}  best {best if best is None else round(best, 4)}",
                  file=progress, flush=True)



def run_studies(cfg, studies: list[tuple[optuna.Study, Callable]], *,
                progress: TextIO | None = None) -> None:
    """Run (or resume) ``(study, objective)`` pairs to their budgets in this process."""
    # First pass: take trials wherever budget is left, never idling while another worker
    # finishes a study's last trials; second pass: make sure every study is complete.
    for wait in (False, True):
        for study, objective in studies:
            run_study(study, objective, cfg.study.trials, timeout=cfg.study.timeout,
                      stale_after_s=cfg.study.stale_after_s, progress=progress, wait=wait)


def _worker(search: Callable, cfg, storage_url: str, index: int, show: bool) -> None:
    search(cfg, storage_url, progress=sys.stderr if show else None, worker=index)


def _search_in_workers(search: Callable, cfg, storage_url: str, workers: int,
                       progress: TextIO | None, names: list[str], root: Path) -> None:
    """``search(cfg, storage_url, progress=, worker=)`` (a module-level function: workers are
    spawned) in ``workers`` processes, after creating the studies ``names`` once."""
    if workers == 1:
        search(cfg, storage_url, progress=progress)
        return
    # Create the storage and studies once, before workers race to do it.
    storage = open_storage(storage_url, root)
    for name in names:
        optuna.create_study(study_name=name, storage=storage, direction="minimize",
                            load_if_exists=True)
    saved = {k: os.environ.get(k) for k in THREAD_ENV}
    os.environ.update({k: "1" for k in THREAD_ENV})  # one BLAS/OpenMP thread per worker
    try:
        ctx = multiprocessing.get_context("spawn")
        procs = [ctx.Process(target=_worker, args=(search, cfg, storage_url, i, bool(progress)))
                 for i in range(workers)]
        for p in procs:
            p.start()
        for p in procs:
            p.join()
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    failed = [p.exitcode for p in procs if p.exitcode != 0]
    if failed:
        raise RuntimeError(f"{len(failed)} of {workers} sweep workers exited with codes {failed}")
