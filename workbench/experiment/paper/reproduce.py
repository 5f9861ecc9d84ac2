"""``workbench reproduce``: every result and figure of the paper from the Google 5-qubit data.

Writes PNG figures, ``results.json``, ``systems.csv`` (test MAE of every system),
``manifest.json`` (figure id -> file(s)) and a ``README.md`` report under the output folder,
and logs the same numbers and figures to the MLflow experiment ``paper-reproduction``: a parent
run with one child run per system (:data:`~.systems.SYSTEMS`, logged by :mod:`.runs` in the
metric schema of ``evaluate``). Every number in a figure comes from the same dictionaries that
are written to JSON and MLflow. Each config is read once, and each system's data loaded once.
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pandas as pd
from sklearn.exceptions import ConvergenceWarning

from ..._io import atomic_write
from ...datasets import Dataset
from ..config import (
    ExperimentConfig,
    check_training_rows,
    data_key,
    load_dataset,
    without_intervals,
)
from ..errors import UsageError
from ..evaluate import evaluate
from ..figures import (
    correlation_heatmap,
    mae_bars,
    model_comparison_bars,
    prior_target_boxplots,
    voltage_boxplots,
)
from ..intervals import family_model
from ..prepare import load_config
from ..results import Result
from ..serving import prediction_frame
from ..sweep.search import Sweep, run_sweep
from ..units import squared
from .compute import (
    SHORT,
    SameAs,
    Save,
    correction_shap,
    figure_saver,
    hamiltonian_config,
    learning_curves,
    say,
    seeded,
    start_clock,
    tabula_rasa_system,
)
from .gates import gate_systems, gates_benchmark, gates_figure
from .report import report
from .reproduction import Reproduction
from .runs import log_reproduction
from .systems import SYSTEMS, Stopwatch, System, paper_systems, summary_table

__all__ = ["CONFIGS", "experiments_dir", "reproduce"]

#: The source checkout the package may have been imported from (an installed wheel's
#: site-packages has no ``experiments/``).
CHECKOUT = Path(__file__).resolve().parents[3]
#: The configs the reproduction runs, read from an experiments folder.
CONFIGS = ("paper_main_body.toml", "paper_improved.toml", "paper_search.toml",
           "hamiltonian.toml")


def experiments_dir(explicit: str | Path | None = None) -> Path:
    """Find the folder holding the reproduction's :data:`CONFIGS`.

    Parameters
    ----------
    explicit : str or Path, optional
        The folder to use (``--experiments``).

    Returns
    -------
    Path
        ``explicit`` if given, else the ``experiments/`` of the checkout the package runs
        from, else ``./experiments`` (an installed wheel carries no configs).

    Raises
    ------
    UsageError
        If the folder lacks a config; the message names what is missing.
    """
    folders = ([Path(explicit)] if explicit is not None
               else [CHECKOUT / "experiments", Path.cwd() / "experiments"])
    for folder in folders:
        if all((folder / name).is_file() for name in CONFIGS):
            return folder
    shown = folders[0] if explicit is not None else Path("experiments")
    missing = [n for n in CONFIGS if not (folders[-1] / n).is_file()]
    raise UsageError(f"reproduce reads its configs from {shown}/, which lacks "
                     f"{', '.join(missing)}; run it from a workbench checkout or pass "
                     "--experiments DIR")


@dataclass
class _Job:
    """A reproduction under way.

    Its settings, the figures written and each system's stopwatch, result and config as they
    come.
    """

    out: Path
    configs: Path
    seed: int
    quick: bool
    files: dict[str, list[Path]] = field(default_factory=dict)
    watches: dict[str, Stopwatch] = field(
        default_factory=lambda: {key: Stopwatch() for key in SYSTEMS})
    settings: dict[str, Result] = field(default_factory=dict)
    cfgs: dict[str, ExperimentConfig] = field(default_factory=dict)
    datasets: dict[str, Dataset] = field(default_factory=dict)
    predictions: dict[str, pd.DataFrame] = field(default_factory=dict)
    save: Save = field(init=False)
    same_as: SameAs = field(init=False)

    def __post_init__(self) -> None:
        (self.out / "figures").mkdir(parents=True, exist_ok=True)
        self.save, self.same_as = figure_saver(self.out / "figures", self.files)

    def evaluate(self, key: str, cfg: ExperimentConfig) -> Any:
        """Evaluate the system ``key`` with ``cfg`` (as loaded), seeded, without intervals."""
        say(f"evaluating the {key} settings ({Path(cfg.path or cfg.name).name})")
        self.cfgs[key] = seeded(cfg, self.seed)
        run = evaluate(self.cfgs[key], return_model=True, dataset=self.dataset(self.cfgs[key]))
        self.settings[key] = run.result
        self.keep_predictions(key, self.cfgs[key], run)
        return run

    def keep_predictions(self, key: str, cfg: ExperimentConfig, run: Any) -> None:
        """Keep a system's test predictions (and, for the paper settings, the prior's)."""
        ds = run.dataset
        X_test = ds.split(cfg.family.inputs(cfg, ds))[1]
        self.predictions[key] = prediction_frame(run.model, X_test, run.result.targets)
        if key == "paper":
            prior = ds.prior.loc[X_test.index, ds.prior_names]
            self.predictions["prior"] = prior.set_axis(ds.target_names, axis=1)

    def dataset(self, cfg: ExperimentConfig) -> Dataset:
        """Load the dataset of ``cfg`` once per ``[data]`` table (:func:`data_key`).

        The Google benchmark's systems share one load; each config's folds and intervals
        are still checked against the training rows.
        """
        key = data_key(cfg)
        if key not in self.datasets:
            self.datasets[key] = load_dataset(cfg)
        else:
            check_training_rows(cfg, len(self.datasets[key].train_index))
        return self.datasets[key]


def _error_bars(save: Save, fig_id: str, result: Result, unit: str | None, **kwargs: Any
                ) -> None:
    """Draw a result's test MAE (or, with ``metric="MSE"``, MSE) bars as ``fig_id``.

    The prior is the control program (the Google data's name of it) unless ``labels`` say.
    """
    kwargs.setdefault("labels", ("control program", "base boosting"))
    key = f"test_{kwargs.get('metric', 'MAE').lower()}"
    save(fig_id, mae_bars(SHORT, getattr(result.prior, key), getattr(result.model, key),
                          prior_ci=result.prior.ci(key), model_ci=result.model.ci(key),
                          unit=unit, **kwargs))


def _paper(job: _Job) -> tuple[Dataset, dict[str, Any]]:
    """Run the paper settings with their figures and learning curves, then the improved ones.

    Returns the Google data and the learning curves.
    """
    with job.watches["paper"]:
        paper_cfg = load_config(job.configs / "paper_main_body.toml")
        run = job.evaluate("paper", paper_cfg)
        ds: Dataset = run.dataset
        paper = run.result
        _error_bars(job.save, "fig2_mae_bars", paper, ds.unit,
                    title="Test MAE per eigenenergy (Fig. 2)", setting="paper settings")
        _error_bars(job.save, "figS4_mse_bars", paper, squared(ds.unit), metric="MSE",
                    title="Test MSE per eigenenergy (Fig. S4)", setting="paper settings")
        correction_shap(run.model, ds, job.seed, job.quick, job.save)
        curves = learning_curves(paper_cfg, ds, job.seed, job.quick, job.save, job.same_as)
    with job.watches["improved"]:
        job.evaluate("improved", load_config(job.configs / "paper_improved.toml"))
    return ds, curves


def _search(job: _Job, storage: str | None) -> Sweep:
    """Run the workbench's own nested-CV search (``experiments/paper_search.toml``)."""
    say("nested-CV search for the workbench's own best configuration "
        "(experiments/paper_search.toml)")
    cfg = load_config(job.configs / "paper_search.toml")
    cv = {"seed": job.seed, **({"outer_folds": 2, "inner_folds": 3} if job.quick else {})}
    cfg = without_intervals(replace(cfg, random_state=job.seed,
                                    cv=cfg.cv.model_copy(update=cv)))
    # another seed, or --quick (other folds and budgets), must not resume these studies
    cfg = cfg.with_study(study_name=f"{cfg.name}-seed{job.seed}{'-quick' if job.quick else ''}",
                         trials=2 if job.quick else None, storage=storage)
    with job.watches["search"], warnings.catch_warnings():
        # a candidate basis's convergence notes: not the user's
        warnings.simplefilter("ignore", ConvergenceWarning)
        # a line per trial: the longest phase
        search = run_sweep(cfg, progress=True, dataset=job.dataset(cfg))
    job.settings["search"], job.cfgs["search"] = search.result, cfg
    return search


def _hamiltonian(job: _Job, ds: Dataset) -> tuple[dict[str, str], list[Path]]:
    """Run the parameter-space model and write its figures and tables.

    Returns the tables (name -> file relative to the report folder) and their files.
    """
    setting = "experiments/hamiltonian.toml"
    with job.watches["hamiltonian"]:
        cfg = hamiltonian_config(load_config(job.configs / "hamiltonian.toml"), job.seed,
                                 job.quick)
        say("the parameter-space model (experiments/hamiltonian.toml): covariate "
            "selection by CV on the training rows")
        run = evaluate(cfg, return_model=True, dataset=job.dataset(cfg))
        job.settings["hamiltonian"], job.cfgs["hamiltonian"] = run.result, cfg
        job.keep_predictions("hamiltonian", cfg, run)
        _error_bars(job.save, "figH1_hamiltonian_mae_bars", run.result, ds.unit,
                    labels=("control program", "parameter-space model"),
                    title="Test MAE per eigenenergy: corrected Hamiltonian", setting=setting)
        outputs = cfg.family.outputs(family_model(run.model), ds, setting=setting)
        job.save("figH2_parameter_corrections", outputs.figures["parameter_corrections"])
        job.save("figH3_selection_path", outputs.figures["selection_path"])
        written = outputs.write(job.out / "hamiltonian", figures=False)
    return ({name: str(path.relative_to(job.out)) for name, path in written.items()},
            list(written.values()))


def _tabula_rasa(job: _Job, ds: Dataset) -> dict[str, Any]:
    """Run the tabula rasa MLPs and draw them against the paper settings (Fig. S6-S8)."""
    with job.watches["tabula_rasa"]:
        tabula = tabula_rasa_system(ds, job.seed, job.quick, job.save, job.same_as)
    paper = job.settings["paper"]
    for metric, fig_id, unit in (("mae", "figS6_tabula_rasa_mae", ds.unit),
                                 ("mse", "figS7_tabula_rasa_mse", squared(ds.unit))):
        name = f"tabula rasa MLP (voltages only, mean of {len(tabula['seeds'])} seeds)"
        values = {name: tabula[f"test_{metric}"],
                  "control program": getattr(paper.prior, f"test_{metric}"),
                  "base boosting (paper settings)": getattr(paper.model, f"test_{metric}")}
        intervals = {name: tabula[f"test_{metric}_ci"],
                     "control program": paper.prior.ci(f"test_{metric}"),
                     "base boosting (paper settings)": paper.model.ci(f"test_{metric}")}
        job.save(fig_id, model_comparison_bars(
            SHORT, values, metric=metric.upper(), unit=unit, log=True,
            intervals={k: v for k, v in intervals.items() if v is not None},
            title=f"Tabula rasa vs base boosting, test {metric.upper()} (Fig. "
                  f"{'S6' if metric == 'mae' else 'S7'})"))
    return tabula


def _data_figures(job: _Job, ds: Dataset) -> dict[str, Any]:
    """Draw the data figures (Fig. 3, S2, S3); returns the training rows' correlation."""
    say("data figures")
    y_train = ds.split()[2]
    train = ds.X.loc[ds.train_index]
    frame = train[ds.prior_names].set_axis([f"X{j}" for j in range(1, 6)], axis=1)
    frame = frame.join(y_train.set_axis(SHORT, axis=1))
    job.save("fig3_correlation", correlation_heatmap(
        frame, title="Correlation of training examples (Fig. 3)"))
    job.save("figS2_voltage_boxplots", voltage_boxplots(
        ds.features.loc[ds.train_index], title="Bias voltages, training rows (Fig. S2)"))
    job.save("figS3_prior_target_boxplots", prior_target_boxplots(
        train[ds.prior_names].set_axis(SHORT, axis=1), y_train.set_axis(SHORT, axis=1),
        unit=ds.unit, labels=(f"{ds.prior_label} (X)", "measured (Y)"),
        title="Control program (X) and measured (Y) eigenenergies (Fig. S3)"))
    return frame.corr().round(6).to_dict()


def _compare(job: _Job, systems: list[System], ds: Dataset) -> None:
    """Draw every system's test MAE side by side (Fig. R1)."""
    compared = [s for s in systems if s.key != "tabula_rasa"]
    intervals = {s.name: (job.settings["paper"].prior if s.key == "prior"
                          else job.settings[s.key].model).ci("test_mae") for s in compared}
    job.save("figR1_systems_mae", model_comparison_bars(
        SHORT, {s.name: [s.metrics[f"test_mae/{t}"] for t in ds.target_names]
                for s in compared},
        unit=ds.unit, intervals={k: v for k, v in intervals.items() if v is not None},
        title="Test MAE per eigenenergy, every system of this reproduction"))


def _write(path: Path, obj: Any) -> None:
    """Write ``obj`` as indented JSON."""
    atomic_write(path, json.dumps(obj, indent=2, default=str) + "\n")


def reproduce(out: str | Path = "reports", *, tracking_uri: str | None = None,
              storage: str | None = None, quick: bool = False, track: bool = True, seed: int = 0,
              experiments: str | Path | None = None) -> Reproduction:
    """Compute the paper's results and figures, write them and log them.

    Each system is computed in one stretch (its MLflow run's duration); with ``track`` each
    becomes a child run of the parent run ``paper reproduction`` (:mod:`.runs`).

    Parameters
    ----------
    out : str or Path, default="reports"
        The report folder.
    tracking_uri : str, optional
        ``--tracking-uri``.
    storage : str, optional
        The search's study storage (default: the config's).
    quick : bool, default=False
        Reduced curves, SHAP rows, seeds and search: a check that everything runs.
    track : bool, default=True
        Log to MLflow.
    seed : int, default=0
        The seed of every system.
    experiments : str or Path, optional
        The configs' folder (see :func:`experiments_dir`).

    Returns
    -------
    Reproduction
        What was computed (also written as ``results.json``).
    """
    start, started = start_clock(), time.time()
    job = _Job(Path(out), experiments_dir(experiments), seed, quick)
    ds, curves = _paper(job)
    search = _search(job, storage)
    tables, table_files = _hamiltonian(job, ds)
    tabula = _tabula_rasa(job, ds)
    gates = gates_benchmark(job.configs, seed, quick, say)
    job.save("figG1_gates_mae", gates_figure(gates))
    correlation = _data_figures(job, ds)
    systems = paper_systems(job.settings, job.cfgs, tabula, search, job.watches, job.files,
                            {"hamiltonian": table_files}, ds)
    for system in systems:
        system.predictions = job.predictions.get(system.key)
    _compare(job, systems, ds)
    atomic_write(job.out / "systems.csv",
                 summary_table(ds.target_names, systems).to_csv(index=False))
    gate_runs = gate_systems(gates, job.files["figG1_gates_mae"])
    atomic_write(job.out / "systems_ibm_gates.csv",
                 summary_table(gates.generic.targets, gate_runs).to_csv(index=False))
    rep = Reproduction(
        targets=ds.target_names, seed=seed, quick=quick, settings=job.settings,
        tabula_rasa=tabula, correlation=correlation, learning_curves=curves,
        figures={k: [str(p.relative_to(job.out)) for p in v] for k, v in job.files.items()},
        hamiltonian_tables=tables, gates=gates, unit=ds.unit)
    if track:
        say("logging every system as a run in MLflow")
        rep.mlflow = log_reproduction(rep, systems, gate_runs, job.files, job.out,
                                      tracking_uri, ds, job.cfgs["paper"], started, start)
    else:
        rep.wall_s = time.perf_counter() - start
    _write(job.out / "results.json", rep.to_json())
    _write(job.out / "manifest.json", {k: (v[0] if len(v) == 1 else v)
                                       for k, v in rep.figures.items()})
    atomic_write(job.out / "README.md", report(rep))
    say(f"done in {rep.wall_s:.0f} s: {job.out / 'README.md'}")
    return rep
