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

__all__ = ["DPI", "draw_study", "write_sweep_figures"]

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
    save_figure(outer_folds_figure(sweep.outer_folds, sweep.dataset.unit),
                folder / "outer_folds.png", dpi=DPI)
    return folder
