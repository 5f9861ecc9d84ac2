"""``workbench sweep``: nested cross-validation driven by Optuna studies.

For each study block of the config's family (a target for family ``eigenvalue``; all targets
together for a family whose one model predicts them all), on the training rows only:

1. *Outer folds* estimate generalisation. In each outer fold an Optuna study searches the
   config's ``[search]`` space (and ``[search.<family>]``); a trial's value is the inner-CV
   mean absolute error of the candidate, reported fold by fold so a pruner can stop poor
   trials. The best configuration is refitted on the outer-training rows and scored once on
   the outer-validation rows: the mean over outer folds is the nested-CV estimate.
2. A *final* study on all training rows chooses the configuration that is refitted and scored
   once on the test rows.

The family supplies the objective, the refit and the final model
(:class:`~workbench.experiment.families.base.ModelFamily`); the studies' storage and trial
scheduling are :mod:`~workbench.experiment.storage` and
:mod:`~workbench.experiment.sweep.scheduler`, its processes
:mod:`~workbench.experiment.sweep.workers`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np
import optuna
from optuna.trial import TrialState
from sklearn.metrics import mean_absolute_error
from sklearn.model_selection import RepeatedKFold

from ...parallel import Task, map_tasks
from ..config import ExperimentConfig, load_dataset
from ..process.errors import SweepTimedOut, redact
from ..runs.evaluate import fit_and_score
from ..scoring.results import OuterFold, Result, SweepSummary
from ..splits.folds import describe_folds, outer_order_splits, sweep_inner_cv
from ..storage import open_storage
from .scheduler import is_counted, open_study, pruner, run_studies, sampler, studies_short
from .workers import search_in_workers

if TYPE_CHECKING:
    import pandas as pd

    from ...datasets import Dataset

__all__ = ["Sweep", "run_search", "run_sweep", "study_attrs", "study_names", "sweep_name"]

optuna.logging.set_verbosity(optuna.logging.WARNING)
log = logging.getLogger("workbench")


@dataclass(frozen=True)
class StudySpec:
    """One study of a sweep.

    Its name, block, the block's targets, and the outer fold (``None``: the final study on all
    training rows).
    """

    name: str
    block: str
    targets: list[str]
    fold: int | None


@dataclass
class Sweep:
    """A finished sweep: the result, the fitted final model and what led to it.

    Parameters
    ----------
    result : Result
        The sweep's result (its ``sweep`` the nested CV's summary).
    model : estimator
        The final model, refitted on all training rows with the final studies' settings.
    dataset : Dataset
        The data.
    config : ExperimentConfig
        The config swept.
    studies : dict of str to optuna.Study
        The studies by name.
    storage : str
        Where the studies are stored.
    """

    result: Result
    model: Any
    dataset: Any
    config: ExperimentConfig
    studies: dict[str, optuna.Study]
    storage: str

    @property
    def outer_folds(self) -> list[OuterFold]:
        """The outer folds of the sweep's summary."""
        assert self.result.sweep is not None  # a sweep's result has its summary
        return self.result.sweep.outer_folds


def _root() -> Path:
    """Relative storage paths resolve against the working directory (the project root)."""
    return Path.cwd()


def study_names(cfg: ExperimentConfig, targets: list[str]) -> list[StudySpec]:
    """List the sweep's studies in order: per block, one per outer fold, then the final one.

    All are named ``<sweep>.<block>.outer<k>`` / ``<sweep>.<block>.final`` (``<sweep>``:
    :func:`sweep_name`), so that the sweep's name finds them (the dashboard's "Search
    study" box).
    """
    base = sweep_name(cfg)
    n_outer = cfg.cv.outer_folds * cfg.cv.repeats
    out = []
    for block, block_targets in cfg.family.blocks(targets).items():
        out += [StudySpec(f"{base}.{block}.outer{k}", block, block_targets, k)
                for k in range(n_outer)]
        out.append(StudySpec(f"{base}.{block}.final", block, block_targets, None))
    return out


def sweep_name(cfg: ExperimentConfig) -> str:
    """Name the sweep's studies begin with: ``[study] study_name``, else the config's."""
    return cfg.study.study_name or cfg.name


def study_attrs(cfg: ExperimentConfig, spec: StudySpec) -> dict[str, Any]:
    """Build a study's user attributes (the dashboard shows them on the study's page).

    The sweep it belongs to, its config, block, targets and outer fold (``"final"``: the
    final study on all training rows).
    """
    return {"sweep": sweep_name(cfg), "config": cfg.label, "block": spec.block,
            "targets": list(spec.targets),
            "fold": "final" if spec.fold is None else spec.fold}


def outer_splits(cfg: ExperimentConfig, n_rows: int,
                 ds: Dataset | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Split ``n_rows`` training rows into the outer folds.

    ``RepeatedKFold`` (``[cv]``, seeded), or forward-chaining when ``ds`` has an order.
    """
    c = cfg.cv
    if ds is not None and ds.order is not None:
        return outer_order_splits(cfg, ds)
    splitter = RepeatedKFold(n_splits=c.outer_folds, n_repeats=c.repeats, random_state=c.sweep_seed)
    return list(splitter.split(np.zeros((n_rows, 1))))


def inner_cv(cfg: ExperimentConfig, ds: Dataset | None = None) -> Any:
    """Make the inner folds of every trial.

    ``[cv]`` inner_folds, shuffled with ``sweep_seed``; forward-chaining when ``ds`` has an order.
    """
    return sweep_inner_cv(cfg, ds)


def _rows(cfg: ExperimentConfig, ds: Dataset,
          spec: StudySpec) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Select a study's search rows: an outer fold's training rows, or all training rows."""
    X = cfg.family.inputs(cfg, ds).loc[ds.train_index]
    Y = ds.targets.loc[ds.train_index]
    if spec.fold is None:
        return X, Y
    train, _ = outer_splits(cfg, len(X), ds)[spec.fold]
    return X.iloc[train], Y.iloc[train]


def _fold_reporter(cfg: ExperimentConfig, trial: optuna.Trial, maes: list[float],
                   prior: list[float]) -> Callable[[int, float, float], None]:
    """Make ``report(i, mae, prior_mae)``, called after inner fold ``i``.

    It beats the heartbeat, reports the value the pruner reads (running mean of the folds'
    MAE for the median pruner, each fold's for wilcoxon), and prunes.
    """
    per_fold = cfg.study.pruner == "wilcoxon"

    def report(i: int, mae: float, prior_mae: float) -> None:
        trial.set_user_attr("heartbeat", time.time())
        if not np.isfinite(mae):
            raise RuntimeError(f"candidate fit failed in inner fold {i}")
        maes.append(mae)
        prior.append(prior_mae)
        trial.report(maes[-1] if per_fold else float(np.mean(maes)), i)
        if trial.should_prune():
            raise optuna.TrialPruned(f"pruned after inner fold {i}")

    return report


def study_objective(cfg: ExperimentConfig, ds: Dataset,
                    spec: StudySpec) -> Callable[[optuna.Trial], float]:
    """Make the objective of one study: a trial's inner-CV MAE on the study's rows."""
    X, Y = _rows(cfg, ds, spec)
    family = cfg.family

    def objective(trial: optuna.Trial) -> float:
        maes: list[float] = []
        prior: list[float] = []
        family.objective(cfg, ds, spec.targets, X, Y, trial, inner_cv(cfg, ds),
                         _fold_reporter(cfg, trial, maes, prior))
        trial.set_user_attr("prior_cv_mae", float(np.mean(prior)))
        trial.set_user_attr("fold_mae", [float(m) for m in maes])
        return float(np.mean(maes))

    return objective


def run_search(cfg: ExperimentConfig, storage_url: str, *, progress: bool = False,
               worker: int = 0, on_trial: Callable | None = None,
               dataset: Dataset | None = None) -> None:
    """Run (or resume) every study of the sweep in this process.

    Parameters
    ----------
    cfg : ExperimentConfig
        The sweep's config.
    storage_url : str
        The Optuna storage (journal file or RDB URL).
    progress : bool, default=False
        A line per trial through the ``workbench`` logger.
    worker : int, default=0
        This process's index, which changes nothing: the samplers are seeded per trial.
    on_trial : callable, optional
        ``on_trial(study, trial)`` after each trial this process finishes.
    dataset : Dataset, optional
        The config's dataset, already loaded (loaded here when not given).
    """
    ds = dataset if dataset is not None else load_dataset(cfg)
    storage = open_storage(storage_url, _root(), stale_after_s=cfg.study.stale_after_s)
    studies = []
    for spec in study_names(cfg, ds.target_names):
        study = open_study(spec.name, storage, attrs=study_attrs(cfg, spec),
                           sampler=sampler(cfg), pruner=pruner(cfg))
        studies.append((study, study_objective(cfg, ds, spec)))
    run_studies(cfg, studies, progress=progress, on_trial=on_trial)


def _best_params(study: optuna.Study) -> dict[str, Any] | None:
    done = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    return min(done, key=lambda t: (t.value, t.number)).params if done else None


def _outer_folds(cfg: ExperimentConfig, ds: Dataset, specs: list[StudySpec],
                 params_of: dict[str, dict[str, Any] | None]
                 ) -> tuple[list[OuterFold], dict[str, list[float]], dict[str, list[float]]]:
    """Refit each study's best settings on its outer fold and score them on its validation rows.

    The refits are independent, on the command's worker processes. Returns the folds, and
    per target the model's and the prior's MAE in each fold (the prior stands where no
    trial completed).
    """
    family = cfg.family
    X_all = family.inputs(cfg, ds).loc[ds.train_index]
    Y_all = ds.targets.loc[ds.train_index]
    prior_all = ds.prior.loc[ds.train_index].to_numpy()
    outer = outer_splits(cfg, len(X_all), ds)
    refits = [spec for spec in specs
              if spec.fold is not None and params_of[spec.name] is not None]
    refitted = dict(zip((spec.name for spec in refits), map_tasks(
        [Task(family.refit_predict, cfg, ds, spec.targets, params_of[spec.name], X_all, Y_all,
              *outer[spec.fold]) for spec in refits if spec.fold is not None], cfg.jobs)))
    nested: dict[str, list[float]] = {}
    nested_prior: dict[str, list[float]] = {}
    folds: list[OuterFold] = []
    for spec in specs:
        if spec.fold is None:
            continue
        params = params_of[spec.name]
        train, val = outer[spec.fold]
        cols = [ds.target_names.index(t) for t in spec.targets]
        y_val = Y_all[spec.targets].to_numpy()[val]
        prior_val = prior_all[val][:, cols]
        if params is None:  # no trial completed: the prior stands
            pred, selected = prior_val, "prior"
        else:
            pred, selected = refitted[spec.name]
        maes = [mean_absolute_error(y_val[:, j], pred[:, j]) for j in range(len(cols))]
        prior_maes = [mean_absolute_error(y_val[:, j], prior_val[:, j])
                      for j in range(len(cols))]
        for t, m, p in zip(spec.targets, maes, prior_maes):
            nested.setdefault(t, []).append(m)
            nested_prior.setdefault(t, []).append(p)
        folds.append(OuterFold(block=spec.block, fold=spec.fold, study=spec.name,
                               mae=float(np.mean(maes)), prior_mae=float(np.mean(prior_maes)),
                               selected=selected, n_train=len(train), n_val=len(val),
                               params=params, target_mae=dict(zip(spec.targets, maes)),
                               target_prior_mae=dict(zip(spec.targets, prior_maes))))
    return folds, nested, nested_prior


def _check_complete(cfg: ExperimentConfig, studies: list[optuna.Study],
                    storage_url: str) -> None:
    """Raise :class:`SweepTimedOut` when the timeout left a study short of its trials."""
    timeout = cfg.study.timeout
    if timeout is None:  # the search returns only with every study complete
        return
    done, wanted = studies_short(studies, cfg.study.trials)
    if done < wanted:
        raise SweepTimedOut(
            f"sweep stopped by its timeout ({timeout:g} s) with {done} of {wanted} trials "
            f"finished; run the same command again to resume (the studies in "
            f"{redact(storage_url)} keep their trials)")


def run_sweep(cfg: ExperimentConfig, *, progress: bool = True,
              on_trial: Callable | None = None, dataset: Dataset | None = None) -> Sweep:
    """Search, then evaluate the chosen configuration once on the test rows.

    Parameters
    ----------
    cfg : ExperimentConfig
        The sweep's config.
    progress : bool, default=True
        A line per trial through the ``workbench`` logger.
    on_trial : callable, optional
        ``on_trial(study, trial)`` after each trial this process finishes (e.g. to log it).
    dataset : Dataset, optional
        The config's dataset, already loaded and checked (loaded here when not given); the
        search's worker processes receive it rather than loading it again.

    Returns
    -------
    Sweep
        The result, the final model and the studies.
    """
    start = time.perf_counter()
    storage_url = cfg.study.storage
    workers = cfg.study.workers
    ds = dataset if dataset is not None else load_dataset(cfg)
    specs = study_names(cfg, ds.target_names)
    log.info("[%s] sweep: %d studies x %d trials, %d worker(s), storage %s", cfg.name,
             len(specs), cfg.study.trials, workers, redact(storage_url))
    search_in_workers(run_search, cfg, storage_url, workers, bool(progress),
                      [s.name for s in specs], _root(), on_trial=on_trial,
                      attrs={s.name: study_attrs(cfg, s) for s in specs}, dataset=ds)

    family = cfg.family
    storage = open_storage(storage_url, _root(), stale_after_s=cfg.study.stale_after_s)
    studies = {s.name: optuna.load_study(study_name=s.name, storage=storage,
                                         sampler=sampler(cfg), pruner=pruner(cfg))
               for s in specs}
    _check_complete(cfg, list(studies.values()), storage_url)
    params_of = {spec.name: _best_params(studies[spec.name]) for spec in specs}
    best = {spec.block: params_of[spec.name] for spec in specs if spec.fold is None}
    folds, nested, nested_prior = _outer_folds(cfg, ds, specs, params_of)

    chosen = family.chosen_config(cfg, ds, best)
    result, fitted = fit_and_score(chosen, ds, family.final_model(chosen, ds))
    result.folds = f"{describe_folds(inner_cv(cfg, ds))} (the sweep's inner folds)"
    block_of = {t: block for block, ts in family.blocks(ds.target_names).items() for t in ts}
    counted = sum(sum(is_counted(t) for t in s.get_trials(deepcopy=False))
                  for s in studies.values())
    result.sweep = SweepSummary(
        nested_cv_mae=[float(np.mean(nested[t])) for t in ds.target_names],
        nested_cv_prior_mae=[float(np.mean(nested_prior[t])) for t in ds.target_names],
        best_params=[best[block_of[t]] for t in ds.target_names],
        trials_per_study=cfg.study.trials, trials_counted=counted, studies=len(studies),
        outer_folds=folds)
    result.wall_s = time.perf_counter() - start
    return Sweep(result=result, model=fitted, dataset=ds, config=chosen, studies=studies,
                 storage=storage_url)
