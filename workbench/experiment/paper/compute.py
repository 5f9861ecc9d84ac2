"""The reproduction's own fits of the paper settings, and its settings.

The paper settings' learning curves and the SHAP summaries of their correction (each a plan
of tasks for the workers, :mod:`workbench.parallel`, its figures drawn and written by tasks
too), the figure filer ``save(fig_id, figure, name)`` of what the main process draws (it
writes the file and files it under the paper's figure id), the parameter-space model's
settings, and the progress lines. The tabula rasa MLPs are in :mod:`.phases`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ...curves import learning_curve_plan
from ...datasets import Dataset
from ...parallel import Plan, Task, gather
from ..config import ExperimentConfig, without_intervals
from ..figures import correction_shap_figure, learning_curve_figure, save_figure, shap_figure
from ..runs.intervals import family_model
from ..scoring.explain import target_shap_values

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["CURVE_FOLDS", "PAPER_SIZES", "SHORT", "TABULA_RASA", "TABULA_RASA_SEEDS",
           "SameAs", "Save", "correction_shap_plan", "figure_saver", "hamiltonian_config",
           "learning_curves_plan", "say", "seeded", "set_clock", "start_clock"]

#: The paper's short names of the five eigenenergies.
SHORT = ["Y1", "Y2", "Y3", "Y4", "Y5"]
#: The paper's learning-curve training sizes (23 ... 95 training rows).
PAPER_SIZES = [23, 33, 43, 54, 64, 74, 85, 95]
#: Folds of the learning curves (5-fold CV on the training rows).
CURVE_FOLDS = 5
#: Tabula rasa MLPs on the 9 voltages (paper_params.md): hidden, alpha, max_iter per target.
TABULA_RASA = [((10,), 15.0, 4600), ((10,), 15.0, 5020), ((10,), 13.0, 5780),
               ((10,), 19.0, 4160), ((8,), 19.0, 5240)]
#: Seeds of the tabula rasa MLPs (their spread is reported; ``--quick``: 3).
TABULA_RASA_SEEDS = 10

#: ``save(fig_id, figure, name=None)``: write a figure, file it under ``fig_id``, return its path.
Save = Callable[..., Path]
#: ``same_as(fig_id, path)``: file an already written figure under another id too.
SameAs = Callable[[str, Path], None]

_T0 = [time.perf_counter()]


def start_clock() -> float:
    """Start the clock of the progress lines (:func:`say`).

    Returns
    -------
    float
        The start, on :func:`time.perf_counter`'s clock.
    """
    _T0[0] = time.perf_counter()
    return _T0[0]


def set_clock(start: float) -> None:
    """Time the progress lines of this process from ``start`` (:func:`say`).

    A worker process, forked before the reproduction started its clock, shows its phase's
    lines on the reproduction's clock.

    Parameters
    ----------
    start : float
        The reproduction's start, on :func:`time.perf_counter`'s clock (system-wide).
    """
    _T0[0] = start


def say(text: str) -> None:
    """Log a progress line with the seconds since :func:`start_clock`.

    Parameters
    ----------
    text : str
        The line.
    """
    logging.getLogger("workbench").info("[reproduce %5.0f s] %s", time.perf_counter() - _T0[0],
                                        text)


def seeded(cfg: ExperimentConfig, random_state: int) -> ExperimentConfig:
    """Seed a config and turn off its intervals, as every evaluation of the reproduction.

    The reproduction reports the paper's errors, and CV+ would refit every model 5 more times
    (``workbench evaluate`` reports the intervals; ``python benchmarks/intervals.py`` measures
    them).

    Parameters
    ----------
    cfg : ExperimentConfig
        The config as loaded.
    random_state : int
        Its ``random_state``.

    Returns
    -------
    ExperimentConfig
        The copy the reproduction evaluates.
    """
    return without_intervals(replace(cfg, random_state=random_state))


def hamiltonian_config(cfg: ExperimentConfig, random_state: int, quick: bool) -> ExperimentConfig:
    """Set up ``experiments/hamiltonian.toml`` as the reproduction evaluates it.

    Its nested CV over all rows (its longest part: it redoes the selection in each outer
    fold) is left to ``workbench evaluate experiments/hamiltonian.toml``; quick mode also uses a
    smaller pool and one CV repeat.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config as loaded (family ``hamiltonian``).
    random_state : int
        Its ``random_state``.
    quick : bool
        The smaller pool, fewer steps and one CV repeat.

    Returns
    -------
    ExperimentConfig
        The seeded copy without nested CV or intervals.
    """
    evaluation: dict[str, Any] = {"nested_folds": 0}
    hamiltonian: dict[str, Any] = {}
    if quick:
        evaluation.update(cv_repeats=1)
        hamiltonian.update(candidates="local", max_steps=2, selection_cv=3)
    assert cfg.family_settings is not None  # family = "hamiltonian" has settings
    return seeded(replace(cfg, evaluation=cfg.evaluation.model_copy(update=evaluation),
                          family_settings=cfg.family_settings.model_copy(update=hamiltonian)),
                  random_state)


def learning_curves_plan(paper_cfg: ExperimentConfig, ds: Dataset, random_state: int,
                         quick: bool, figdir: Path) -> Plan:
    """Plan the paper settings' augmented learning curves and their figures.

    The five targets' (size, fold) fits, then one task per target drawing its panel of
    Fig. S5 (Fig. 4 is its Y3 panel), as one plan for the workers (:mod:`workbench.parallel`).
    The fits need the paper settings' config only, not their fitted model.

    Parameters
    ----------
    paper_cfg : ExperimentConfig
        The paper settings as loaded (``experiments/paper_main_body.toml``); its family builds
        each target's candidate.
    ds : Dataset
        The Google 5-qubit data.
    random_state : int
        Seeds the folds.
    quick : bool
        Two sizes (the smallest and the largest) instead of every paper size.
    figdir : Path
        Where the figures go.

    Returns
    -------
    Plan
        Returns ``(curves, files)``: ``train_sizes``, ``folds`` and the ``curves`` (short
        target name -> the curve's JSON), and the figures written by figure id.
    """
    X_train, _, y_train, _ = ds.split()
    largest = len(X_train) - -(-len(X_train) // CURVE_FOLDS)
    sizes = [s for s in PAPER_SIZES if s <= largest]
    sizes = sorted(set(sizes + [largest]))
    if quick:  # the curve's two ends: a third fewer fits, the largest size still checked
        sizes = [sizes[0], sizes[-1]]
    say(f"augmented learning curves at training sizes {sizes} "
        f"(5-fold CV on the training rows: at most {largest} rows)")
    model = paper_cfg.family.build(paper_cfg, ds)
    candidates = [model.target_estimators[t].estimator for t in ds.target_names]
    curves = yield from gather([
        learning_curve_plan(est, X_train, y_train[target].to_numpy(), train_sizes=sizes,
                            cv=CURVE_FOLDS, random_state=random_state)
        for target, est in zip(ds.target_names, candidates)])
    paths = yield [Task(_curve_figure, figdir, j, target, curve, ds.unit)
                   for j, (target, curve) in enumerate(zip(ds.target_names, curves))]
    files = {"figS5_learning_curves": paths, "fig4_learning_curve_Y3": [paths[SHORT.index("Y3")]]}
    return ({"train_sizes": sizes, "folds": CURVE_FOLDS,
             "curves": {SHORT[j]: curve.to_dict() for j, curve in enumerate(curves)}}, files)


def _curve_figure(figdir: Path, j: int, target: str, curve: Any, unit: str | None) -> Path:
    """Draw and write target ``j``'s learning curve (a panel of Fig. S5)."""
    fig = learning_curve_figure(curve, target=f"{SHORT[j]} ({target})", unit=unit,
                                setting="paper settings")
    return save_figure(fig, figdir / f"figS5_learning_curve_{SHORT[j]}.png")


def correction_shap_plan(model: Any, ds: Dataset, random_state: int, quick: bool,
                         figdir: Path) -> Plan:
    """Plan the SHAP values of what the paper settings learned, and their figures.

    Per target, the correction's (model − prior) and the whole prediction's on the training
    rows, one task each (the longest tasks of the paper settings: they go first), then one
    task per figure: the correction (``figR2_shap_correction``) beside the whole prediction
    (``figR3_shap_prediction``), for the workers (:mod:`workbench.parallel`).

    Parameters
    ----------
    model : estimator
        The paper settings' fitted model (as ``evaluate`` returns it).
    ds : Dataset
        The data it was fitted on.
    random_state : int
        Seeds the SHAP background and the beeswarms.
    quick : bool
        Explain 30 training rows instead of all.
    figdir : Path
        Where the figures go.

    Returns
    -------
    Plan
        Returns the figures written, by figure id.
    """
    say("SHAP of the paper settings' correction (model − prior) and whole prediction")
    X_train = ds.split()[0]
    rows = X_train.iloc[:30] if quick else X_train
    tasks = [Task(target_shap_values, est, rows, random_state=random_state)
             for est in family_model(model).estimators_]
    for task in tasks:
        task.priority = 10 ** 6
    done = yield tasks
    figures = [Task(_shap_figure, figdir, fig_id, j, target, shap, ds.unit, random_state)
               for fig_id in ("figR2_shap_correction", "figR3_shap_prediction")
               for j, (target, shap) in enumerate(zip(ds.target_names, done))]
    paths = yield figures
    n = len(ds.target_names)
    return {"figR2_shap_correction": paths[:n], "figR3_shap_prediction": paths[n:]}


def _shap_figure(figdir: Path, fig_id: str, j: int, target: str, shap: Any,
                 unit: str | None, random_state: int) -> Path:
    """Draw and write target ``j``'s SHAP summary: of the correction (Fig. R2) or of the
    whole prediction (Fig. R3)."""
    name = f"{SHORT[j]} ({target})"
    if fig_id == "figR2_shap_correction":
        fig = correction_shap_figure(shap.correction, target=name, unit=unit, note=shap.note,
                                     random_state=random_state, setting="paper settings")
    else:
        assert shap.prediction is not None  # computed: prediction=True
        fig = shap_figure(shap.prediction.values, shap.prediction.expected,
                          shap.prediction.rows, target=name, unit=unit, random_state=random_state,
                          setting="paper settings", explained="prediction")
    return save_figure(fig, figdir / f"{fig_id}_{SHORT[j]}.png")


def figure_saver(figdir: Path, files: dict[str, list[Path]]) -> tuple[Save, SameAs]:
    """Make the :data:`Save` and :data:`SameAs` of a reproduction.

    Parameters
    ----------
    figdir : Path
        Where the PNG files go.
    files : dict
        Figure id -> its files, filled in as figures are saved.

    Returns
    -------
    save, same_as
        The two callbacks.
    """
    def save(fig_id: str, fig: Figure, name: str | None = None) -> Path:
        path = save_figure(fig, figdir / f"{name or fig_id}.png")
        files.setdefault(fig_id, []).append(path)
        return path

    def same_as(fig_id: str, path: Path) -> None:  # a paper figure that is another's panel
        files.setdefault(fig_id, []).append(path)

    return save, same_as
