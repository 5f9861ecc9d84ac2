"""``workbench reproduce``: every result and figure of the paper from the Google 5-qubit data.

By default (``make run``) the paper's settings with their figures, learning curves and SHAP,
the improved settings, the parameter-space model and the tabula rasa MLPs; with
``all_systems`` (``--all``) also the workbench's own nested-CV search and the second
benchmark, the IBM two-qubit gates (:data:`ALL_ONLY`).

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
from ...parallel import Plan, Started, Task, run_plans
from ...parallel import start as start_on_worker
from ..config import (
    ExperimentConfig,
    check_training_rows,
    data_key,
    load_dataset,
    without_intervals,
)
from ..figures import (
    correlation_heatmap,
    error_bars,
    model_comparison_bars,
    prior_target_boxplots,
    save_figure,
    voltage_boxplots,
)
from ..process.errors import UsageError
from ..runs.evaluate import evaluate
from ..runs.prepare import load_config
from ..scoring.results import Result
from ..sweep.search import Sweep, run_sweep
from ..tracking.serving import prediction_frame
from .compute import (
    SHORT,
    SameAs,
    Save,
    correction_shap_plan,
    figure_saver,
    hamiltonian_config,
    learning_curves_plan,
    say,
    seeded,
    start_clock,
)
from .gates import gate_systems, gates_benchmark, gates_figure
from .phases import (
    Phase,
    evaluate_phase,
    hamiltonian_phase,
    tabula_rasa_plan,
    timed,
)
from .report import report
from .reproduction import Reproduction
from .runs import log_reproduction
from .systems import SYSTEMS, Stopwatch, System, paper_systems, summary_table

__all__ = ["ALL_ONLY", "CONFIGS", "experiments_dir", "reproduce"]

#: The source checkout the package may have been imported from (an installed wheel's
#: site-packages has no ``experiments/``).
CHECKOUT = Path(__file__).resolve().parents[3]
#: The configs the reproduction runs, read from an experiments folder.
CONFIGS = ("paper_main_body.toml", "paper_improved.toml", "paper_search.toml",
           "hamiltonian.toml")
#: The order of the settings and figures in ``results.json`` and ``manifest.json`` (that of
#: running the phases one after another; they may end in another order).
ORDER = ("paper", "improved", "search", "hamiltonian", "fig2_mae_bars", "figS4_mse_bars",
         "figR2_shap_correction", "figR3_shap_prediction", "figS5_learning_curves",
         "fig4_learning_curve_Y3", "figH1_hamiltonian_mae_bars", "figH2_parameter_corrections",
         "figH3_selection_path", "figS8_shap", "fig5_shap_Y1", "figS6_tabula_rasa_mae",
         "figS7_tabula_rasa_mse", "figG1_gates_mae", "fig3_correlation",
         "figS2_voltage_boxplots", "figS3_prior_target_boxplots", "figR1_systems_mae")
#: What only ``reproduce --all`` runs: the longest phases, beside the paper's own figures.
ALL_ONLY = ("the workbench's own nested-CV search (experiments/paper_search.toml)",
            "the IBM two-qubit gates benchmark (experiments/generic.toml against the peer)")


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

    Its settings (``clock``: its start on :func:`time.perf_counter`'s clock), the figures
    written and each system's stopwatch, result and config as they come.
    """

    out: Path
    configs: Path
    random_state: int
    quick: bool
    clock: float
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
        self.cfgs[key] = seeded(cfg, self.random_state)
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


def _paper(job: _Job, all_systems: bool) -> tuple[Dataset, dict[str, Any], dict[str, Started],
                                                 Phase]:
    """Run the paper settings with their figures, SHAP and learning curves, and the rest.

    The serial phases start first on the workers (:func:`_start_phases`: the longest first,
    so that none is left running alone at the end); then the paper settings' model (its
    folds and refits on the workers as they come free), and one run of the workers for its
    SHAP values, its learning curves and the tabula rasa MLPs, each with its figures (the
    long SHAP tasks first). Returns the Google data, the learning curves, the started
    phases and the tabula rasa MLPs' phase.
    """
    paper_cfg = load_config(job.configs / "paper_main_body.toml")
    ds = job.dataset(seeded(paper_cfg, job.random_state))
    phases = _start_phases(job, ds, all_systems)
    figdir = job.out / "figures"
    with job.watches["paper"]:
        run = job.evaluate("paper", paper_cfg)
        paper = run.result
        for metric, fig_id, fig in (("MAE", "fig2_mae_bars", "Fig. 2"),
                                    ("MSE", "figS4_mse_bars", "Fig. S4")):
            job.save(fig_id, error_bars(paper, metric, targets=SHORT, unit=ds.unit,
                                        labels=(ds.prior_label, "base boosting"),
                                        title=f"Test {metric} per eigenenergy ({fig})",
                                        setting="paper settings"))
        shap, (curves, curve_files), tabula, data_files = run_plans(
            [correction_shap_plan(run.model, ds, job.random_state, job.quick, figdir),
             learning_curves_plan(paper_cfg, ds, job.random_state, job.quick, figdir),
             tabula_rasa_plan(ds, job.random_state, job.quick, job.out, paper),
             _data_figures_plan(ds, figdir)], -1)
        for files in (shap, curve_files, data_files):
            for fig_id, paths in files.items():
                job.files.setdefault(fig_id, []).extend(paths)
    return ds, curves, phases, tabula


def _start_phases(job: _Job, ds: Dataset, all_systems: bool) -> dict[str, Started]:
    """Start the serial phases independent of the paper settings on the workers.

    The parameter-space model and the improved settings (:mod:`.phases`) and, with
    ``all_systems``, the IBM benchmark; each runs serially in a worker process, the longest
    first (the workers take them in this order as they come free), while this process runs
    the paper settings' plans on the workers beside them and the search (every core busy);
    without workers each runs when its result is taken.
    """
    improved = seeded(load_config(job.configs / "paper_improved.toml"), job.random_state)
    ham = hamiltonian_config(load_config(job.configs / "hamiltonian.toml"), job.random_state,
                             job.quick)
    job.cfgs.update(improved=improved, hamiltonian=ham)
    calls: dict[str, tuple[Any, ...]] = {
        "hamiltonian": (hamiltonian_phase, ham, job.dataset(ham), job.out),
        "improved": (evaluate_phase, improved, job.dataset(improved))}
    if all_systems:  # the longest: first
        calls = {"gates": (gates_benchmark, job.configs, job.random_state, job.quick, say),
                 **calls}
    say("started on the workers beside the paper settings: " + ", ".join(calls))
    return {key: start_on_worker(Task(timed, job.clock, *call))
            for key, call in calls.items()}


def _keep(job: _Job, key: str, phase: Phase) -> Phase:
    """Keep a finished phase's result, predictions, figures and time."""
    job.watches[key] = phase.watch
    if phase.result is not None:
        job.settings[key] = phase.result
    if phase.predictions is not None:
        job.predictions[key] = phase.predictions
    for fig_id, paths in phase.files.items():
        job.files.setdefault(fig_id, []).extend(paths)
    return phase


def _search(job: _Job, storage: str | None) -> Sweep:
    """Run the workbench's own nested-CV search (``experiments/paper_search.toml``)."""
    say("nested-CV search for the workbench's own best configuration "
        "(experiments/paper_search.toml)")
    cfg = load_config(job.configs / "paper_search.toml")
    cv = {"sweep_seed": job.random_state,
          **({"outer_folds": 2, "inner_folds": 3} if job.quick else {})}
    cfg = without_intervals(replace(cfg, random_state=job.random_state,
                                    cv=cfg.cv.model_copy(update=cv)))
    # another seed, or --quick (other folds and budgets), must not resume these studies
    quick = "-quick" if job.quick else ""
    cfg = cfg.with_study(study_name=f"{cfg.name}-seed{job.random_state}{quick}",
                         trials=2 if job.quick else None, storage=storage)
    with job.watches["search"], warnings.catch_warnings():
        # a candidate basis's convergence notes: not the user's
        warnings.simplefilter("ignore", ConvergenceWarning)
        # a line per trial: the longest phase
        search = run_sweep(cfg, progress=True, dataset=job.dataset(cfg))
    job.settings["search"], job.cfgs["search"] = search.result, cfg
    return search


def _data_frame(ds: Dataset) -> pd.DataFrame:
    """The training rows' control program (X1-X5) and measurements (Y1-Y5)."""
    train = ds.X.loc[ds.train_index]
    frame = train[ds.prior_names].set_axis([f"X{j}" for j in range(1, 6)], axis=1)
    return frame.join(ds.split()[2].set_axis(SHORT, axis=1))


def _correlation(ds: Dataset) -> dict[str, Any]:
    """The training rows' correlation of control program and measurements (Fig. 3's)."""
    return _data_frame(ds).corr().round(6).to_dict()


def _data_figures_plan(ds: Dataset, figdir: Path) -> Plan:
    """Plan the data figures (Fig. 3, S2, S3), one task each; returns them by figure id."""
    say("data figures")
    ids = ("fig3_correlation", "figS2_voltage_boxplots", "figS3_prior_target_boxplots")
    paths = yield [Task(_data_figure, ds, fig_id, figdir) for fig_id in ids]
    return {fig_id: [path] for fig_id, path in zip(ids, paths)}


def _data_figure(ds: Dataset, fig_id: str, figdir: Path) -> Path:
    """Draw and write one of the data figures."""
    train = ds.X.loc[ds.train_index]
    if fig_id == "fig3_correlation":
        fig = correlation_heatmap(_data_frame(ds),
                                  title="Correlation of training examples (Fig. 3)")
    elif fig_id == "figS2_voltage_boxplots":
        fig = voltage_boxplots(ds.features.loc[ds.train_index],
                               title="Bias voltages, training rows (Fig. S2)")
    else:
        y_train = ds.split()[2]
        fig = prior_target_boxplots(
            train[ds.prior_names].set_axis(SHORT, axis=1), y_train.set_axis(SHORT, axis=1),
            unit=ds.unit, labels=(f"{ds.prior_label} (X)", "measured (Y)"),
            title="Control program (X) and measured (Y) eigenenergies (Fig. S3)")
    return save_figure(fig, figdir / f"{fig_id}.png")


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


def _ordered(d: dict[str, Any]) -> dict[str, Any]:
    """``d`` with its keys in :data:`ORDER`."""
    return dict(sorted(d.items(), key=lambda kv: ORDER.index(kv[0])))


def _write(path: Path, obj: Any) -> None:
    """Write ``obj`` as indented JSON."""
    atomic_write(path, json.dumps(obj, indent=2, default=str) + "\n")


def reproduce(out: str | Path = "reports", *, tracking_uri: str | None = None,
              storage: str | None = None, quick: bool = False, track: bool = True,
              random_state: int = 0, experiments: str | Path | None = None,
              all_systems: bool = False) -> Reproduction:
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
    random_state : int, default=0
        Every system's ``random_state`` (``reproduce --random-state``). Formerly ``seed``.
    experiments : str or Path, optional
        The configs' folder (see :func:`experiments_dir`).
    all_systems : bool, default=False
        Also run :data:`ALL_ONLY` (``--all``): the nested-CV search and the IBM benchmark.

    Returns
    -------
    Reproduction
        What was computed (also written as ``results.json``).
    """
    start, started = start_clock(), time.time()
    job = _Job(Path(out), experiments_dir(experiments), random_state, quick, start)
    ds, curves, phases, tabula_phase = _paper(job, all_systems)
    tabula = _keep(job, "tabula_rasa", tabula_phase).numbers
    search = _search(job, storage) if all_systems else None
    ham = _keep(job, "hamiltonian", phases["hamiltonian"].result())
    tables = {name: str(path.relative_to(job.out)) for name, path in ham.tables.items()}
    table_files = list(ham.tables.values())
    _keep(job, "improved", phases["improved"].result())
    gates = phases["gates"].result() if all_systems else None
    if gates is not None:
        job.save("figG1_gates_mae", gates_figure(gates))
    correlation = _correlation(ds)
    systems = paper_systems(job.settings, job.cfgs, tabula, search, job.watches, job.files,
                            {"hamiltonian": table_files}, ds)
    for system in systems:
        system.predictions = job.predictions.get(system.key)
    _compare(job, systems, ds)
    atomic_write(job.out / "systems.csv",
                 summary_table(ds.target_names, systems).to_csv(index=False))
    gate_runs = []
    if gates is not None:
        gate_runs = gate_systems(gates, job.files["figG1_gates_mae"])
        atomic_write(job.out / "systems_ibm_gates.csv",
                     summary_table(gates.generic.targets, gate_runs).to_csv(index=False))
    job.files = _ordered(job.files)
    rep = Reproduction(
        targets=ds.target_names, random_state=random_state, quick=quick,
        all_systems=all_systems,
        settings=_ordered(job.settings),
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
