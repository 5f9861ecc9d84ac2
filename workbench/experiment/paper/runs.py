"""The reproduction in MLflow.

A parent run with one child run per system, and a second parent for the IBM benchmark's
systems.

Each child run has its params, its config file (credentials redacted) and source tags, the
training and test rows as MLflow datasets, its result as JSON, its own figures and tables, and
its true start and end (the reproduction computes each system in one stretch and logs it
afterwards). The parent has the cross-system figures, the data figures, the summary table and
``results.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from ...datasets import Dataset
from ..config import ExperimentConfig
from ..process.errors import redact
from ..runs.run_fields import (
    NOTE_TAG,
    config_text,
    log_inputs,
    log_sweep_children,
    log_test_predictions,
    run_tags,
)
from ..scoring.units import unit_name
from ..tracking.runs import Tracker
from ..tracking.uris import resolve_tracking_uri
from ..tracking.views import metric_view
from .reproduction import Reproduction
from .systems import System

__all__ = ["SYSTEM_TAG", "log_reproduction", "log_systems"]

#: The tag naming a run's system (its key in the reproduction).
SYSTEM_TAG = "workbench.system"
#: The parent's figures (the others are a system's own).
PARENT_FIGURES = ("figR1_systems_mae", "fig3_correlation", "figS2_voltage_boxplots",
                  "figS3_prior_target_boxplots")


def log_systems(tracker: Tracker, parent: str, systems: list[System], ds: Dataset,
                paper_cfg: ExperimentConfig, kind: str = "reproduce") -> dict[str, str]:
    """Log each system as a child run of ``parent``.

    Every run gets the training and test rows as datasets (of ``paper_cfg``'s inputs unless
    the system's own config says otherwise).

    Parameters
    ----------
    tracker : Tracker
        The MLflow experiment.
    parent : str
        The parent run's id.
    systems : list of System
        The systems.
    ds : Dataset
        Their data.
    paper_cfg : ExperimentConfig
        The config of a system without one of its own.
    kind : str, default="reproduce"
        The command, in the runs' tags.

    Returns
    -------
    dict of str to str
        System key -> run id.
    """
    ids = {}
    for system in systems:
        cfg = system.config or paper_cfg
        tags = {**run_tags(cfg, ds, kind), SYSTEM_TAG: system.key,
                NOTE_TAG: system.description}
        if system.config is None:  # no config of its own: the reproduction's source
            tags.update({"config": "", "mlflow.source.name": f"workbench {kind}"})
        run = tracker.start_run(system.name, parent_run_id=parent, tags=tags,
                                params=system.params, start_time=system.started)
        try:
            _log_system(tracker, run, system, cfg, ds)
        except BaseException:
            tracker.end_run(run, "FAILED")
            raise
        tracker.end_run(run, end_time=system.ended)
        ids[system.key] = run
    return ids


def _log_system(tracker: Tracker, run: str, system: System, cfg: ExperimentConfig,
                ds: Dataset) -> None:
    """Log one system's metrics, data, config, result, figures, tables and sweep folds."""
    tracker.log_metrics(run, {**system.metrics, "wall_s": system.seconds})
    X_train, X_test, y_train, y_test = ds.split(cfg.family.inputs(cfg, ds))
    log_inputs(tracker, run, cfg, ds, X_train, X_test, y_train, y_test)
    config = config_text(system.config) if system.config is not None else None
    if config is not None and system.config is not None and system.config.path:
        tracker.log_text(run, config, Path(system.config.path).name)
    if system.result is not None:
        tracker.log_dict(run, json.loads(json.dumps(system.result.to_json(), default=str)),
                         "result.json")
        tracker.set_tags(run, {"selected": ",".join(system.result.model.selected)})
    for path in dict.fromkeys(system.figures):
        tracker.log_file(run, path, "figures")
    for path in system.tables:
        tracker.log_file(run, path, "tables")
    if system.predictions is not None:
        log_test_predictions(tracker, run, ds, system.predictions)
    if system.sweep is not None:
        log_sweep_children(tracker, run, system.sweep, trials=False)


def log_reproduction(rep: Reproduction, systems: list[System], gate_systems: list[System],
                     files: dict[str, list[Path]], out: Path, tracking_uri: str | None,
                     ds: Dataset, paper_cfg: ExperimentConfig, started: float,
                     start: float) -> dict[str, str]:
    """Log the reproduction: a parent run, a child per system, a second parent for IBM's.

    The parent runs from the reproduction's start and holds its data and cross-system
    figures, ``systems.csv`` and ``results.json``; ``rep.wall_s`` is set to the whole
    command's time, the parent's ``wall_s``, once everything else is logged.

    Parameters
    ----------
    rep : Reproduction
        What was computed.
    systems, gate_systems : list of System
        The Google benchmark's systems and the IBM benchmark's.
    files : dict of str to list of Path
        The figures by id.
    out : Path
        The report folder (with ``systems.csv``).
    tracking_uri : str, optional
        ``--tracking-uri`` (else $MLFLOW_TRACKING_URI, else ``./mlruns``).
    ds : Dataset
        The Google 5-qubit data.
    paper_cfg : ExperimentConfig
        The paper settings' config (the parent's tags and data).
    started : float
        The reproduction's start, seconds since the epoch.
    start : float
        The same on :func:`time.perf_counter`'s clock.

    Returns
    -------
    dict of str to str
        The tracking URI (redacted), the parent's run id and each system's
        (``run_id.<key>``).
    """
    uri = resolve_tracking_uri(tracking_uri, None, Path.cwd())
    tracker = Tracker(uri, "paper-reproduction")
    tags = {**run_tags(paper_cfg, ds, "reproduce"), "config": "",
            "mlflow.source.name": "workbench reproduce",
            NOTE_TAG: "The paper's results and figures from the Google 5-qubit data (95 "
                      "training, 41 test experiments): one child run per system, with the "
                      "metric keys of `workbench evaluate`; here the figures comparing them "
                      "and the data figures, `systems.csv` and `results.json`. Errors in "
                      f"{unit_name(ds.unit)}."}
    parent = tracker.start_run("paper reproduction", tags=tags, start_time=started,
                               params={"random_state": rep.random_state, "quick": rep.quick,
                                       "systems": ", ".join(s.name for s in systems)})
    try:
        ids = log_systems(tracker, parent, systems, ds, paper_cfg)
        if rep.gates is not None:
            ids.update(_log_gates(tracker, parent, rep, gate_systems))
        log_inputs(tracker, parent, paper_cfg, ds, *ds.split())
        for fig_id in PARENT_FIGURES:
            for path in files[fig_id]:
                tracker.log_file(parent, path, "figures")
        tracker.log_file(parent, out / "systems.csv")
        # `workbench ui`'s link: the systems side by side, their test MAE per target
        tracker.share_view(metric_view(rep.targets, search_filter=f"tags.`{SYSTEM_TAG}` LIKE '%'"))
        rep.wall_s = time.perf_counter() - start
        tracker.log_dict(parent, json.loads(json.dumps(rep.to_json(), default=str)),
                         "results.json")
        tracker.log_metrics(parent, {"wall_s": rep.wall_s})
    except BaseException:
        tracker.end_run(parent, "FAILED")
        raise
    tracker.end_run(parent)
    return {"tracking_uri": redact(uri), "run_id": parent,
            **{f"run_id.{key}": run for key, run in ids.items()}}


def _log_gates(tracker: Tracker, parent: str, rep: Reproduction,
               gate_systems: list[System]) -> dict[str, str]:
    """Log the IBM benchmark's systems under a second parent, a child of ``parent``."""
    gates = rep.gates
    assert gates is not None  # called with the benchmark's results
    second = tracker.start_run(
        "IBM two-qubit gates", parent_run_id=parent,
        tags={**run_tags(gates.config, gates.dataset, "reproduce"),
              NOTE_TAG: "The second benchmark: the coherence limit, the peer and the "
                        "generic config on IBM's two-qubit gates, newer devices held "
                        "out; one child run per system."},
        start_time=gates.watches["gates_generic"].started)
    ids = log_systems(tracker, second, gate_systems, gates.dataset, gates.config)
    tracker.end_run(second, end_time=gates.watches["gates_peer"].ended)
    return ids
