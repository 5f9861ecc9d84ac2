"""The peer every claim is measured against: LightGBM boosted from the prior, tuned by CV.

Per target, ``LGBMRegressor`` is fitted with ``init_score`` = the target's prior column on the
prior columns and the dataset's features, its hyperparameters tuned by 5-fold CV on the
training rows (shuffled folds, seeded): Optuna's TPE sampler (seeded), ``trials`` trials per
target, each scored by the mean absolute error over the folds; the best setting is refitted on
every training row and predicts ``prior + booster``. The search chooses LightGBM's objective
too, among squared error, absolute error and Huber (:data:`PEER_OBJECTIVES`; ``objectives``
names others, e.g. ``("regression",)`` for squared error alone). Each fit
uses one LightGBM thread; a trial's folds run in ``n_jobs`` threads (LightGBM releases the
GIL), which changes no number.
"""

from __future__ import annotations

import logging
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import optuna
import pandas as pd
from lightgbm import LGBMRegressor
from sklearn.metrics import mean_absolute_error
from sklearn.model_selection import KFold

__all__ = ["PEER_OBJECTIVES", "PEER_TRIALS", "Peer", "peer_predict"]

log = logging.getLogger("workbench")

#: Optuna trials per target of the peer's search.
PEER_TRIALS = 50
#: LightGBM objectives the peer's search chooses among: the strongest peer a user would tune
#: (squared error alone was 7% weaker on the IBM time split).
PEER_OBJECTIVES = ("regression", "regression_l1", "huber")
#: The peer's search space, as LightGBM parameters: (low, high, log).
SPACE = {"n_estimators": (20, 600, True), "learning_rate": (0.01, 0.3, True),
         "num_leaves": (4, 63, True), "min_child_samples": (3, 40, True),
         "reg_lambda": (1e-3, 10.0, True), "subsample": (0.5, 1.0, False),
         "colsample_bytree": (0.5, 1.0, False)}


@dataclass
class Peer:
    """The peer's predictions and settings.

    Parameters
    ----------
    predictions : numpy.ndarray of shape (n_rows, n_targets)
        Its test predictions.
    params : list of dict
        The settings it chose per target.
    seconds : float
        The seconds its tuning and final fits took.
    """

    predictions: np.ndarray
    params: list[dict[str, Any]]
    seconds: float


def _suggest(trial: optuna.Trial, objectives: tuple[str, ...]) -> dict[str, Any]:
    """Draw one setting of the peer's search space (and objective, if several)."""
    params: dict[str, Any] = {}
    for name, (low, high, log_scale) in SPACE.items():
        if isinstance(low, int):
            params[name] = trial.suggest_int(name, low, int(high), log=log_scale)
        else:
            params[name] = trial.suggest_float(name, low, high, log=log_scale)
    if len(objectives) > 1:
        params["objective"] = trial.suggest_categorical("objective", list(objectives))
    return params


def peer_predict(X_train: pd.DataFrame, y_train: pd.DataFrame, X_test: pd.DataFrame,
                 priors: list[str], features: list[str], *, trials: int = PEER_TRIALS,
                 random_state: int = 0, objectives: tuple[str, ...] = PEER_OBJECTIVES,
                 n_jobs: int = 1) -> Peer:
    """Tune and fit the peer (see the module docstring) per target, and predict the test rows.

    Parameters
    ----------
    X_train, y_train : pandas.DataFrame
        The training rows' inputs and targets.
    X_test : pandas.DataFrame
        The rows to predict.
    priors : list of str
        ``priors[j]``: target ``j``'s prior column.
    features : list of str
        The other input columns.
    trials : int, default=PEER_TRIALS
        Optuna trials per target.
    random_state : int, default=0
        Seeds the folds, the sampler and LightGBM. Formerly ``seed``.
    objectives : tuple of str, default=PEER_OBJECTIVES
        The LightGBM objectives the search chooses among.
    n_jobs : int, default=1
        Threads for a trial's folds.

    Returns
    -------
    Peer
        The test predictions, the chosen settings and the seconds taken.
    """
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    start = time.perf_counter()
    cols = list(dict.fromkeys(list(priors) + list(features)))
    folds = list(KFold(5, shuffle=True, random_state=random_state).split(X_train))
    out, chosen = [], []

    def make(params: dict[str, Any]) -> LGBMRegressor:
        return LGBMRegressor(n_jobs=1, verbose=-1, random_state=random_state, subsample_freq=1,
                             **params)

    with ThreadPoolExecutor(max(1, n_jobs)) as pool:
        for j, target in enumerate(y_train.columns):
            X = X_train[cols].to_numpy()
            y = y_train[target].to_numpy(dtype=float)
            base = X_train[priors[j]].to_numpy(dtype=float)

            def fold_error(params: dict[str, Any], rows: tuple[np.ndarray, np.ndarray],
                           X: np.ndarray = X, y: np.ndarray = y,
                           base: np.ndarray = base) -> float:
                fit_rows, val_rows = rows
                model = make(params).fit(X[fit_rows], y[fit_rows], init_score=base[fit_rows])
                pred = base[val_rows] + model.predict(X[val_rows])
                return mean_absolute_error(y[val_rows], pred)

            def objective(trial: optuna.Trial, fold_error: Any = fold_error) -> float:
                params = _suggest(trial, objectives)
                return float(np.mean(list(pool.map(lambda r: fold_error(params, r), folds))))

            study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=random_state))
            study.optimize(objective, n_trials=trials)
            model = make(study.best_params).fit(X, y, init_score=base)
            out.append(X_test[priors[j]].to_numpy(dtype=float)
                       + model.predict(X_test[cols].to_numpy()))
            chosen.append(dict(study.best_params))
            log.info("peer: %s tuned (%d trials, CV MAE %.4g)", target, trials,
                     study.best_value)
    return Peer(np.column_stack(out), chosen, time.perf_counter() - start)
