"""The reproduction's systems.

The catalogue (:data:`SYSTEMS`), one :class:`System` per compared model in the metric schema
of ``evaluate``, and the summary table.

Every system's metrics use the keys of :func:`~workbench.experiment.runs.run_fields.score_metrics`
(``test_mae/<target>``, ``test_mae_avg``, ...), so MLflow's compare view lines the systems up
with each other and with any ``evaluate`` run of the same data (:mod:`.runs` logs them).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from ...datasets import Dataset
from ..config import ExperimentConfig
from ..runs.run_fields import result_metrics, run_params, score_metrics
from ..scoring.results import Result
from ..scoring.scores import Scores
from ..scoring.units import squared, unit_suffix
from .compute import TABULA_RASA

if TYPE_CHECKING:
    from ..sweep.search import Sweep

__all__ = ["SYSTEMS", "Stopwatch", "System", "paper_systems", "summary_table"]

#: The reproduction's systems: key -> the name of its MLflow run (and its table row), and the
#: description its run page shows.
SYSTEMS = {
    "prior": ("control program",
              "The control program's prediction of each eigenenergy (the prior), scored on the "
              "test rows: the incumbent every other system must beat."),
    "paper": ("base boosting, paper settings",
              "Base boosting with the paper's main-body settings "
              "(`experiments/paper_main_body.toml`): stacking basis, K = 1, squared-error "
              "residuals, absolute-error line search with penalty 0.1, inbuilt model "
              "selection by 5-fold CV. Figures: Fig. 2, S4 and the learning curves (S5; Fig. "
              "4 is its Y3 panel)."),
    "improved": ("base boosting, improved settings",
                 "Base boosting with the reference's improved settings "
                 "(`experiments/paper_improved.toml`): Huber losses, a ridge basis for Y3."),
    "search": ("nested-CV search",
               "The configuration chosen per target by the workbench's nested-CV search on the "
               "training rows (`experiments/paper_search.toml`); its children are the outer "
               "folds."),
    "hamiltonian": ("parameter-space model",
                    "The Hamiltonian parameter-space model (`experiments/hamiltonian.toml`): "
                    "corrected chain-Hamiltonian parameters, re-diagonalised. Figures H1-H3, "
                    "tables of coefficients and corrected parameters."),
    "tabula_rasa": ("tabula rasa MLP",
                    "An MLP on the 9 bias voltages alone (no prior; the paper's per-target "
                    "settings), the mean over several seeds. Figures S6, S7, S8 (Fig. 5 is "
                    "S8's Y1 panel)."),
}

#: Each system's own figures (ids of the reproduction's figures).
FIGURES = {"paper": ["fig2_mae_bars", "figS4_mse_bars", "figS5_learning_curves",
                     "figR2_shap_correction", "figR3_shap_prediction"],
           "hamiltonian": ["figH1_hamiltonian_mae_bars", "figH2_parameter_corrections",
                           "figH3_selection_path"],
           "tabula_rasa": ["figS6_tabula_rasa_mae", "figS7_tabula_rasa_mse", "figS8_shap"]}


@dataclass
class System:
    """One system of a reproduction, as its MLflow run will show it.

    Parameters
    ----------
    key, name : str
        Its key in the catalogue and its run's name.
    started, ended : float
        Seconds since the epoch around the system's own work.
    metrics : dict
        Its metrics in the shared schema.
    params : dict
        Its run's params.
    config : ExperimentConfig, optional
        The experiment config it ran (``None``: no config, as for the control program).
    result : Result, optional
        Logged as ``result.json``.
    figures, tables : list of Path
        Files to log under ``figures/`` and ``tables/``.
    sweep : Sweep, optional
        A sweep whose outer folds become the run's children.
    predictions : DataFrame, optional
        Its test rows' predictions (one column per target), logged with the measured
        targets for ``workbench compare``.
    description : str
        The run page's description (Markdown).
    """

    key: str
    name: str
    started: float
    ended: float
    metrics: dict[str, float] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)
    config: ExperimentConfig | None = None
    result: Result | None = None
    figures: list[Path] = field(default_factory=list)
    tables: list[Path] = field(default_factory=list)
    sweep: Sweep | None = None
    predictions: pd.DataFrame | None = None
    description: str = ""

    @property
    def seconds(self) -> float:
        """The seconds the system's work took."""
        return self.ended - self.started


class Stopwatch:
    """``with watch: ...`` records the block's start and end.

    :attr:`started` and :attr:`ended` are seconds since the epoch (NaN before).
    """

    def __init__(self) -> None:
        self.started = self.ended = float("nan")

    def __enter__(self) -> Stopwatch:
        """Record the start."""
        self.started = time.time()
        return self

    def __exit__(self, *exc: object) -> None:
        """Record the end."""
        self.ended = time.time()


def _tabula_rasa_metrics(targets: list[str], tabula: dict[str, Any]) -> dict[str, float]:
    """Write the tabula rasa MLPs' metrics: the shared keys and the spread over the seeds."""
    scores = Scores(tabula["test_mae"], tabula["test_mse"], [], [])
    return {**score_metrics(targets, scores),
            "test_mae_avg_min_over_seeds": tabula["test_mae_avg_min"],
            "test_mae_avg_max_over_seeds": tabula["test_mae_avg_max"],
            "test_mae_avg_sd_over_seeds": tabula["test_mae_avg_sd"],
            "test_mae_avg_ci_low": tabula["test_mae_ci"][-1][0],
            "test_mae_avg_ci_high": tabula["test_mae_ci"][-1][1]}


def paper_systems(settings: dict[str, Result], cfgs: dict[str, ExperimentConfig],
                  tabula: dict[str, Any], search: Sweep | None,
                  watches: dict[str, Stopwatch],
                  files: dict[str, list[Path]], tables: dict[str, list[Path]],
                  ds: Dataset) -> list[System]:
    """Gather the reproduction's systems (:data:`SYSTEMS`) in the shared schema.

    Parameters
    ----------
    settings : dict of str to Result
        The results of the evaluated systems (paper, improved, search, hamiltonian).
    cfgs : dict of str to ExperimentConfig
        Their configs, as run.
    tabula : dict
        The tabula rasa MLPs' numbers (:func:`.phases.tabula_rasa_system`).
    search : Sweep or None
        The nested-CV search (``None``: not run, and no system of it).
    watches : dict of str to Stopwatch
        Each system's time.
    files : dict of str to list of Path
        The reproduction's figures by id.
    tables : dict of str to list of Path
        A system's tables by its key.
    ds : Dataset
        The Google 5-qubit data (its targets and unit).

    Returns
    -------
    list of System
        One per catalogue entry that was run, in its order.
    """
    paper = settings["paper"]
    targets = ds.target_names
    unit = f"errors in{unit_suffix(ds.unit)} (MSE in{unit_suffix(squared(ds.unit))})" \
        if ds.unit else "errors in the targets' units (MSE squared)"
    out = []
    for key, (name, description) in SYSTEMS.items():
        if key == "search" and search is None:  # `reproduce --all` only
            continue
        watch = watches[key]
        system = System(key, name, watch.started, watch.ended,
                        description=f"{description} Test rows scored once; {unit}.",
                        figures=[p for f in FIGURES.get(key, []) for p in files[f]])
        if key == "prior":  # scored with the paper settings: no work of its own
            system.started = system.ended = watches["paper"].ended
            system.metrics = score_metrics(targets, paper.prior)
            system.params = {"system": "control program", "n_train": paper.n_train,
                             "n_test": paper.n_test}
        elif key == "tabula_rasa":
            system.metrics = _tabula_rasa_metrics(targets, tabula)
            system.params = {"random_states": ",".join(map(str, tabula["seeds"])),
                             "inputs": "the 9 bias voltages",
                             "input_transform": tabula["input_transform"],
                             **{f"{t}.{k}": v for t, spec in zip(targets, TABULA_RASA)
                                for k, v in zip(("hidden_layer_sizes", "alpha", "max_iter"),
                                                spec)}}
        else:
            result, cfg = settings[key], cfgs[key]
            system.config, system.result = cfg, result
            system.metrics = result_metrics(result, wall=False)
            system.params = run_params(cfg, targets, result.n_train, result.n_test)
            if key == "search":
                system.sweep = search
            system.tables = tables.get(key, [])
        out.append(system)
    return out


def summary_table(targets: list[str], systems: list[System]) -> pd.DataFrame:
    """Tabulate the systems' test MAE.

    Parameters
    ----------
    targets : list of str
        The targets' names.
    systems : list of System
        The systems.

    Returns
    -------
    pandas.DataFrame
        One row per system: its test MAE per target and on average (the shared metric keys,
        to 4 decimals), and its seconds.
    """
    rows = []
    for system in systems:
        row: dict[str, Any] = {"system": system.name}
        for t in targets:
            row[t] = system.metrics.get(f"test_mae/{t}", float("nan"))
        row["average"] = system.metrics.get("test_mae_avg", float("nan"))
        row = {k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}
        row["seconds"] = round(system.seconds, 1)
        rows.append(row)
    return pd.DataFrame(rows)
