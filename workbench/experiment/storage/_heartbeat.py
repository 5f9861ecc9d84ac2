"""Heartbeats and retries of running trials.

Optuna's own on an RDB storage, a user attribute on the journal file (Optuna's
``JournalStorage`` has no heartbeat), and the one retry of a trial whose worker died. The
scheduler reaches what Optuna keeps private (a study's storage, its id, a trial's id)
through :mod:`._optuna`, the one module that reads those names (tests/test_layering.py
checks that no module outside this package does).
"""

from __future__ import annotations

import copy
import time
import warnings
from typing import Any

import optuna
from optuna.trial import FrozenTrial

from ._optuna import storage_of, study_id, trial_id

__all__ = ["beat", "heartbeat_enabled", "heartbeat_interval", "retry", "retry_callback",
           "set_trial_attr"]

#: User attributes that belong to one attempt at a trial, not to its configuration.
_ATTEMPT_ATTRS = ("worker", "heartbeat", "finished_by", "error", "surplus", "stale")


def heartbeat_interval(stale_after_s: float) -> int:
    """Seconds between heartbeats: a quarter of the grace period, 1 to 10 s."""
    return int(max(1, min(10, stale_after_s // 4)))


class _Retry(optuna.storages.RetryFailedTrialCallback):
    """Optuna's retry of a failed trial, without the dead attempt's own user attributes.

    The retry has the same parameters and ``retry_history`` in its system attributes; the
    attempt's ``worker`` (host:pid of a dead process) would get the retry failed again the
    moment another process looks.
    """

    def __call__(self, study: optuna.Study, trial: FrozenTrial) -> None:
        trial = copy.deepcopy(trial)
        trial.user_attrs = {k: v for k, v in trial.user_attrs.items()
                            if k not in _ATTEMPT_ATTRS}
        super().__call__(study, trial)


def retry_callback() -> _Retry:
    """Optuna's retry of a failed trial, once, without the dead attempt's own attributes.

    Returns
    -------
    RetryFailedTrialCallback
        The callback (Optuna's, its experimental warning silenced).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # experimental / renamed in 4.9: same behaviour
        return _Retry(max_retry=1)



def heartbeat_enabled(study: optuna.Study) -> bool:
    """Tell whether ``study``'s storage has Optuna's own heartbeat.

    An RDB storage opened by :func:`open_storage` has one; the journal file has none.
    """
    storage = storage_of(study)
    return isinstance(storage, optuna.storages.RDBStorage) \
        and storage.get_heartbeat_interval() is not None


def fail_stale_trials(study: optuna.Study) -> None:
    """Fail the running trials whose heartbeat stopped, when the storage has Optuna's own.

    :func:`optuna.storages.fail_stale_trials` (its experimental warning silenced); nothing
    for a storage without a heartbeat (the journal file: the scheduler fails those by the
    ``heartbeat`` user attribute).
    """
    if heartbeat_enabled(study):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            optuna.storages.fail_stale_trials(study)


def beat(study: optuna.Study, trial: optuna.Trial) -> None:
    """Record one heartbeat of a running trial.

    Optuna's own on an RDB storage, a user attribute on the journal file.
    """
    storage = storage_of(study)
    if isinstance(storage, optuna.storages.RDBStorage) and heartbeat_enabled(study):
        storage.record_heartbeat(trial_id(trial))
    else:
        trial.set_user_attr("heartbeat", time.time())


def set_trial_attr(study: optuna.Study, number: int, key: str, value: Any) -> None:
    """Set a user attribute of trial ``number``, which another process may be running."""
    storage = storage_of(study)
    trial_id = storage.get_trial_id_from_study_id_trial_number(study_id(study), number)
    storage.set_trial_user_attr(trial_id, key, value)


def retry(study: optuna.Study, number: int) -> None:
    """Queue failed trial ``number`` once more with its parameters.

    Optuna's ``RetryFailedTrialCallback``, without the dead attempt's own attributes.
    """
    retry_callback()(study, study.get_trials(deepcopy=False)[number])

