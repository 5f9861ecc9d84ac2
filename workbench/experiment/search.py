"""``workbench sweep``: nested cross-validation driven by Optuna studies.

Per target, on the training rows only:

1. *Outer folds* estimate generalisation. In each outer fold an Optuna study searches the
   config's ``[search]`` space; a trial's value is the inner-CV mean absolute error of the
   boosted candidate, read from :class:`~workbench.BaseBoostCV`'s own fold scores (reported
   fold by fold, so a pruner can stop poor trials). The best configuration is refitted (with
   BaseBoostCV's fallback to the prior) on the outer-training rows and scored once on the
   outer-validation rows: the mean over outer folds is the nested-CV estimate.
2. A *final* study on all training rows chooses the configuration that is refitted and scored
   once on the test rows.

For ``[model] family = "hamiltonian"`` the unit of a study is all targets together (one
parameter-space model predicts every target): a trial's value is the inner-CV MAE, over all
targets, of the :class:`~workbench.fitted_prior.FittedPriorBoost` that the trial's
``[search.hamiltonian]`` and ``[search]`` settings describe, refitted fold by fold.

Studies live in shared storage (a journal file by default, or an RDB URL), so an interrupted
sweep resumes where it stopped and several processes, or machines, can work on one sweep:
each trial records its worker and a heartbeat; a running trial whose process is gone (same
host) or whose heartbeat is older than ``stale_after_s`` is marked failed and not counted, and
a trial started beyond the budget is marked ``surplus`` and not run. So every study finishes
exactly ``trials`` counted trials, none lost or repeated.
"""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, TextIO

import numpy as np
import optuna
import pandas as pd
from optuna.trial import FixedTrial, TrialState
from sklearn.base import clone
from sklearn.exceptions import ConvergenceWarning
from sklearn.model_selection import KFold, RepeatedKFold

from ..datasets import Dataset
from ..multitarget import MultiTargetBaseBoost
from ..selection import BaseBoostCV
from .config import (ExperimentConfig, build_model, load_dataset, make_booster, model_inputs,
                     target_inputs)
from .evaluate import fit_and_score
from . import studies as _studies
from .studies import (_counted, _pruner, _sampler, open_storage,  # noqa: F401
                      redact, run_studies, run_study)

__all__ = ["open_storage", "run_search", "run_sweep", "settings_for", "study_names"]

optuna.logging.set_verbosity(optuna.logging.WARNING)

#: The unit of the studies of family hamiltonian: all targets together.
ALL_TARGETS = "hamiltonian"


def _root() -> Path:
    """Relative storage paths resolve against the working directory (the project root)."""
    return Path.cwd()


def _hamiltonian(cfg: ExperimentConfig) -> bool:
    return cfg.family == "hamiltonian"


def _unit_targets(unit: str, targets: list[str]) -> list[str]:
    """The targets one study's unit covers: one target, or all of them (``ALL_TARGETS``)."""
    return list(targets) if unit == ALL_TARGETS else [unit]


def study_names(cfg: ExperimentConfig, targets: list[str]) -> list[tuple[str, str, int | None]]:
    """``(study name, unit, outer fold or None for the final study)`` in sweep order. The unit
    is a target, or ``"hamiltonian"`` (all targets together) for family hamiltonian."""
    base = cfg.study["study_name"] or cfg.name
    n_outer = cfg.cv["outer_folds"] * cfg.cv["repeats"]
    out = []
    for t in [ALL_TARGETS] if _hamiltonian(cfg) else targets:
        out += [(f"{base}.{t}.outer{k}", t, k) for k in range(n_outer)]
        out.append((f"{base}.{t}.final", t, None))
    return out


def _outer_splits(cfg: ExperimentConfig, n_rows: int):
    c = cfg.cv
    if c["repeats"] > 1:
        splitter = RepeatedKFold(n_splits=c["outer_folds"], n_repeats=c["repeats"],
                                 random_state=c["seed"])
    else:
        splitter = KFold(c["outer_folds"], shuffle=True, random_state=c["seed"])
    return list(splitter.split(np.zeros((n_rows, 1))))


def _inner_cv(cfg: ExperimentConfig) -> KFold:
    return KFold(cfg.cv["inner_folds"], shuffle=True, random_state=cfg.cv["seed"])


def _rows(ds: Dataset, unit: str, fold: int | None, cfg: ExperimentConfig):
    """Search rows (X, y) of one study: an outer fold's training rows, or all training rows
    (for the unit ``ALL_TARGETS``, y is a frame of all targets)."""
    X = model_inputs(cfg, ds).loc[ds.train_index]
    y = ds.targets.loc[ds.train_index]
    y = y if unit == ALL_TARGETS else y[unit]
    if fold is None:
        return X, y
    train, _ = _outer_splits(cfg, len(X))[fold]
    return X.iloc[train], y.iloc[train]


def settings_for(cfg: ExperimentConfig, target: str, params: dict[str, Any]) -> dict[str, Any]:
    """The model settings of a finished trial's parameters; for family hamiltonian, the
    target's boosting-stage settings with the parameter-space model's under ``"hamiltonian"``."""
    trial = FixedTrial(params)
    settings = cfg.search.sample(trial, cfg.model_for(target))
    if _hamiltonian(cfg):
        settings["hamiltonian"] = cfg.search.sample_hamiltonian(trial, cfg.hamiltonian)
    return settings


def _with_settings(cfg: ExperimentConfig, targets: list[str], trial) -> ExperimentConfig:
    """Family hamiltonian: ``cfg`` with a trial's settings, for :func:`build_model` and
    :func:`fit_and_score` (``[model.hamiltonian]`` and every target's boosting stage; the
    ``[search]`` entries are shared by all targets: one parameter each)."""
    return replace(cfg, hamiltonian=cfg.search.sample_hamiltonian(trial, cfg.hamiltonian),
                   targets={t: cfg.search.sample(trial, cfg.model_for(t)) for t in targets})


def _chosen_config(cfg: ExperimentConfig, targets: list[str],
                   params: dict[str, Any] | None) -> ExperimentConfig:
    """Family hamiltonian: ``cfg`` with a finished trial's settings (its own without one)."""
    return cfg if params is None else _with_settings(cfg, targets, FixedTrial(params))


def _booster_cv(cfg: ExperimentConfig, ds: Dataset, target: str,
                settings: dict[str, Any], **kwargs) -> BaseBoostCV:
    prior = ds.prior_names[ds.target_names.index(target)]
    booster = make_booster(settings, prior=prior, inputs=target_inputs(settings, ds))
    return BaseBoostCV(booster, cv=_inner_cv(cfg), scoring=cfg.selection["scoring"],
                       random_state=cfg.random_state, **kwargs)


def _fold_reporter(cfg: ExperimentConfig, trial, maes: list[float]) -> Callable:
    """``report(i, mae)`` after inner fold ``i``: heartbeat, the value the pruner reads
    (running mean of the folds' MAE for the median pruner, each fold's for wilcoxon), and
    pruning."""
    per_fold = cfg.study["pruner"] == "wilcoxon"

    def report(i: int, mae: float) -> None:
        trial.set_user_attr("heartbeat", time.time())
        if not np.isfinite(mae):
            raise RuntimeError(f"candidate fit failed in inner fold {i}")
        maes.append(mae)
        trial.report(maes[-1] if per_fold else float(np.mean(maes)), i)
        if trial.should_prune():
            raise optuna.TrialPruned(f"pruned after inner fold {i}")

    return report


def _objective(cfg, ds, target, X, y, trial) -> float:
    settings = cfg.search.sample(trial, cfg.model_for(target))
    cv = _booster_cv(cfg, ds, target, settings, refit=False)
    maes: list[float] = []
    report = _fold_reporter(cfg, trial, maes)
    with warnings.catch_warnings():  # an MLP's max_iter is the search's business, not noise
        warnings.simplefilter("ignore", ConvergenceWarning)
        cv.fit(X, y.to_numpy(),
               fold_callback=lambda i, prior_score, boosted_score: report(i, -boosted_score))
    trial.set_user_attr("prior_cv_mae", float(-np.mean(cv.cv_scores_prior_)))
    trial.set_user_attr("fold_mae", [float(m) for m in maes])
    return float(np.mean(maes))


def _hamiltonian_objective(cfg, ds, X, Y, trial) -> float:
    """Family hamiltonian: inner-CV MAE over all targets of the trial's whole model."""
    model = build_model(_with_settings(cfg, ds.target_names, trial), ds)
    prior = X[ds.prior_names].to_numpy()
    maes: list[float] = []
    prior_maes: list[float] = []
    report = _fold_reporter(cfg, trial, maes)
    for i, (train, val) in enumerate(_inner_cv(cfg).split(X)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            fitted = clone(model).fit(X.iloc[train], Y.iloc[train])
        y_val = Y.iloc[val].to_numpy()
        pred = np.asarray(fitted.predict(X.iloc[val]), dtype=float)
        prior_maes.append(float(np.mean(np.abs(y_val - prior[val]))))
        report(i, float(np.mean(np.abs(y_val - pred))))
    trial.set_user_attr("prior_cv_mae", float(np.mean(prior_maes)))
    trial.set_user_attr("fold_mae", [float(m) for m in maes])
    return float(np.mean(maes))


def _study_objective(cfg: ExperimentConfig, ds: Dataset, unit: str,
                     fold: int | None) -> Callable:
    """The objective of one study: a trial's inner-CV MAE on the study's rows."""
    X, y = _rows(ds, unit, fold, cfg)
    if unit == ALL_TARGETS:
        return lambda trial: _hamiltonian_objective(cfg, ds, X, y, trial)
    return lambda trial: _objective(cfg, ds, unit, X, y, trial)


def run_search(cfg: ExperimentConfig, storage_url: str, *, progress: TextIO | None = None,
               worker: int = 0, on_trial: Callable | None = None) -> None:
    """Run (or resume) every study of the sweep in this process (``worker``: its index;
    ``on_trial(study, trial)`` after each trial it finishes)."""
    ds = load_dataset(cfg)
    storage = open_storage(storage_url, _root(), stale_after_s=cfg.study["stale_after_s"])
    studies = []
    for name, unit, fold in study_names(cfg, ds.target_names):
        study = optuna.create_study(study_name=name, storage=storage, direction="minimize",
                                    sampler=_sampler(cfg, name, worker),
                                    pruner=_pruner(cfg), load_if_exists=True)
        studies.append((study, _study_objective(cfg, ds, unit, fold)))
    run_studies(cfg, studies, progress=progress, on_trial=on_trial)


def _search_in_workers(cfg: ExperimentConfig, storage_url: str, workers: int,
                       progress: TextIO | None, on_trial: Callable | None = None) -> None:
    names = [name for name, _, _ in study_names(cfg, load_dataset(cfg).target_names)]
    _studies._search_in_workers(run_search, cfg, storage_url, workers, progress, names, _root(),
                                on_trial=on_trial)


def _load(cfg: ExperimentConfig, storage_url: str, name: str) -> optuna.Study:
    return optuna.load_study(study_name=name, storage=open_storage(storage_url, _root()),
                             sampler=_sampler(cfg, name), pruner=_pruner(cfg))


def _best_params(study: optuna.Study) -> dict[str, Any] | None:
    done = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    return min(done, key=lambda t: (t.value, t.number)).params if done else None


def _refit_predict(cfg: ExperimentConfig, ds: Dataset, unit: str, params: dict[str, Any],
                   X: pd.DataFrame, Y: pd.DataFrame, train, val) -> tuple[np.ndarray, str]:
    """An outer fold: a study's best settings refitted on the outer-training rows. Returns
    the predictions on the outer-validation rows, ``(n_val, targets of the unit)``, and what
    was selected (family hamiltonian: per target, comma-joined)."""
    if unit == ALL_TARGETS:
        model = build_model(_chosen_config(cfg, ds.target_names, params), ds)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            model.fit(X.iloc[train], Y.iloc[train])
        selected = ",".join("hamiltonian+boosted" if s == "boosted" else "hamiltonian"
                            for s in model.selected_)
        return np.asarray(model.predict(X.iloc[val]), dtype=float), selected
    model = _booster_cv(cfg, ds, unit, settings_for(cfg, unit, params))
    model.fit(X.iloc[train], Y[unit].to_numpy()[train])
    return np.asarray(model.predict(X.iloc[val])).reshape(-1, 1), model.selected_


def _final_model(cfg: ExperimentConfig, ds: Dataset, best: dict[str, dict[str, Any] | None]):
    """``(config, unfitted model)`` of the final studies' choices, for :func:`fit_and_score`
    (a unit without a completed trial keeps the config's own settings)."""
    if _hamiltonian(cfg):
        chosen = _chosen_config(cfg, ds.target_names, best[ALL_TARGETS])
        return chosen, build_model(chosen, ds)
    return cfg, MultiTargetBaseBoost(target_estimators={
        t: (_booster_cv(cfg, ds, t, settings_for(cfg, t, best[t])) if best[t] is not None
            else _booster_cv(cfg, ds, t, cfg.model_for(t)))
        for t in ds.target_names}, random_state=cfg.random_state, n_jobs=cfg.n_jobs)


def run_sweep(cfg: ExperimentConfig, *, storage: str | None = None, workers: int | None = None,
              progress: TextIO | None | bool = True,
              on_trial: Callable | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """Search, then evaluate. Returns ``(result, details)``: the JSON-ready result (the
    ``evaluate`` fields plus ``nested_cv_mae``, ``nested_cv_mae_avg``, ``best_params``) and
    in-process details (the fitted final model, dataset, studies, outer-fold results)."""
    start = time.perf_counter()
    if progress is True:
        progress = sys.stderr
    storage_url = storage or cfg.study["storage"]
    workers = workers or cfg.study["workers"]
    ds = load_dataset(cfg)
    names = study_names(cfg, ds.target_names)
    if progress:
        print(f"[{cfg.name}] sweep: {len(names)} studies x {cfg.study['trials']} trials, "
              f"{workers} worker(s), storage {redact(storage_url)}", file=progress, flush=True)
    _search_in_workers(cfg, storage_url, workers, progress, on_trial)

    studies = {name: _load(cfg, storage_url, name) for name, _, _ in names}
    X_all = model_inputs(cfg, ds).loc[ds.train_index]
    Y_all = ds.targets.loc[ds.train_index]
    prior_all = ds.prior.loc[ds.train_index].to_numpy()
    outer = _outer_splits(cfg, len(X_all))
    nested, nested_prior, folds, best = {}, {}, [], {}
    for name, unit, fold in names:
        params = _best_params(studies[name])
        if fold is None:
            best[unit] = params
            continue
        train, val = outer[fold]
        targets = _unit_targets(unit, ds.target_names)
        cols = [ds.target_names.index(t) for t in targets]
        y_val = Y_all[targets].to_numpy()[val]
        prior_val = prior_all[val][:, cols]
        if params is None:  # no trial completed: the prior stands
            pred, selected = prior_val, "prior"
        else:
            pred, selected = _refit_predict(cfg, ds, unit, params, X_all, Y_all, train, val)
        maes = [float(np.mean(np.abs(y_val[:, j] - pred[:, j]))) for j in range(len(targets))]
        prior_maes = [float(np.mean(np.abs(y_val[:, j] - prior_val[:, j])))
                      for j in range(len(targets))]
        for t, mae, prior_mae in zip(targets, maes, prior_maes):
            nested.setdefault(t, []).append(mae)
            nested_prior.setdefault(t, []).append(prior_mae)
        folds.append(dict(target=unit, fold=fold, study=name, mae=float(np.mean(maes)),
                          prior_mae=float(np.mean(prior_maes)), selected=selected,
                          n_train=len(train), n_val=len(val), params=params,
                          target_mae=dict(zip(targets, maes)),
                          target_prior_mae=dict(zip(targets, prior_maes))))

    final_cfg, final = _final_model(cfg, ds, best)
    result, fitted = fit_and_score(final_cfg, ds, final)
    result["nested_cv_mae"] = [float(np.mean(nested[t])) for t in ds.target_names]
    result["nested_cv_mae_avg"] = float(np.mean(result["nested_cv_mae"]))
    result["nested_cv_prior_mae"] = [float(np.mean(nested_prior[t])) for t in ds.target_names]
    result["nested_cv_prior_mae_avg"] = float(np.mean(result["nested_cv_prior_mae"]))
    # family hamiltonian: the one study's choice, repeated for every target
    result["best_params"] = [best[ALL_TARGETS if _hamiltonian(cfg) else t]
                             for t in ds.target_names]
    counts = {n: sum(_counted(t) for t in s.get_trials(deepcopy=False))
              for n, s in studies.items()}
    result["trials"] = {"per_study": cfg.study["trials"], "counted": sum(counts.values()),
                        "studies": len(studies)}
    result["wall_s"] = time.perf_counter() - start
    details = dict(model=fitted, dataset=ds, studies=studies, outer_folds=folds,
                   storage=storage_url, config=final_cfg)
    return result, details


def with_overrides(cfg: ExperimentConfig, *, trials: int | None = None,
                   workers: int | None = None, storage: str | None = None) -> ExperimentConfig:
    """``cfg`` with command-line overrides of the ``[study]`` table."""
    study = dict(cfg.study)
    for key, value in (("trials", trials), ("workers", workers), ("storage", storage)):
        if value is not None:
            study[key] = value
    return replace(cfg, study=study)
