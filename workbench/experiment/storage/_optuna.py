"""The one module that reads Optuna's private names.

Optuna has no public way to reach a study's storage and ids, a trial's id, or the journal
file's lock and record types; the storage adapter needs them. Gathered here, an Optuna
release that renames one breaks one file.
"""

from __future__ import annotations

from typing import Any

import optuna
from optuna.storages.journal._file import get_lock_file
from optuna.storages.journal._storage import JournalOperation, JournalStorageReplayResult

__all__ = ["JournalOperation", "JournalStorageReplayResult", "get_lock_file", "storage_of",
           "study_id", "trial_id"]


def storage_of(study: optuna.Study) -> Any:
    """Return the storage a study reads and writes.

    Parameters
    ----------
    study : optuna.Study

    Returns
    -------
    optuna.storages.BaseStorage
    """
    return study._storage


def study_id(study: optuna.Study) -> int:
    """Return a study's id in its storage.

    Parameters
    ----------
    study : optuna.Study

    Returns
    -------
    int
    """
    return study._study_id


def trial_id(trial: optuna.Trial) -> int:
    """Return a running trial's id in its storage.

    Parameters
    ----------
    trial : optuna.Trial

    Returns
    -------
    int
    """
    return trial._trial_id
