"""Family ``eigenvalue``: base boosting per target from the control program's eigenvalues.

Target ``j`` boosts from prior column ``j`` with a :class:`~workbench.BaseBoostCV` (which keeps
the prior unless CV on the training rows says boosting helps); the targets together form a
:class:`~workbench.MultiTargetBaseBoost`. A sweep searches each target on its own (the study
block is the target), a trial's value read from BaseBoostCV's own fold scores.
"""

from __future__ import annotations

import logging
import queue
import threading
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from sklearn.exceptions import ConvergenceWarning

from ...curves import learning_curve_plan, selection_curve_plan
from ...multitarget import MultiTargetBaseBoost
from ...parallel import (
    Plan,
    Task,
    effective_n_jobs,
    gather,
    prioritised,
    run_plans,
    start_workers,
)
from ...selection import BaseBoostCV, BasisChoiceCV
from ..figures import correction_shap_figure, learning_curve_figure, shap_figure
from ..scoring.explain import target_shap_values
from ..scoring.scores import ModelScores, Scores, mae, mse
from ..splits.folds import curve_cv, largest_curve_size, sweep_inner_cv
from .artifacts import Artifacts
from .base import ModelFamily, Report
from .choices import candidate_choices
from .fitting import quiet_fit
from .stage import (
    booster_cv,
    per_target_boost,
    stage_scores,
)

if TYPE_CHECKING:
    import pandas as pd

    from ...datasets import Dataset
    from ..config import ExperimentConfig

__all__ = ["EigenvalueFamily", "curve_sizes"]


#: Sizes of a run's augmented learning curves: a quarter, half and all of a fold's training
#: rows (the last point is the selection's own fold fits; two more fits per fold and target).
CURVE_POINTS = 3


def curve_sizes(n_rows: int, folds: int, points: int = CURVE_POINTS, *,
                largest: int | None = None) -> list[int]:
    """Choose training sizes from a quarter of the fold-training size up to all of it.

    Parameters
    ----------
    n_rows : int
        The training rows.
    folds : int
        The folds they are split into.
    points : int, default=CURVE_POINTS
        How many sizes at most (equal sizes merge).
    largest : int, default=None
        The rows the smallest fold trains on (``None``: K-fold's, ``n_rows`` less the
        largest fold); forward-chaining folds train on fewer.

    Returns
    -------
    list of int
        The sizes, increasing.
    """
    if largest is None:
        largest = n_rows - -(-n_rows // folds)  # rows left for training in the largest fold
    return sorted({int(s) for s in np.linspace(max(5, largest // 4), largest, points)})


class EigenvalueFamily(ModelFamily):
    """Base boosting in eigenvalue space, one BaseBoostCV per target."""

    name = "eigenvalue"
    cv_from_repeats = False  # BaseBoostCV's own folds give the CV figures
    interval_method = "oof"  # BaseBoostCV keeps its out-of-fold predictions

    def build(self, cfg: ExperimentConfig, ds: Dataset) -> MultiTargetBaseBoost:
        """Build one BaseBoostCV per target, each boosting from its prior column."""
        return per_target_boost(cfg, ds, ds.prior_names)

    def blocks(self, targets: list[str]) -> dict[str, list[str]]:
        """Make each target a study block of its own."""
        return {t: [t] for t in targets}

    def objective(self, cfg: ExperimentConfig, ds: Dataset, targets: list[str],
                  X: pd.DataFrame, Y: pd.DataFrame, trial: Any, cv: Any,
                  report: Report) -> None:
        """Score a trial by BaseBoostCV's own fold scores, reported fold by fold."""
        (target,) = targets
        settings = self.with_trial(cfg, trial, targets).model_for(target)
        model = booster_cv(cfg, ds, target, settings, cv, refit=False)
        quiet_fit_callback(model, X, Y[target].to_numpy(), report)

    def refit_predict(self, cfg: ExperimentConfig, ds: Dataset, targets: list[str],
                      params: dict[str, Any], X: pd.DataFrame, Y: pd.DataFrame, train: Any,
                      val: Any) -> tuple[np.ndarray, str]:
        """Refit the target's best settings on the outer fold (inner folds ``[cv]``)."""
        from optuna.trial import FixedTrial  # (b) Optuna: not for evaluate

        (target,) = targets
        settings = self.with_trial(cfg, FixedTrial(params), targets).model_for(target)
        model = booster_cv(cfg, ds, target, settings, cfg_inner_cv(cfg, ds))
        quiet_fit(model, X.iloc[train], Y[target].to_numpy()[train])
        return np.asarray(model.predict(X.iloc[val])).reshape(-1, 1), model.selected_

    def final_model(self, cfg: ExperimentConfig, ds: Dataset) -> MultiTargetBaseBoost:
        """Build the final model of a sweep.

        The chosen settings, each target's BaseBoostCV on the sweep's inner folds (as in the
        search).
        """
        return MultiTargetBaseBoost(target_estimators={
            t: booster_cv(cfg, ds, t, cfg.model_for(t), cfg_inner_cv(cfg, ds),
                          return_train_score=True)  # the curves reuse its folds
            for t in ds.target_names}, random_state=cfg.random_state, n_jobs=cfg.jobs)

    def scores(self, ds: Dataset, model: Any, Y_train: pd.DataFrame, prior_test: Any,
               y_test: Any, pred: Any) -> tuple[Scores, ModelScores, dict[str, Any]]:
        """Score prior and model, the CV figures from each target's BaseBoostCV."""
        s = stage_scores(model.estimators_, Y_train.to_numpy(dtype=float))
        prior = Scores(test_mae=mae(y_test, prior_test), test_mse=mse(y_test, prior_test),
                       cv_mae=s["prior_cv_mae"], cv_mse=s["prior_cv_mse"])
        scores = ModelScores(test_mae=mae(y_test, pred), test_mse=mse(y_test, pred),
                             cv_mae=s["cv_mae"], cv_mse=s["cv_mse"],
                             selected=s["selected"], coefs=s["coefs"],
                             extra={"cv_mae_boosted": s["boosted_cv_mae"]})
        return prior, scores, candidate_choices(ds.target_names, model.estimators_)

    def begin_artifacts(self, cfg: ExperimentConfig, ds: Dataset, model: Any, setting: str,
                        quick: bool = False) -> Callable[..., Artifacts]:
        """Start an augmented learning curve and two SHAP summaries per target.

        A BaseBoostCV's curve is drawn on its own selection folds, with its candidate as
        seeded there, at :data:`CURVE_POINTS` sizes: the whole-fold points are the
        selection's fold fits (not fitted again). The curves' fits and the SHAP values run
        on the command's worker processes (``n_jobs``), driven from a background thread
        while the caller logs the run's other records, one target after another (its tasks
        first in the queue), so the returned function draws (and emits) a target's figures
        while the workers go on with the next ones; figures are drawn in the calling thread
        (matplotlib and SHAP's plots are not thread-safe). SHAP explains the fitted model's
        whole prediction (``shap_<target>``, dominated by its prior) and, on the same rows
        over the same background, its correction, model - prior, what boosting learned
        (``shap_correction_<target>``; a note instead where the model is the prior)
        (:func:`~workbench.experiment.scoring.explain.target_shap_values`).
        """
        log = logging.getLogger("workbench")
        X_train, _, y_train, _ = ds.split()
        cv = curve_cv(cfg, ds)  # the selection's folds where they follow the data
        sizes = curve_sizes(len(X_train), cfg.selection.cv,
                            largest=largest_curve_size(cv, X_train))
        log.info("[%s] figures: learning curves at sizes %s and SHAP summaries of %d targets "
                 "(%d processes)", cfg.name, sizes, len(ds.target_names),
                 effective_n_jobs(cfg.jobs))
        results: queue.Queue[Any] = queue.Queue()
        n_targets = len(ds.target_names)
        plans = [prioritised(_reported(_target_plan(cfg, est, X_train, y_train[target].to_numpy(),
                                                    sizes, cv), j, results),
                             (n_targets - j) * 10 ** 7)  # target j's tasks before j + 1's
                 for j, (target, est) in enumerate(zip(ds.target_names, model.estimators_))]

        def work() -> None:
            try:
                run_plans(plans, cfg.jobs)
            except BaseException as exc:  # re-raised by finish()
                results.put(exc)

        start_workers(cfg.jobs)  # never fork from the thread
        threading.Thread(target=work, name="workbench-artifacts", daemon=True).start()

        def finish(emit: Callable[[str, Any], None] | None = None) -> Artifacts:
            drawn: dict[int, tuple[Any, dict[str, Any]]] = {}
            while len(drawn) < n_targets:
                item = results.get()
                if isinstance(item, BaseException):
                    raise item
                j, (curve, [explained]) = item
                target = ds.target_names[j]
                whole = explained.prediction
                figs = {f"learning_curve_{target}": learning_curve_figure(
                            curve, target=target, unit=ds.unit, setting=setting),
                        f"shap_{target}": shap_figure(whole.values, whole.expected, whole.rows,
                                                      target=target, unit=ds.unit,
                                                      setting=setting, explained="prediction"),
                        f"shap_correction_{target}": correction_shap_figure(
                            explained.correction, target=target, unit=ds.unit,
                            note=explained.note, setting=setting)}
                for name, fig in figs.items():
                    if emit is not None:
                        emit(name, fig)
                drawn[j] = (curve, figs)
            out = Artifacts()
            for j in range(n_targets):
                out.figures.update(drawn[j][1])
            out.data["learning_curves"] = {t: drawn[j][0].to_dict()
                                           for j, t in enumerate(ds.target_names)}
            return out

        return finish


def _target_plan(cfg: ExperimentConfig, est: Any, X_train: pd.DataFrame, y: np.ndarray,
                 sizes: list[int], cv: Any) -> Plan:
    """Plan one target's learning curve and SHAP values (:mod:`workbench.parallel`).

    The curve is drawn on ``cv`` (:func:`~workbench.experiment.splits.folds.curve_cv`), or on a
    BaseBoostCV's own folds.
    """
    if isinstance(est, BaseBoostCV) and not isinstance(est, BasisChoiceCV):
        # its own folds (a sweep's final model: the inner folds)
        own = curve_sizes(len(X_train), len(est.cv_splits_),
                          largest=min(len(train) for train, _ in est.cv_splits_))
        curve = selection_curve_plan(est, X_train, y, train_sizes=own,
                                     random_state=cfg.random_state)
    else:  # BasisChoiceCV: its chosen candidate on fresh folds
        candidate = getattr(est, "estimator_", None) or est.estimator
        curve = learning_curve_plan(candidate, X_train, y, train_sizes=sizes,
                                    cv=cv, random_state=cfg.random_state)
    # the whole prediction's and the correction's SHAP values, one task
    shap = Task(target_shap_values, est.best_estimator_, X_train,
                random_state=cfg.random_state or 0)
    shap.priority = 10 ** 6  # a long task: start it early
    return gather([curve, _all([shap])])


def _reported(plan: Plan, key: int, results: queue.Queue[Any]) -> Plan:
    """Run ``plan``, putting ``(key, its result)`` on the queue ``results`` when it ends."""
    value = yield from plan
    results.put((key, value))
    return value


def _all(tasks: list[Task]) -> Plan:
    """Plan independent tasks (:mod:`workbench.parallel`)."""
    return (yield tasks)


def cfg_inner_cv(cfg: ExperimentConfig, ds: Dataset | None = None) -> Any:
    """Make a sweep's inner folds (``[cv]``).

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.
    ds : Dataset, optional
        The dataset (its order).

    Returns
    -------
    cross-validator
        ``inner_folds`` shuffled folds seeded by ``[cv] sweep_seed``, forward-chaining when the
        dataset has an order (:func:`~workbench.experiment.splits.folds.sweep_inner_cv`).
    """
    return sweep_inner_cv(cfg, ds)


def quiet_fit_callback(model: Any, X: Any, y: Any, report: Report) -> None:
    """Fit a BaseBoostCV, reporting each fold's boosted and prior MAE as it finishes.

    A :class:`~workbench.BasisChoiceCV` (a trial whose settings hold candidates) runs its
    candidates' folds side by side and takes no fold callback: its folds (those of the
    candidate it would choose) are reported once all have run, so a pruner makes the same
    decision, only later.

    Parameters
    ----------
    model : BaseBoostCV
        The model to fit (convergence warnings silenced).
    X, y : array-like
        The training rows.
    report : callable
        ``report(fold, mae, prior_mae)``.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        if isinstance(model, BasisChoiceCV):
            model.fit(X, y)
            for i, (prior_score, boosted_score) in enumerate(
                    zip(model.cv_scores_prior_, model.cv_scores_boosted_)):
                report(i, -boosted_score, -prior_score)
            return
        model.fit(X, y, fold_callback=lambda i, prior_score, boosted_score:
                  report(i, -boosted_score, -prior_score))
