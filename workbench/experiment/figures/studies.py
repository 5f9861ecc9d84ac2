"""Optuna's own figures of a sweep's study (:mod:`optuna.visualization.matplotlib`).

:func:`study_figures` draws a study's optimization history, parameter importances, parallel
coordinates, slices, and the contour of its two most important parameters, and tabulates the
importances (fANOVA, seeded: :class:`optuna.importance.FanovaImportanceEvaluator`, computed
once and reused by the importance and contour figures). A figure Optuna cannot draw (no
complete trial, fewer than two for the importances, fewer than two parameters for the
contour) is skipped, with the reason for the caller to log; so is the contour of a study
with fewer than :data:`MIN_CONTOUR_TRIALS` complete trials (a surface interpolated on a
100 x 100 grid from a handful of points shows the interpolation, not the objective).

Optuna's functions draw through pyplot: the Agg backend is selected when pyplot is not
loaded yet (a command), the user's is kept otherwise (a notebook), and
:func:`~workbench.experiment.figures.save_figure` closes each figure it writes; nothing is
shown. Optuna's ``ExperimentalWarning`` (these functions are experimental) and matplotlib's
warning about a parameter that took one value (a flat axis) are silenced here only.

Cost, paid once per study, mostly matplotlib's (axes, ticks, text, PNG): the slice and
parallel-coordinate figures show the parameters the importances rank (those every complete
trial has: not a basis's own hyperparameters in a search over bases), at most
:data:`MAX_PARAMS`, most important first (the importance figure and table rank them all),
and all of them when there are no importances: each one is another subplot or axis to draw.
The importances' random forest has :data:`FANOVA_TREES` trees, not Optuna's 64: a study of
tens of trials needs no more, and the forest took a quarter of the time (0.12 s against
0.47 s per smoke study).
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

import pandas as pd

if TYPE_CHECKING:
    import optuna
    from matplotlib.figure import Figure

__all__ = ["FANOVA_TREES", "FIGURES", "MAX_PARAMS", "MIN_CONTOUR_TRIALS", "StudyFigures",
           "study_figures"]

#: The figures of a study, by file name (without ``.png``).
FIGURES = ("history", "importances", "parallel_coordinate", "slice", "contour")

#: Trees of the fANOVA forest (Optuna's default: 64).
FANOVA_TREES = 16

#: Most parameters on the slice and parallel-coordinate figures.
MAX_PARAMS = 4

#: Fewest complete trials for a contour figure.
MIN_CONTOUR_TRIALS = 10


@dataclass
class StudyFigures:
    """A study's Optuna figures, its importances table, and why any figure is missing.

    Attributes
    ----------
    figures : dict of str to Figure
        Name (of :data:`FIGURES`) -> figure.
    importances : DataFrame
        Columns ``param``, ``importance`` (fANOVA, summing to 1), most important first;
        empty when they could not be computed.
    skipped : dict of str to str
        Name -> why Optuna could not draw it.
    """

    figures: dict[str, Figure] = field(default_factory=dict)
    importances: pd.DataFrame = field(
        default_factory=lambda: pd.DataFrame(columns=["param", "importance"]))
    skipped: dict[str, str] = field(default_factory=dict)


def _pyplot() -> Any:
    """Import pyplot, on the Agg backend unless the process loaded it already."""
    if "matplotlib.pyplot" not in sys.modules:
        import matplotlib

        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _importances(study: optuna.Study, seed: int) -> dict[str, float]:
    """Compute the study's fANOVA importances (seeded), most important first."""
    import optuna

    evaluator = optuna.importance.FanovaImportanceEvaluator(n_trees=FANOVA_TREES, seed=seed)
    return optuna.importance.get_param_importances(study, evaluator=evaluator)


def _fixed_evaluator(values: dict[str, float]) -> Any:
    """Make an importance evaluator that returns ``values`` (computed once, drawn twice)."""
    import optuna

    class Fixed(optuna.importance.BaseImportanceEvaluator):
        def evaluate(self, study: optuna.Study, params: list[str] | None = None, *,
                     target: Callable[..., float] | None = None) -> dict[str, float]:
            return dict(values)

    return Fixed()


def _draw(name: str, plot: Callable[[], Any], out: StudyFigures) -> None:
    """Draw one figure with ``plot()`` (Optuna's), or record why it failed."""
    try:
        ax = plot()
    except (ValueError, RuntimeError) as exc:
        out.skipped[name] = f"{type(exc).__name__}: {exc}"
        return
    first = ax.flat[0] if hasattr(ax, "flat") else ax  # slice and contour: an array of axes
    out.figures[name] = first.get_figure()


def _reasons(n_complete: int, importances: dict[str, float]) -> dict[str, str]:
    """Say which figures cannot be drawn, and why, before Optuna is asked."""
    reasons: dict[str, str] = {}
    if n_complete == 0:
        return {name: "no complete trial" for name in FIGURES}
    if n_complete < 2:
        reasons["importances"] = reasons["contour"] = "fewer than 2 complete trials"
    elif len(importances) < 2:
        reasons["contour"] = (f"{len(importances)} parameter(s) common to every complete "
                              "trial; a contour needs 2")
    if n_complete < MIN_CONTOUR_TRIALS:
        reasons.setdefault("contour", f"{n_complete} complete trial(s); a contour needs "
                                      f"{MIN_CONTOUR_TRIALS}")
    return reasons


def study_figures(study: optuna.Study, seed: int,
                  target_name: str = "Objective Value") -> StudyFigures:
    """Draw a study's Optuna figures and tabulate its parameter importances.

    Parameters
    ----------
    study : optuna.Study
        A finished study (single objective).
    seed : int
        The fANOVA forest's seed (the config's ``random_state``): the same trials give the
        same importances.
    target_name : str, default="Objective Value"
        The objective's label on the figures' axes and colour bars.

    Returns
    -------
    StudyFigures
        The figures drawn, the importances, and the reasons for those skipped.
    """
    import optuna
    from optuna.exceptions import ExperimentalWarning
    from optuna.trial import TrialState

    plt = _pyplot()
    vis = optuna.visualization.matplotlib
    out = StudyFigures()
    n_complete = len(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)))
    values: dict[str, float] = {}
    if n_complete >= 2:
        try:
            values = _importances(study, seed)
        except (ValueError, RuntimeError) as exc:
            out.skipped["importances"] = f"{type(exc).__name__}: {exc}"
    out.skipped.update(_reasons(n_complete, values))
    if values:
        out.importances = pd.DataFrame({"param": list(values),
                                        "importance": list(values.values())})
    fixed = _fixed_evaluator(values)
    shown = list(values)[:MAX_PARAMS] or None
    plots: dict[str, Callable[[], Any]] = {
        "history": lambda: vis.plot_optimization_history(study, target_name=target_name),
        "importances": lambda: vis.plot_param_importances(study, evaluator=fixed),
        "parallel_coordinate": lambda: vis.plot_parallel_coordinate(study, params=shown,
                                                                    target_name=target_name),
        "slice": lambda: vis.plot_slice(study, params=shown, target_name=target_name),
        "contour": lambda: vis.plot_contour(study, params=list(values)[:2],
                                            target_name=target_name),
    }
    with warnings.catch_warnings(), plt.rc_context({"figure.max_open_warning": 0}):
        warnings.simplefilter("ignore", ExperimentalWarning)
        warnings.filterwarnings("ignore", "Attempting to set identical", UserWarning)
        for name, plot in plots.items():
            if name not in out.skipped:
                _draw(name, plot, out)
    return out
