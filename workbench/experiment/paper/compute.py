"""The reproduction's own fits.

The paper settings' learning curves and the SHAP summaries of their correction, the tabula
rasa MLPs on the voltages, and the parameter-space model's settings.

Each function fits, draws its figures through ``save(fig_id, figure, name)`` (which writes the
file and files it under the paper's figure id) and returns the numbers the report and the
MLflow runs show.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor
from sklearn.pipeline import Pipeline, make_pipeline

from ...bases import NormalQuantileTransformer
from ...curves import learning_curve_plan
from ...datasets import Dataset
from ...parallel import Task, map_tasks, run_plans
from ..bootstrap import bootstrap_error_interval
from ..config import ExperimentConfig, without_intervals
from ..explain import shap_values, target_shap_values
from ..figures import correction_shap_figure, learning_curve_figure, save_figure, shap_figure
from ..intervals import family_model

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["PAPER_SIZES", "SHORT", "TABULA_RASA", "TABULA_RASA_SEEDS", "SameAs", "Save",
           "correction_shap", "figure_saver", "hamiltonian_config", "learning_curves",
           "say", "seeded", "start_clock", "tabula_rasa_system"]

#: The paper's short names of the five eigenenergies.
SHORT = ["Y1", "Y2", "Y3", "Y4", "Y5"]
#: The paper's learning-curve training sizes (23 ... 95 training rows).
PAPER_SIZES = [23, 33, 43, 54, 64, 74, 85, 95]
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


def say(text: str) -> None:
    """Log a progress line with the seconds since :func:`start_clock`.

    Parameters
    ----------
    text : str
        The line.
    """
    logging.getLogger("workbench").info("[reproduce %5.0f s] %s", time.perf_counter() - _T0[0],
                                        text)


def seeded(cfg: ExperimentConfig, seed: int) -> ExperimentConfig:
    """Seed a config and turn off its intervals, as every evaluation of the reproduction.

    The reproduction reports the paper's errors, and CV+ would refit every model 5 more times
    (``workbench evaluate`` reports the intervals; ``python benchmarks/intervals.py`` measures
    them).

    Parameters
    ----------
    cfg : ExperimentConfig
        The config as loaded.
    seed : int
        Its ``random_state``.

    Returns
    -------
    ExperimentConfig
        The copy the reproduction evaluates.
    """
    return without_intervals(replace(cfg, random_state=seed))


def hamiltonian_config(cfg: ExperimentConfig, seed: int, quick: bool) -> ExperimentConfig:
    """Set up ``experiments/hamiltonian.toml`` as the reproduction evaluates it.

    Its nested CV over all rows (its longest part: it redoes the selection in each outer
    fold) is left to ``workbench evaluate experiments/hamiltonian.toml``; quick mode also uses a
    smaller pool and one CV repeat.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config as loaded (family ``hamiltonian``).
    seed : int
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
                  seed)


def learning_curves(paper_cfg: ExperimentConfig, ds: Dataset, seed: int, quick: bool,
                    save: Save, same_as: SameAs) -> dict[str, Any]:
    """Compute and draw the paper settings' augmented learning curves.

    Fig. S5, one panel per target; Fig. 4 is its Y3 panel.

    Parameters
    ----------
    paper_cfg : ExperimentConfig
        The paper settings as loaded (``experiments/paper_main_body.toml``); its family builds
        each target's candidate.
    ds : Dataset
        The Google 5-qubit data.
    seed : int
        Seeds the folds.
    quick : bool
        Two sizes (the smallest and the largest) instead of every paper size.
    save, same_as
        File the figures (see :data:`Save`, :data:`SameAs`).

    Returns
    -------
    dict
        ``train_sizes``, ``folds`` and the ``curves`` (short target name -> the curve's JSON).
    """
    X_train, _, y_train, _ = ds.split()
    folds = 5
    largest = len(X_train) - -(-len(X_train) // folds)
    sizes = [s for s in PAPER_SIZES if s <= largest]
    sizes = sorted(set(sizes + [largest]))
    if quick:  # the curve's two ends: a third fewer fits, the largest size still checked
        sizes = [sizes[0], sizes[-1]]
    say(f"augmented learning curves at training sizes {sizes} "
        f"(5-fold CV on the training rows: at most {largest} rows)")
    model = paper_cfg.family.build(paper_cfg, ds)
    candidates = [model.target_estimators[t].estimator for t in ds.target_names]
    # the five curves' (size, fold) fits share the worker processes (every core)
    fitted = run_plans([learning_curve_plan(est, X_train, y_train[target].to_numpy(),
                                            train_sizes=sizes, cv=folds, random_state=seed)
                        for target, est in zip(ds.target_names, candidates)], -1)
    curves = {}
    for j, (target, curve) in enumerate(zip(ds.target_names, fitted)):
        curves[SHORT[j]] = curve.to_dict()
        fig = learning_curve_figure(curve, target=f"{SHORT[j]} ({target})", unit=ds.unit,
                                    setting="paper settings")
        path = save("figS5_learning_curves", fig, f"figS5_learning_curve_{SHORT[j]}")
        if SHORT[j] == "Y3":
            same_as("fig4_learning_curve_Y3", path)
    return {"train_sizes": sizes, "folds": folds, "curves": curves}


def correction_shap(model: Any, ds: Dataset, seed: int, quick: bool, save: Save) -> None:
    """Draw, per target, the SHAP summaries of what the paper settings learned.

    The correction (model − prior) beside the whole prediction, on the training rows (figures
    ``figR2_shap_correction`` and ``figR3_shap_prediction``), computed on the workers.

    Parameters
    ----------
    model : estimator
        The paper settings' fitted model (as ``evaluate`` returns it).
    ds : Dataset
        The data it was fitted on.
    seed : int
        Seeds the SHAP background and the beeswarms.
    quick : bool
        Explain 30 training rows instead of all.
    save : Save
        Files the figures.
    """
    say("SHAP of the paper settings' correction (model − prior) and whole prediction")
    X_train = ds.split()[0]
    rows = X_train.iloc[:30] if quick else X_train
    estimators = family_model(model).estimators_
    done = map_tasks([Task(target_shap_values, est, rows, random_state=seed)
                      for est in estimators], -1)
    for j, (target, shap) in enumerate(zip(ds.target_names, done)):
        name = f"{SHORT[j]} ({target})"
        save("figR2_shap_correction", correction_shap_figure(
            shap.correction, target=name, unit=ds.unit, note=shap.note, random_state=seed,
            setting="paper settings"), f"figR2_shap_correction_{SHORT[j]}")
        assert shap.prediction is not None  # computed: prediction=True
        save("figR3_shap_prediction", shap_figure(
            shap.prediction.values, shap.prediction.expected, shap.prediction.rows,
            target=name, unit=ds.unit, random_state=seed, setting="paper settings",
            explained="prediction"), f"figR3_shap_prediction_{SHORT[j]}")


def _tabula_rasa(j: int, seed: int) -> Pipeline:
    """Build target ``j``'s tabula rasa model: normal quantiles of the voltages, an MLP.

    The voltages mapped to normal quantiles, then the paper's MLP.

    The reference's ``Regressor`` puts the same transform before every model by default
    (``pipeline_transform="quantilenormal"``); without it the voltages' scale (standard
    deviations 0.006 to 0.1) against the penalty alpha = 13 to 19 leaves the MLP near a
    constant (about 19.8 MHz average test MAE for every seed, against about 11 with it).
    """
    hidden, alpha, max_iter = TABULA_RASA[j]
    return make_pipeline(
        NormalQuantileTransformer(random_state=seed),
        MLPRegressor(hidden_layer_sizes=hidden, activation="relu", solver="lbfgs",
                     alpha=alpha, max_iter=max_iter, random_state=seed))


def _tabula_rasa_target(j: int, seed: int, V_train: pd.DataFrame, y_train: pd.Series,
                        V_test: pd.DataFrame, y_test: pd.Series,
                        shap_rows: pd.DataFrame | None, background: int
                        ) -> tuple[np.ndarray | None, float | None, np.ndarray]:
    """Fit target ``j``'s tabula rasa MLP on the voltages.

    Returns (unless ``shap_rows`` is ``None``) the SHAP values and expected value of its
    predictions on ``shap_rows``, and its test residuals.
    """
    with warnings.catch_warnings():  # the paper's max_iter, kept as published
        warnings.simplefilter("ignore", ConvergenceWarning)
        mlp = _tabula_rasa(j, seed).fit(V_train.to_numpy(), y_train.to_numpy())
    err = y_test.to_numpy() - mlp.predict(V_test.to_numpy())
    values = expected = None
    if shap_rows is not None:
        values, expected = shap_values(lambda a: mlp.predict(a), shap_rows,
                                       background_size=background, random_state=seed)
    return values, expected, err


def tabula_rasa_system(ds: Dataset, seed: int, quick: bool, save: Save,
                       same_as: SameAs) -> dict[str, Any]:
    """Fit the tabula rasa MLPs over :data:`TABULA_RASA_SEEDS` seeds and draw their SHAP.

    The seeds are ``seed``, ``seed + 1``, ...; the SHAP summaries (Fig. S8; Fig. 5 is its Y1
    panel) are the first seed's MLPs'.

    Parameters
    ----------
    ds : Dataset
        The Google 5-qubit data (the MLPs see its voltages only).
    seed : int
        The first seed.
    quick : bool
        3 seeds, 30 SHAP rows and a background of 10.
    save, same_as
        File the figures.

    Returns
    -------
    dict
        Per target the mean test MAE and MSE over the seeds with their bootstrap intervals,
        each seed's errors and average, the average's spread over the seeds.
    """
    n_seeds = 3 if quick else TABULA_RASA_SEEDS
    seeds = list(range(seed, seed + n_seeds))
    say(f"tabula rasa MLPs on the 9 voltages ({n_seeds} seeds), SHAP summaries")
    X_train, X_test, y_train, y_test = ds.split()
    targets = ds.target_names
    V_train, V_test = X_train[ds.feature_names], X_test[ds.feature_names]
    shap_rows = V_train.iloc[:30] if quick else V_train
    background = 10 if quick else 50
    # one task per (target, seed) on the workers (fit, test errors; SHAP for the first seed)
    tasks = [Task(_tabula_rasa_target, j, s, V_train, y_train[target], V_test, y_test[target],
                  shap_rows if s == seed else None, background)
             for s in seeds for j, target in enumerate(targets)]
    done = map_tasks(tasks, -1)
    # test residuals, seeds x targets x rows
    errors = np.array([d[2] for d in done]).reshape(n_seeds, len(targets), -1)
    per_seed = np.abs(errors).mean(axis=2)  # seeds x targets
    per_seed_mse = (errors ** 2).mean(axis=2)
    # per test row and target, the seeds' mean absolute and root mean squared error: their
    # bootstrap over rows is that of the seed-averaged MAE and MSE
    mae_ci = bootstrap_error_interval(np.abs(errors).mean(axis=0).T, random_state=seed)
    mse_ci = bootstrap_error_interval(np.sqrt((errors ** 2).mean(axis=0)).T, squared=True,
                                      random_state=seed)
    for j, target in enumerate(targets):
        values, expected, _ = done[j]  # the first seed's
        path = save("figS8_shap", shap_figure(
            values, expected, shap_rows, target=f"{SHORT[j]} ({target})", unit=ds.unit,
            random_state=seed, setting="MLP on the 9 voltages"), f"figS8_shap_{SHORT[j]}")
        if SHORT[j] == "Y1":
            same_as("fig5_shap_Y1", path)
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
