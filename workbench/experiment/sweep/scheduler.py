"""The trial scheduler of ``workbench sweep``.

Samplers and pruners, and running studies in shared storage until each holds exactly its
budget of counted trials (:mod:`~workbench.experiment.storage` opens the storages,
:mod:`~workbench.experiment.sweep.workers` starts the processes,
:mod:`~workbench.experiment.sweep.search` holds the objectives).

Several processes (or machines) may work on one storage at once:

* **Distinct proposals.** The sampler's random numbers are seeded per *trial*, from (the cv
  seed, the study's name, the trial's number) (:class:`TrialSeededSampler`). Every storage
  assigns trial numbers atomically, so concurrent processes never draw from one stream, a
  trial number draws the same numbers whichever process runs it, and nothing but the
  studies is kept in the storage. TPE runs with ``constant_liar`` so running trials repel
  proposals.
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
* **Workers die with their parent** (:func:`workbench.parallel.init_worker`): the parent's
  end sends them SIGTERM, which fails and queues their running trials.
"""

from __future__ import annotations

import logging
import os
import socket
import time
import warnings
import zlib
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

import numpy as np
import optuna
from optuna.distributions import BaseDistribution
from optuna.exceptions import ExperimentalWarning, UpdateFinishedTrialError
from optuna.trial import FrozenTrial, TrialState

from ...parallel import pid_alive
from ..process.errors import StorageError
from ..process.signals import interrupts_deferred
from ..storage import (
    beat,
    fail_stale_trials,
    heartbeat_enabled,
    heartbeat_interval,
    retry,
    set_trial_attr,
)
from ..tracking.lifecycle import every

if TYPE_CHECKING:
    from optuna.storages import BaseStorage

    from ..config import ExperimentConfig

log = logging.getLogger("workbench")

__all__ = ["OBJECTIVE", "TrialSeededSampler", "fail_stale", "is_counted", "open_study",
           "pruner", "run_studies", "run_study", "sampler", "studies_short", "trial_seed"]


def trial_seed(seed: int, study_name: str, number: int) -> int:
    """Seed trial ``number`` of study ``study_name``: 32 bits, well mixed.

    Nearby seeds, names and numbers give unrelated streams.
    """
    entropy = [seed, zlib.crc32(study_name.encode()), number]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0])


class TrialSeededSampler(optuna.samplers.BaseSampler):
    """Optuna's sampler ``kind`` with its random numbers seeded per trial.

    ``kind`` is ``"tpe"`` (with ``constant_liar``) or ``"random"``. Each trial is sampled by
    a fresh sampler seeded with :func:`trial_seed` of (``seed``, the study's name, the
    trial's number). Trial numbers are assigned atomically by every Optuna storage, so
    processes sharing a study never draw the same numbers, one trial number draws the same
    numbers in whichever process runs it, and one process alone proposes the same trials run
    after run (TPE's proposals also depend on the trials finished before, which only a lone
    process fixes). A fresh sampler per trial costs nothing that matters here: Optuna's TPE
    and random samplers keep no state between trials but their random generator and caches
    of the study's trials.
    """

    def __init__(self, kind: str, seed: int):
        if kind not in ("tpe", "random"):
            raise ValueError(f"unknown sampler {kind!r}")
        self.kind, self.seed = kind, seed
        self._current: tuple[tuple[str, int], optuna.samplers.BaseSampler] | None = None

    def __repr__(self) -> str:
        """Show the sampler's kind and seed."""
        return f"TrialSeededSampler({self.kind!r}, seed={self.seed})"

    def _for(self, study: optuna.Study, trial: FrozenTrial) -> optuna.samplers.BaseSampler:
        """Get the sampler of ``trial`` (made when the trial starts, kept while it runs)."""
        key = (study.study_name, trial.number)
        if self._current is None or self._current[0] != key:
            seed = trial_seed(self.seed, *key)
            inner = (optuna.samplers.RandomSampler(seed=seed) if self.kind == "random" else
                     optuna.samplers.TPESampler(seed=seed, constant_liar=True))
            self._current = (key, inner)
        return self._current[1]

    def before_trial(self, study: optuna.Study, trial: FrozenTrial) -> None:
        """Delegate to the trial's sampler."""
        self._for(study, trial).before_trial(study, trial)

    def infer_relative_search_space(self, study: optuna.Study,
                                    trial: FrozenTrial) -> dict[str, BaseDistribution]:
        """Delegate to the trial's sampler."""
        return self._for(study, trial).infer_relative_search_space(study, trial)

    def sample_relative(self, study: optuna.Study, trial: FrozenTrial,
                        search_space: dict[str, BaseDistribution]) -> dict[str, Any]:
        """Delegate to the trial's sampler."""
        return self._for(study, trial).sample_relative(study, trial, search_space)

    def sample_independent(self, study: optuna.Study, trial: FrozenTrial, param_name: str,
                           param_distribution: BaseDistribution) -> Any:
        """Delegate to the trial's sampler."""
        return self._for(study, trial).sample_independent(study, trial, param_name,
                                                          param_distribution)

    def after_trial(self, study: optuna.Study, trial: FrozenTrial, state: TrialState,
                    values: Sequence[float] | None) -> None:
        """Delegate to the trial's sampler."""
        self._for(study, trial).after_trial(study, trial, state, values)

    def reseed_rng(self) -> None:
        """Nothing to reseed: every trial's numbers come from its own seed."""


def sampler(cfg: ExperimentConfig) -> TrialSeededSampler:
    """Make the sampler of a sweep's study (``[study] sampler``).

    It is seeded per trial from ``[cv] sweep_seed`` and the study's name
    (:class:`TrialSeededSampler`).
    """
    return TrialSeededSampler(cfg.study.sampler, cfg.cv.sweep_seed)


#: What a study's value is, as the Optuna dashboard labels it (instead of "Objective 0").
OBJECTIVE = "inner-CV MAE (targets' units)"


def open_study(name: str, storage: BaseStorage, *,
               attrs: Mapping[str, Any] | None = None, **kwargs: Any) -> optuna.Study:
    """Open the sweep's study ``name`` in ``storage`` (created if new; minimised).

    Its objective is named (:data:`OBJECTIVE`) and its user attributes ``attrs`` set where
    missing (what sweep it belongs to, which the dashboard shows; a resumed study keeps the
    values it has). ``kwargs``: Optuna's (a sampler, a pruner).
    """
    study = optuna.create_study(study_name=name, storage=storage, direction="minimize",
                                load_if_exists=True, **kwargs)
    if study.metric_names != [OBJECTIVE]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExperimentalWarning)  # set_metric_names
            study.set_metric_names([OBJECTIVE])
    if attrs:
        have = study.user_attrs
        for key, value in attrs.items():
            if key not in have:
                study.set_user_attr(key, value)
    return study


def pruner(cfg: ExperimentConfig) -> optuna.pruners.BasePruner:
    """Make the pruner of a sweep's study (``[study] pruner``: median, wilcoxon or none)."""
    name = cfg.study.pruner
    if name == "median":  # reported values: running mean of the inner folds' MAE
        return optuna.pruners.MedianPruner(n_startup_trials=3)
    if name == "wilcoxon":  # reported values: each inner fold's MAE
        return optuna.pruners.WilcoxonPruner(p_threshold=0.1)
    return optuna.pruners.NopPruner()


def is_counted(t: FrozenTrial) -> bool:
    """Whether a trial uses one of the study's ``trials`` (stale and surplus ones do not)."""
    attrs = t.user_attrs
    if attrs.get("surplus"):
        return False
    if t.state == TrialState.FAIL:  # failed in the objective, not failed as stale by others
        return "finished_by" in attrs and not attrs.get("stale")
    return True


def _fail_and_retry(study: optuna.Study, number: int) -> None:
    """Fail a running trial that no process works on, then queue it once more.

    Only the process whose FAIL lands first queues it: the storage refuses the others'. The
    trial is marked ``stale`` first, so it is not counted even when its process died after
    setting ``finished_by`` and before its own ``tell``.
    """
    try:
        set_trial_attr(study, number, "stale", True)
        study.tell(number, state=TrialState.FAIL)
    except (RuntimeError, ValueError, UpdateFinishedTrialError):  # finished meanwhile
        return
    retry(study, number)


def fail_stale(study: optuna.Study, stale_after_s: float) -> None:
    """Fail (and queue once more) running trials whose worker is gone.

    At once when it was a process on this host; after ``stale_after_s`` without a heartbeat
    otherwise (RDB: by Optuna's heartbeat; journal: by the ``heartbeat`` user attribute).
    """
    fail_stale_trials(study)
    host, now = socket.gethostname(), time.time()
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        worker = t.user_attrs.get("worker", "")
        w_host, _, w_pid = worker.rpartition(":")
        dead = w_host == host and w_pid.isdigit() and not pid_alive(int(w_pid))
        started = t.datetime_start.timestamp() if t.datetime_start else now
        old = (not heartbeat_enabled(study)
               and now - t.user_attrs.get("heartbeat", started) > stale_after_s)
        if dead or old:
            _fail_and_retry(study, t.number)


def _best_value(study: optuna.Study) -> float | None:
    try:
        return study.best_value
    except ValueError:
        return None


def _start_trial(study: optuna.Study, worker: str) -> optuna.Trial:
    with warnings.catch_warnings():  # "heartbeat ... supposed to be used with optimize":
        warnings.simplefilter("ignore", UserWarning)  # run_study beats it (see beat)
        trial = study.ask()
    trial.set_user_attr("worker", worker)
    trial.set_user_attr("heartbeat", time.time())
    if heartbeat_enabled(study):
        beat(study, trial)
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
    re-run, and propagates.
    """
    worker = f"{socket.gethostname()}:{os.getpid()}"
    beat_s = heartbeat_interval(stale_after_s)
    start = time.perf_counter()
    while timeout is None or time.perf_counter() - start < timeout:
        fail_stale(study, stale_after_s)
        counted = [t for t in study.get_trials(deepcopy=False) if is_counted(t)]
        queued = any(t.state == TrialState.WAITING for t in counted)
        if len(counted) >= n_trials and not queued:
            if wait and any(t.state == TrialState.RUNNING for t in counted):
                time.sleep(0.1)  # another worker's last trials: leave the study complete
                continue
            return
        asked: list[optuna.Trial] = []
        try:
            with interrupts_deferred():  # an asked trial is running or told, never left behind
                trial = _start_trial(study, worker)
                asked.append(trial)
                earlier = [t for t in study.get_trials(deepcopy=False)
                           if t.number < trial.number]
                if sum(is_counted(t) for t in earlier) >= n_trials:  # another took the budget
                    trial.set_user_attr("surplus", True)
                    study.tell(trial, state=TrialState.FAIL)
                    asked.clear()
                    continue
        except BaseException:  # a signal deferred during the ask is raised on leaving it:
            if asked:  # the asked trial is failed and queued again, as in the objective
                _fail_and_retry(study, asked[0].number)
            raise
        state, value, note = TrialState.COMPLETE, None, ""
        try:
            # beats while the folds run, so a long fold is not taken for dead
            with every(beat_s, lambda t=trial: beat(study, t), name=f"heartbeat-{trial.number}"):
                value = objective(trial)
        except optuna.TrialPruned as exc:
            state, note = TrialState.PRUNED, str(exc)
        except StorageError:  # the store is away: its trial stays RUNNING for the reaper
            raise  # (fail_stale: this process gone), not counted as the configuration's
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


def run_studies(cfg: ExperimentConfig, studies: list[tuple[optuna.Study, Callable]], *,
                progress: bool = False,
                on_trial: Callable[[optuna.Study, FrozenTrial], None] | None = None) -> None:
    """Run (or resume) ``(study, objective)`` pairs to their budgets in this process.

    Each study has its own sampler (see :func:`sampler`). ``[study] timeout`` (``--timeout``)
    bounds the whole call, as Optuna's ``study.optimize(timeout=...)`` bounds one study: no
    trial starts once it has passed, and the running one finishes (the studies are then
    short of their budgets; :func:`studies_short` tells).
    """
    if not studies:
        return
    for study, _ in studies:
        fail_stale(study, cfg.study.stale_after_s)  # every dead trial at once, not per study
    deadline = None if cfg.study.timeout is None else time.monotonic() + cfg.study.timeout
    # First pass: take trials wherever budget is left, never idling while another worker
    # finishes a study's last trials; second pass: make sure every study is complete.
    for wait in (False, True):
        for study, objective in studies:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                return
            run_study(study, objective, cfg.study.trials, timeout=left,
                      stale_after_s=cfg.study.stale_after_s, progress=progress, wait=wait,
                      on_trial=on_trial)


def studies_short(studies: Sequence[optuna.Study], n_trials: int) -> tuple[int, int]:
    """Count the studies' counted trials, and the trials their budgets call for.

    Parameters
    ----------
    studies : sequence of optuna.Study
        A sweep's studies.
    n_trials : int
        Each study's budget (``[study] trials``).

    Returns
    -------
    tuple of int
        ``(finished, wanted)``: counted trials not running, and ``n_trials`` per study.
    """
    done = sum(is_counted(t) and t.state.is_finished()
               for s in studies for t in s.get_trials(deepcopy=False))
    return done, n_trials * len(studies)
