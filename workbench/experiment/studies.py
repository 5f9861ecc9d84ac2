"""Optuna studies in shared storage, and the processes that work on them.

The storage/scheduling half of ``workbench sweep`` (:mod:`workbench.experiment.search` holds
the family-specific objectives): storages, samplers and pruners, the trial scheduler that
leaves every study with exactly its budget of counted trials, and worker processes.

Several processes (or machines) may work on one storage at once:

* **Distinct proposals.** Each process claims a *stream* number on the study (the first
  process 0, so a lone sweep draws the same numbers as before) and seeds its sampler with it;
  TPE runs with ``constant_liar`` so running trials repel proposals.
* **Exact budgets.** A trial started beyond the budget is marked ``surplus`` and not run; a
  trial counts unless it is surplus or failed by someone other than its own worker.
* **Dead workers.** While a trial runs, a background thread beats its heartbeat (so a long
  inner fold never looks dead). RDB storages use Optuna's own heartbeat
  (``RDBStorage(heartbeat_interval, grace_period, heartbeat_stale_trial_callback)`` and
  :func:`optuna.storages.fail_stale_trials`); Optuna 5's ``JournalStorage`` has no heartbeat
  (it does not implement ``BaseHeartbeat``), so for the journal file the heartbeat is a user
  attribute checked here. A trial whose heartbeat is older than the grace period
  (``stale_after_s``), or whose worker process on this host is gone (checked at once, no
  wait), is failed, not counted, and re-run once with the same parameters through Optuna's
  ``RetryFailedTrialCallback``.
* **Workers die with their parent**: each watches its parent process.
"""

from __future__ import annotations

import copy
import logging
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
import warnings
import zlib
from pathlib import Path
from typing import Callable

import optuna
from optuna.exceptions import ExperimentalWarning, UpdateFinishedTrialError
from optuna.trial import FrozenTrial, TrialState

from ..parallel import one_thread_env
from .errors import redact
from .lifecycle import every, interrupts_deferred

log = logging.getLogger("workbench")

__all__ = ["StorageError", "open_storage", "run_studies", "run_study"]

#: User attributes that belong to one attempt at a trial, not to its configuration.
_ATTEMPT_ATTRS = ("worker", "heartbeat", "finished_by", "error", "surplus", "stale")
#: Exit codes of a process ended by SIGINT / SIGTERM (128 + the signal number).
EXIT_SIGINT, EXIT_SIGTERM = 130, 143


class StorageError(ValueError):
    """The Optuna storage cannot be used (bad path, missing driver, unreachable server)."""


def heartbeat_interval(stale_after_s: float) -> int:
    """Seconds between heartbeats: a quarter of the grace period, 1 to 10 s."""
    return int(max(1, min(10, stale_after_s // 4)))


class _Retry(optuna.storages.RetryFailedTrialCallback):
    """Optuna's retry of a failed trial (same parameters, ``retry_history`` in its system
    attributes), without the dead attempt's own user attributes: its ``worker`` (host:pid of
    a dead process) would get the retry failed again the moment another process looks."""

    def __call__(self, study: optuna.Study, trial: FrozenTrial) -> None:
        trial = copy.deepcopy(trial)
        trial.user_attrs = {k: v for k, v in trial.user_attrs.items()
                            if k not in _ATTEMPT_ATTRS}
        super().__call__(study, trial)


def _retry() -> _Retry:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # experimental / renamed in 4.9: same behaviour
        return _Retry(max_retry=1)


class _JournalFile(optuna.storages.journal.JournalFileBackend):
    """Optuna's journal file, flushed to disk (fsync) only when the appended operations
    create or delete a study, create a trial or set a trial's state, instead of after every
    append (a trial's parameters, reports, heartbeats and attributes: ~20 fsyncs of ~3.5 ms
    per trial here, an eighth of a small sweep). Every append is still written under the
    file lock before it returns, so other processes (and machines sharing the file, whose
    NFS flushes at close) see it at once; only an operating-system crash or power loss can
    lose the unsynced operations of the running trials, which a resumed sweep runs again."""

    def append_logs(self, logs: list[dict]) -> None:
        import json

        from optuna.storages.journal._file import get_lock_file
        from optuna.storages.journal._storage import JournalOperation as Op

        synced = (Op.CREATE_STUDY, Op.DELETE_STUDY, Op.CREATE_TRIAL,
                  Op.SET_TRIAL_STATE_VALUES, Op.DISCARD_TRIALS)
        sync = any(log.get("op_code") in synced for log in logs)
        with get_lock_file(self._lock):
            text = "\n".join(json.dumps(log, separators=(",", ":")) for log in logs) + "\n"
            with open(self._file_path, "ab") as f:
                f.write(text.encode("utf-8"))
                f.flush()
                if sync:
                    os.fsync(f.fileno())


def open_storage(storage: str, root: Path, *, stale_after_s: float = 600):
    """An Optuna storage: an RDB URL (with Optuna's heartbeat, grace period ``stale_after_s``
    and one retry of a stale trial), else a journal file (relative to ``root``). Problems end
    in a :class:`StorageError` of one line (without the URL's password)."""
    if "://" in storage:
        return _rdb_storage(storage, stale_after_s)
    path = Path(storage)
    path = path if path.is_absolute() else root / path
    if path.is_dir():
        raise StorageError(f"Optuna storage {path} is a directory; give a journal file path "
                           "(e.g. mlruns/optuna.journal) or a database URL")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        backend = _JournalFile(str(path))
    except OSError as exc:
        raise StorageError(f"cannot use Optuna journal file {path}: {exc}") from None
    return optuna.storages.JournalStorage(backend)


def _rdb_storage(url: str, stale_after_s: float):
    import sqlalchemy.exc

    shown = redact(url)
    kwargs = {}
    if url.startswith("postgresql"):  # an unreachable host fails in seconds, not minutes
        kwargs["connect_args"] = {"connect_timeout": 10}
    if url.startswith("sqlite:///"):
        db = Path(url[len("sqlite:///"):])
        if db.is_dir():
            raise StorageError(f"Optuna storage {shown} is a directory, not a database file")
        db.parent.mkdir(parents=True, exist_ok=True)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExperimentalWarning)  # heartbeat_interval
            return optuna.storages.RDBStorage(
                url, engine_kwargs=kwargs or None,
                heartbeat_interval=heartbeat_interval(stale_after_s),
                grace_period=max(1, int(stale_after_s)),
                heartbeat_stale_trial_callback=_retry())
    except ImportError as exc:  # missing driver (psycopg2, pymysql, ...)
        raise StorageError(f"Optuna storage {shown}: its database driver is not installed "
                           f"({exc}); install it, e.g. pip install psycopg2-binary") from None
    except sqlalchemy.exc.NoSuchModuleError as exc:
        raise StorageError(f"Optuna storage {shown}: unknown database kind ({exc})") from None
    except sqlalchemy.exc.ArgumentError as exc:
        raise StorageError(f"Optuna storage {shown} is not a valid database URL "
                           f"({exc})") from None
    except sqlalchemy.exc.OperationalError as exc:
        reason = str(getattr(exc, "orig", exc)).strip().splitlines()
        raise StorageError(f"cannot connect to Optuna storage {shown}: "
                           f"{reason[0] if reason else type(exc).__name__}") from None


def _heartbeat_enabled(storage) -> bool:
    return isinstance(storage, optuna.storages.RDBStorage) \
        and storage.get_heartbeat_interval() is not None


def _sampler(cfg, name: str, worker: int = 0):
    """Seeded per study and per stream (processes with one seed would propose the same
    configurations); stream 0 is the first process of a sweep."""
    seed = (cfg.cv.seed + zlib.crc32(name.encode()) + 7919 * worker) % 2**31
    if cfg.study.sampler == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    return optuna.samplers.TPESampler(seed=seed, constant_liar=True)


STREAMS = ".streams"


def claim_stream(study: optuna.Study) -> int:
    """A stream number no other process on this study holds: the number of a trial in the
    study ``<name>.streams`` (trial numbers are assigned atomically by every storage, so the
    first process gets 0 and concurrent ones never share a number)."""
    streams = optuna.create_study(study_name=study.study_name + STREAMS,
                                  storage=study._storage, load_if_exists=True,
                                  sampler=optuna.samplers.RandomSampler(seed=0))
    claim = streams.ask()
    streams.tell(claim, 0.0, skip_if_finished=True)  # holds nothing: the number is the claim
    return claim.number


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
    if t.state == TrialState.FAIL:  # failed in the objective, not failed as stale by others
        return "finished_by" in attrs and not attrs.get("stale")
    return True


def _fail_and_retry(study: optuna.Study, number: int) -> None:
    """Fail a running trial that no process works on, then queue it once more (only the
    process whose FAIL lands first queues it: the storage refuses the others'). The trial is
    marked ``stale`` first, so it is not counted even when its process died after setting
    ``finished_by`` and before its own ``tell``."""
    try:
        storage = study._storage
        trial_id = storage.get_trial_id_from_study_id_trial_number(study._study_id, number)
        storage.set_trial_user_attr(trial_id, "stale", True)
        study.tell(number, state=TrialState.FAIL)
    except (RuntimeError, ValueError, UpdateFinishedTrialError):  # finished meanwhile
        return
    _retry()(study, study.get_trials(deepcopy=False)[number])


def _fail_stale(study: optuna.Study, stale_after_s: float) -> None:
    """Fail (and queue once more) running trials whose worker is gone: at once when it was a
    process on this host; after ``stale_after_s`` without a heartbeat otherwise (RDB: by
    Optuna's heartbeat; journal: by the ``heartbeat`` user attribute)."""
    if _heartbeat_enabled(study._storage):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExperimentalWarning)
            optuna.storages.fail_stale_trials(study)
    host, now = socket.gethostname(), time.time()
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        worker = t.user_attrs.get("worker", "")
        w_host, _, w_pid = worker.rpartition(":")
        dead = w_host == host and w_pid.isdigit() and not _alive(int(w_pid))
        started = t.datetime_start.timestamp() if t.datetime_start else now
        old = (not _heartbeat_enabled(study._storage)
               and now - t.user_attrs.get("heartbeat", started) > stale_after_s)
        if dead or old:
            _fail_and_retry(study, t.number)


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


def _beat(study: optuna.Study, trial: optuna.Trial) -> None:
    """One heartbeat of a running trial: Optuna's own on an RDB storage, a user attribute on
    the journal file (which has none)."""
    if _heartbeat_enabled(study._storage):
        study._storage.record_heartbeat(trial._trial_id)
    else:
        trial.set_user_attr("heartbeat", time.time())


def _start_trial(study: optuna.Study, worker: str) -> optuna.Trial:
    with warnings.catch_warnings():  # "heartbeat ... supposed to be used with optimize":
        warnings.simplefilter("ignore", UserWarning)  # run_study beats it (see _beat)
        trial = study.ask()
    trial.set_user_attr("worker", worker)
    trial.set_user_attr("heartbeat", time.time())
    if _heartbeat_enabled(study._storage):
        study._storage.record_heartbeat(trial._trial_id)
    return trial


def run_study(study: optuna.Study, objective: Callable, n_trials: int, *,
              timeout: float | None = None, stale_after_s: float = 600,
              progress: bool = False, wait: bool = True,
              on_trial: Callable[[optuna.Study, FrozenTrial], None] | None = None) -> None:
    """Run trials until the study holds ``n_trials`` counted trials (or ``timeout`` s pass).

    With ``wait``, return only once no counted trial is still running elsewhere (so the study
    is complete); without, return as soon as the budget is taken. ``on_trial(study, trial)``
    is called after each trial this process finishes (e.g. to log it). An interrupt
    (``KeyboardInterrupt``, SIGTERM raised as one) fails the running trial, queues it to be
    re-run, and propagates."""
    worker = f"{socket.gethostname()}:{os.getpid()}"
    beat = heartbeat_interval(stale_after_s)
    start = time.perf_counter()
    while timeout is None or time.perf_counter() - start < timeout:
        _fail_stale(study, stale_after_s)
        counted = [t for t in study.get_trials(deepcopy=False) if _counted(t)]
        queued = any(t.state == TrialState.WAITING for t in counted)
        if len(counted) >= n_trials and not queued:
            if wait and any(t.state == TrialState.RUNNING for t in counted):
                time.sleep(0.1)  # another worker's last trials: leave the study complete
                continue
            return
        with interrupts_deferred():  # an asked trial is running or told, never left behind
            trial = _start_trial(study, worker)
            earlier = [t for t in study.get_trials(deepcopy=False) if t.number < trial.number]
            if sum(_counted(t) for t in earlier) >= n_trials:  # another worker took the budget
                trial.set_user_attr("surplus", True)
                study.tell(trial, state=TrialState.FAIL)
                continue
        state, value, note = TrialState.COMPLETE, None, ""
        try:
            # beats while the folds run, so a long fold is not taken for dead
            with every(beat, lambda: _beat(study, trial), name=f"heartbeat-{trial.number}"):
                value = objective(trial)
        except optuna.TrialPruned as exc:
            state, note = TrialState.PRUNED, str(exc)
        except Exception as exc:  # a failed configuration is recorded, never chosen
            state, note = TrialState.FAIL, f"{type(exc).__name__}: {exc}"
            trial.set_user_attr("error", note[:2000])
        except BaseException:  # interrupted: not the configuration's fault, run it again
            _fail_and_retry(study, trial.number)
            raise
        with interrupts_deferred():  # a finished trial is told (and logged) whole
            trial.set_user_attr("finished_by", worker)
            try:
                study.tell(trial, value if state == TrialState.COMPLETE else None, state=state)
            except (RuntimeError, ValueError, UpdateFinishedTrialError):
                continue  # taken for dead meanwhile (and queued again): the retry counts
            if on_trial is not None:
                on_trial(study, study.get_trials(deepcopy=False)[trial.number])
        if progress:
            best = _best_value(study)
            shown = f"MAE {value:.4f}" if value is not None else note[:60]
            log.info("[%s] trial %3d %-8s %s  best %s", study.study_name, trial.number,
                     state.name.lower(), shown, best if best is None else round(best, 4))


def run_studies(cfg, studies: list[tuple[optuna.Study, Callable]], *,
                progress: bool = False,
                on_trial: Callable[[optuna.Study, FrozenTrial], None] | None = None) -> None:
    """Run (or resume) ``(study, objective)`` pairs to their budgets in this process, with a
    sampler stream of its own (see :func:`claim_stream`)."""
    if not studies:
        return
    stream = claim_stream(studies[0][0])
    for study, _ in studies:
        study.sampler = _sampler(cfg, study.study_name, stream)
        _fail_stale(study, cfg.study.stale_after_s)  # every dead trial at once, not per study
    # First pass: take trials wherever budget is left, never idling while another worker
    # finishes a study's last trials; second pass: make sure every study is complete.
    for wait in (False, True):
        for study, objective in studies:
            run_study(study, objective, cfg.study.trials, timeout=cfg.study.timeout,
                      stale_after_s=cfg.study.stale_after_s, progress=progress, wait=wait,
                      on_trial=on_trial)


def _watch_parent(parent: int) -> None:
    """Ends this worker (SIGTERM to itself) when its parent process is gone, e.g. SIGKILLed
    (the parent by pid: a worker started by the fork server is the server's child)."""
    def watch():
        while _alive(parent) and os.getppid() != 1:
            time.sleep(1.0)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(60)  # the main thread is stuck in native code: do not linger
        os._exit(EXIT_SIGTERM)

    threading.Thread(target=watch, daemon=True, name="watch-parent").start()


def _worker(search: Callable, cfg, storage_url: str, index: int, show: bool, parent: int,
            on_trial) -> None:
    from .lifecycle import handle_signals

    _watch_parent(parent)
    try:
        with handle_signals():  # Ctrl-C reaches the whole group: the parent reports it
            if show:  # this process's per-trial lines to its standard error
                from .cli import _logging

                _logging()
            search(cfg, storage_url, progress=show, worker=index, on_trial=on_trial)
    except KeyboardInterrupt as exc:  # its running trial is failed and queued again
        sys.exit(getattr(exc, "code", EXIT_SIGINT))


def worker_context():
    """The multiprocessing context of sweep workers: the fork server where there is one
    (started early by the command, :func:`workbench.parallel.start_fork_server`, or now),
    else spawn."""
    from ..parallel import start_fork_server
    from .cli import SWEEP_WORKER_MODULES

    if start_fork_server(SWEEP_WORKER_MODULES):  # a no-op when it runs already
        return multiprocessing.get_context("forkserver")
    return multiprocessing.get_context("spawn")


def _search_in_workers(search: Callable, cfg, storage_url: str, workers: int,
                       progress: bool, names: list[str], root: Path,
                       on_trial=None) -> None:
    """``search(cfg, storage_url, progress=, worker=, on_trial=)`` (a module-level function:
    workers come from the fork server, or are spawned) in ``workers`` processes, after creating the studies ``names`` once.
    An interrupt of this process ends the workers (their running trials are queued again)."""
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


def dashboard_command(storage: str, port: int, root: Path) -> list[str]:
    """The ``optuna-dashboard`` command line serving the studies of ``storage`` (a journal
    file, relative to ``root``, or an RDB URL) on 127.0.0.1."""
    cmd = [sys.executable, "-c", "from optuna_dashboard._cli import main; main()",
           "--host", "127.0.0.1", "--port", str(port)]  # the package has no __main__
    if "://" in storage:
        return cmd + [storage]
    path = Path(storage)
    path = path if path.is_absolute() else root / path
    return cmd + ["--storage-class", "JournalFileStorage", str(path)]
