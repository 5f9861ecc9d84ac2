"""A sweep's Optuna figures and tables, for its MLflow run and ``sweep --out``.

:func:`write_sweep_figures` writes, into one directory, per study ``studies/<study>/`` with
Optuna's figures (:func:`~workbench.experiment.figures.studies.study_figures`: ``history``,
``importances``, ``parallel_coordinate``, ``slice``, ``contour`` PNGs) and
``importances.csv``; across the studies ``importances.csv`` (column ``study`` first) and
``outer_folds.png`` (:func:`~workbench.experiment.figures.outer_folds.outer_folds_figure`).
The studies are drawn on the command's worker processes, each from its trials rebuilt in an
in-memory study (the storage stays with this process). A figure Optuna cannot draw is logged
with the reason and left out.
"""

from __future__ import annotations

import logging
import shutil
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import optuna
import pandas as pd
from optuna.trial import FrozenTrial

from ..._io import atomic_write
from ...parallel import Task, map_tasks
from ..figures import save_figure
from ..figures.outer_folds import outer_folds_figure
from ..figures.studies import study_figures
from .scheduler import OBJECTIVE

if TYPE_CHECKING:
    from .search import Sweep

__all__ = ["DPI", "draw_study", "figures_of_sweep", "write_sweep_figures"]

log = logging.getLogger("workbench")

#: Resolution of the figures (PNG).
DPI = 80


def draw_study(name: str, trials: list[FrozenTrial], seed: int,
               directory: str) -> tuple[dict[str, str], pd.DataFrame]:
    """Draw one study's figures into ``directory`` (a worker's task).

    Parameters
    ----------
    name : str
        The study's name.
    trials : list of FrozenTrial
        Its finished trials.
    seed : int
        The importances' seed.
    directory : str
        Where its PNGs and ``importances.csv`` go (created).

    Returns
    -------
    tuple
        Why each figure left out was (name -> reason), and the importances.
    """
    study = optuna.create_study(study_name=name, direction="minimize")
    study.add_trials(trials)
    drawn = study_figures(study, seed, target_name=OBJECTIVE)
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    for figure, fig in drawn.figures.items():
        save_figure(fig, folder / f"{figure}.png", dpi=DPI)
    atomic_write(folder / "importances.csv", drawn.importances.to_csv(index=False))
    return drawn.skipped, drawn.importances


def _finished(study: optuna.Study) -> list[FrozenTrial]:
    """List the study's finished trials, without the surplus ones (never run)."""
    return [t for t in study.get_trials(deepcopy=False)
            if t.state.is_finished() and not t.user_attrs.get("surplus")]


def write_sweep_figures(sweep: Sweep, directory: str | Path, seed: int,
                        jobs: int | None = None) -> Path:
    """Write a sweep's Optuna figures, importances and outer-fold summary into ``directory``.

    Parameters
    ----------
    sweep : Sweep
        The finished sweep (its studies, outer folds and dataset).
    directory : str or Path
        Where they go (created if missing).
    seed : int
        The importances' seed (the fANOVA forest's).
    jobs : int, optional
        Worker processes drawing the studies (the command's ``n_jobs``).

    Returns
    -------
    Path
        ``directory``.
    """
    folder = Path(directory)
    names = list(sweep.studies)
    drawn: list[Any] = map_tasks(
        [Task(draw_study, name, _finished(sweep.studies[name]), seed,
              str(folder / "studies" / name)) for name in names], jobs)
    tables = []
    for name, (skipped, importances) in zip(names, drawn):
        for figure, why in skipped.items():
            log.info("[%s] no %s figure: %s", name, figure, why)
        tables.append(importances.assign(study=name)[["study", "param", "importance"]])
    atomic_write(folder / "importances.csv", pd.concat(tables).to_csv(index=False))
    save_figure(outer_folds_figure(sweep.outer_folds, sweep.dataset.unit,
                                   prior_label=sweep.dataset.prior_label),
                folder / "outer_folds.png", dpi=DPI)
    return folder


def _fold_runs(tracker: Any, run_id: str) -> dict[str, str]:
    """Map each outer-fold study to its run (a child of the sweep's run, tagged ``study``)."""
    runs = tracker.client.search_runs(
        [tracker.experiment_id], max_results=10_000,
        filter_string=f"tags.`mlflow.parentRunId` = '{run_id}' "
                      "and tags.`workbench.kind` = 'outer_fold'")
    return {r.data.tags["study"]: r.info.run_id for r in runs if "study" in r.data.tags}


def figures_of_sweep(done: Sweep, out: str | None, tracker: Any, run_id: str | None) -> None:
    """Draw a sweep's Optuna figures into its runs (``optuna/``) and ``--out`` (if given).

    An outer fold's study goes to that fold's run, the final studies (no run of their own)
    and the tables across studies to the sweep's run, under ``optuna/studies/<study>/``.

    Parameters
    ----------
    done : Sweep
        The finished sweep.
    out : str or None
        ``sweep --out``: a directory that gets the same files.
    tracker : Tracker or None
        The command's tracker (``None`` without tracking).
    run_id : str or None
        The sweep's run.
    """
    if out is None and run_id is None:
        return
    cfg = done.config
    seed = cfg.random_state if cfg.random_state is not None else cfg.cv.sweep_seed
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="workbench-optuna-") as tmp:
        write_sweep_figures(done, tmp, seed, cfg.jobs)
        log.info(
            "[%s] Optuna figures of %d studies in %.1f s", cfg.name, len(done.studies),
            time.perf_counter() - start)
        if out is not None:
            shutil.copytree(tmp, out, dirs_exist_ok=True)
        if run_id is not None:
            for study, fold_run in _fold_runs(tracker, run_id).items():
                folder = Path(tmp) / "studies" / study
                if folder.is_dir():
                    tracker.log_file(fold_run, folder, "optuna")
                    shutil.rmtree(folder)
            tracker.log_file(run_id, tmp, "optuna")
