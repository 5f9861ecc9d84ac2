"""The reproduction's phases beside the paper settings.

``reproduce`` starts the serial ones on the worker processes first
(:func:`workbench.parallel.start`, the longest first): the parameter-space model (with its
figures and tables), the improved settings and with ``--all`` the IBM benchmark. Each runs
serially in its worker (one BLAS/OpenMP thread) and returns what the reproduction keeps of
it, with its :class:`~.systems.Stopwatch`. The tabula rasa MLPs are a plan
(:func:`tabula_rasa_plan`): their fits, SHAP values and figures share the other workers with
the paper settings' curves and SHAP. Every random component is seeded, so the numbers are
those of running it in the main process. Without worker processes, everything runs there,
in turn."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor
from sklearn.pipeline import Pipeline, make_pipeline

from ...bases import NormalQuantileTransformer
from ...datasets import Dataset
from ...parallel import Plan, Task
from ..config import ExperimentConfig
from ..figures import error_bars, model_comparison_bars, save_figure, shap_figure
from ..runs.evaluate import evaluate
from ..runs.intervals import family_model
from ..scoring.bootstrap import bootstrap_error_interval
from ..scoring.explain import shap_values
from ..scoring.results import Result
from ..scoring.units import squared
from ..tracking.serving import prediction_frame
from .compute import (
    SHORT,
    TABULA_RASA,
    TABULA_RASA_SEEDS,
    figure_saver,
    say,
    set_clock,
)
from .systems import Stopwatch

__all__ = ["Phase", "draw_tabula_rasa", "evaluate_phase", "hamiltonian_phase",
           "tabula_rasa_plan", "timed"]

#: The tabula rasa MLPs against the paper settings: metric -> (figure id, the paper's figure).
TABULA_RASA_FIGURES = {"mae": ("figS6_tabula_rasa_mae", "S6"),
                       "mse": ("figS7_tabula_rasa_mse", "S7")}
#: The parameter-space model's setting, as its figures name it.
HAMILTONIAN_SETTING = "experiments/hamiltonian.toml"


@dataclass
class Phase:
    """What a phase computed.

    Parameters
    ----------
    watch : Stopwatch
        Its start and end.
    result : Result, optional
        An evaluated system's result.
    predictions : DataFrame, optional
        Its test rows' predictions (one column per target).
    files : dict of str to list of Path
        The figures it wrote, by figure id.
    tables : dict of str to Path
        The tables it wrote, by name.
    numbers : dict
        Other numbers (the tabula rasa MLPs').
    """

    watch: Stopwatch
    result: Result | None = None
    predictions: pd.DataFrame | None = None
    files: dict[str, list[Path]] = field(default_factory=dict)
    tables: dict[str, Path] = field(default_factory=dict)
    numbers: dict[str, Any] = field(default_factory=dict)


def timed(clock: float, func: Callable[..., Any], *args: Any) -> Any:
    """Call ``func(*args)`` with the progress lines timed from ``clock`` (:func:`.compute.say`).

    A worker process was forked before the reproduction started its clock.

    Parameters
    ----------
    clock : float
        The reproduction's start, on :func:`time.perf_counter`'s clock (system-wide).
    func : callable
        The phase.
    *args
        Its arguments.

    Returns
    -------
    object
        What ``func`` returns.
    """
    set_clock(clock)
    return func(*args)


def _evaluated(cfg: ExperimentConfig, ds: Dataset, phase: Phase) -> Any:
    """Evaluate ``cfg`` on ``ds`` into ``phase`` (result, test predictions); returns the run."""
    run = evaluate(cfg, return_model=True, dataset=ds)
    X_test = ds.split(cfg.family.inputs(cfg, ds))[1]
    phase.result = run.result
    phase.predictions = prediction_frame(run.model, X_test, run.result.targets)
    return run


def evaluate_phase(cfg: ExperimentConfig, ds: Dataset) -> Phase:
    """Evaluate a system (the improved settings): its result and test predictions.

    Parameters
    ----------
    cfg : ExperimentConfig
        The seeded config (:func:`.compute.seeded`).
    ds : Dataset
        Its data, loaded once by the reproduction.

    Returns
    -------
    Phase
        The result, the predictions and the time.
    """
    phase = Phase(Stopwatch())
    with phase.watch:
        _evaluated(cfg, ds, phase)
    return phase


def hamiltonian_phase(cfg: ExperimentConfig, ds: Dataset, out: Path) -> Phase:
    """Evaluate the parameter-space model and write its figures (H1-H3) and tables.

    Parameters
    ----------
    cfg : ExperimentConfig
        ``experiments/hamiltonian.toml`` as the reproduction runs it
        (:func:`.compute.hamiltonian_config`).
    ds : Dataset
        The Google data.
    out : Path
        The report folder (figures under ``figures/``, tables under ``hamiltonian/``).

    Returns
    -------
    Phase
        The result, predictions, figures, tables and time.
    """
    phase = Phase(Stopwatch())
    with phase.watch:
        run = _evaluated(cfg, ds, phase)
        save, _ = figure_saver(out / "figures", phase.files)
        save("figH1_hamiltonian_mae_bars", error_bars(
            run.result, "MAE", targets=SHORT, unit=ds.unit,
            labels=("control program", "parameter-space model"),
            title="Test MAE per eigenenergy: corrected Hamiltonian", setting=HAMILTONIAN_SETTING))
        outputs = cfg.family.outputs(family_model(run.model), ds, setting=HAMILTONIAN_SETTING)
        save("figH2_parameter_corrections", outputs.figures["parameter_corrections"])
        save("figH3_selection_path", outputs.figures["selection_path"])
        phase.tables = outputs.write(out / "hamiltonian", figures=False)
    return phase


def _tabula_rasa(j: int, random_state: int) -> Pipeline:
    """Build target ``j``'s tabula rasa model: normal quantiles of the voltages, an MLP.

    The voltages mapped to normal quantiles, then the paper's MLP.

    The reference's ``Regressor`` puts the same transform before every model by default
    (``pipeline_transform="quantilenormal"``); without it the voltages' scale (standard
    deviations 0.006 to 0.1) against the penalty alpha = 13 to 19 leaves the MLP near a
    constant (about 19.8 MHz average test MAE for every seed, against about 11 with it).
    """
    hidden, alpha, max_iter = TABULA_RASA[j]
    return make_pipeline(
        NormalQuantileTransformer(random_state=random_state),
        MLPRegressor(hidden_layer_sizes=hidden, activation="relu", solver="lbfgs",
                     alpha=alpha, max_iter=max_iter, random_state=random_state))


def _tabula_rasa_target(j: int, random_state: int, V_train: pd.DataFrame, y_train: pd.Series,
                        V_test: pd.DataFrame, y_test: pd.Series,
                        shap_rows: pd.DataFrame | None, background: int
                        ) -> tuple[np.ndarray | None, float | None, np.ndarray]:
    """Fit target ``j``'s tabula rasa MLP on the voltages.

    Returns (unless ``shap_rows`` is ``None``) the SHAP values and expected value of its
    predictions on ``shap_rows``, and its test residuals.
    """
    with warnings.catch_warnings():  # the paper's max_iter, kept as published
        warnings.simplefilter("ignore", ConvergenceWarning)
        mlp = _tabula_rasa(j, random_state).fit(V_train.to_numpy(), y_train.to_numpy())
    err = y_test.to_numpy() - mlp.predict(V_test.to_numpy())
    values = expected = None
    if shap_rows is not None:
        # the quantile transform maps each column on its own, value by value: SHAP's
        # synthetic rows built from the transformed rows are the transforms of those built
        # from the rows, so the MLP sees the same inputs, and the transform (most of the
        # cost of 2^9 coalitions x the background per row) runs once per row instead
        transform, net = mlp[0], mlp[-1]
        rows = pd.DataFrame(transform.transform(shap_rows.to_numpy(dtype=float)),
                            columns=shap_rows.columns, index=shap_rows.index)
        values, expected = shap_values(lambda a: net.predict(a), rows,
                                       background_size=background, random_state=random_state)
    return values, expected, err


def tabula_rasa_plan(ds: Dataset, random_state: int, quick: bool, out: Path, paper: Result) -> Plan:
    """Plan the tabula rasa MLPs over :data:`TABULA_RASA_SEEDS` seeds and their SHAP figures.

    One task per (seed, target) (fit, test errors; SHAP values for the first seed), then one
    task per target drawing its SHAP summary (Fig. S8; Fig. 5 is its Y1 panel) and one per
    metric drawing them against the paper settings (Fig. S6, S7), so that they share the
    workers with the reproduction's other plans (:mod:`workbench.parallel`). The seeds are
    ``random_state``, ``random_state + 1``, ...; the summaries are the first seed's MLPs'.

    Parameters
    ----------
    ds : Dataset
        The Google 5-qubit data (the MLPs see its voltages only).
    random_state : int
        The first seed.
    quick : bool
        3 seeds, 30 SHAP rows and a background of 10.
    out : Path
        The report folder (figures under ``figures/``).
    paper : Result
        The paper settings' result (Fig. S6, S7).

    Returns
    -------
    Plan
        Returns a :class:`Phase`: in ``numbers``, per target the mean test MAE and MSE over
        the seeds with their bootstrap intervals, each seed's errors and average, the
        average's spread over the seeds; its figures and time.
    """
    phase = Phase(Stopwatch())
    with phase.watch:
        n_seeds = 3 if quick else TABULA_RASA_SEEDS
        seeds = list(range(random_state, random_state + n_seeds))
        say(f"tabula rasa MLPs on the 9 voltages ({n_seeds} seeds), SHAP summaries")
        X_train, X_test, y_train, y_test = ds.split()
        targets = ds.target_names
        V_train, V_test = X_train[ds.feature_names], X_test[ds.feature_names]
        shap_rows = V_train.iloc[:30] if quick else V_train
        background = 10 if quick else 50
        # one task per (target, seed) (fit, test errors; SHAP for the first seed), the SHAP
        # tasks (the longest) first
        tasks = [Task(_tabula_rasa_target, j, s, V_train, y_train[target], V_test,
                      y_test[target], shap_rows if s == random_state else None, background)
                 for s in seeds for j, target in enumerate(targets)]
        for task in tasks[:len(targets)]:
            task.priority = 10 ** 6
        done = yield tasks
        phase.numbers = _tabula_rasa_numbers(done, seeds, len(targets), random_state)
        figures = [Task(_tabula_rasa_figure, out / "figures", j, done[j][0], done[j][1],
                        shap_rows, target, ds.unit, random_state)
                   for j, target in enumerate(targets)]
        figures += [Task(draw_tabula_rasa, out / "figures", metric, ds.unit, paper,
                         phase.numbers) for metric in ("mae", "mse")]
        paths = yield figures
        for j, path in enumerate(paths[:len(targets)]):
            phase.files.setdefault("figS8_shap", []).append(path)
            if SHORT[j] == "Y1":
                phase.files.setdefault("fig5_shap_Y1", []).append(path)
        for metric, path in zip(("mae", "mse"), paths[len(targets):]):
            phase.files[TABULA_RASA_FIGURES[metric][0]] = [path]
    return phase


def _tabula_rasa_figure(figdir: Path, j: int, values: np.ndarray, expected: float,
                        shap_rows: pd.DataFrame, target: str, unit: str | None,
                        random_state: int) -> Path:
    """Draw and write target ``j``'s SHAP summary of its first-seed MLP (Fig. S8)."""
    return save_figure(shap_figure(values, expected, shap_rows, target=f"{SHORT[j]} ({target})",
                                   unit=unit, random_state=random_state,
                                   setting="MLP on the 9 voltages"),
                       figdir / f"figS8_shap_{SHORT[j]}.png")


def _tabula_rasa_numbers(done: list[Any], seeds: list[int], n_targets: int,
                         random_state: int) -> dict[str, Any]:
    """The tabula rasa MLPs' numbers from their (seed, target) tasks' results."""
    n_seeds = len(seeds)
    # test residuals, seeds x targets x rows
    errors = np.array([d[2] for d in done]).reshape(n_seeds, n_targets, -1)
    per_seed = np.abs(errors).mean(axis=2)  # seeds x targets
    per_seed_mse = (errors ** 2).mean(axis=2)
    # per test row and target, the seeds' mean absolute and root mean squared error: their
    # bootstrap over rows is that of the seed-averaged MAE and MSE
    mae_ci = bootstrap_error_interval(np.abs(errors).mean(axis=0).T, random_state=random_state)
    mse_ci = bootstrap_error_interval(np.sqrt((errors ** 2).mean(axis=0)).T, squared=True,
                                      random_state=random_state)
    avg = per_seed.mean(axis=1)
    return {"test_mae": per_seed.mean(axis=0).tolist(),
            "test_mse": per_seed_mse.mean(axis=0).tolist(),
            "seeds": seeds, "test_mae_per_seed": per_seed.tolist(),
            "test_mae_avg_per_seed": avg.tolist(),
            "test_mae_avg_min": float(avg.min()), "test_mae_avg_max": float(avg.max()),
            "test_mae_avg_sd": float(avg.std(ddof=1)) if n_seeds > 1 else 0.0,
            "test_mae_ci": [*mae_ci.per_target, mae_ci.average],
            "test_mse_ci": [*mse_ci.per_target, mse_ci.average],
            "input_transform": "quantile_normal"}


def draw_tabula_rasa(figdir: Path, metric: str, unit: str | None, paper: Result,
                     tabula: dict[str, Any]) -> Path:
    """Draw the tabula rasa MLPs against the paper settings (Fig. S6 or S7).

    Parameters
    ----------
    figdir : Path
        Where the figure goes.
    metric : {"mae", "mse"}
        The error: Fig. S6 (MAE) or S7 (MSE).
    unit : str, optional
        The data's unit.
    paper : Result
        The paper settings' result.
    tabula : dict
        The MLPs' numbers (:func:`tabula_rasa_plan`).

    Returns
    -------
    Path
        The file written.
    """
    fig_id, fig = TABULA_RASA_FIGURES[metric]
    name = f"tabula rasa MLP (voltages only, mean of {len(tabula['seeds'])} seeds)"
    values = {name: tabula[f"test_{metric}"],
              "control program": getattr(paper.prior, f"test_{metric}"),
              "base boosting (paper settings)": getattr(paper.model, f"test_{metric}")}
    intervals = {name: tabula[f"test_{metric}_ci"],
                 "control program": paper.prior.ci(f"test_{metric}"),
                 "base boosting (paper settings)": paper.model.ci(f"test_{metric}")}
    return save_figure(model_comparison_bars(
        SHORT, values, metric=metric.upper(), unit=unit if metric == "mae" else squared(unit),
        log=True, intervals={k: v for k, v in intervals.items() if v is not None},
        title=f"Tabula rasa vs base boosting, test {metric.upper()} (Fig. {fig})"),
        figdir / f"{fig_id}.png")
