"""``reproduce``'s systems as MLflow runs: one child run per system (control program, paper
settings, improved settings, nested-CV search, parameter-space model, tabula rasa) under one
parent run, in the metric schema of ``evaluate`` and ``sweep`` (:func:`.record.score_metrics`:
``test_mae/<target>``, ``test_mae_avg``, ...), so MLflow's compare view lines them up with each
other and with any ``evaluate`` run of the same data.

Each run has its params, its config file (credentials redacted) and source tags, the training
and test rows as MLflow datasets, its result as JSON, its own figures and tables, and its true
start and end (the reproduction computes each system in one stretch and logs it afterwards).
The parent has the cross-system figures, the data figures, the summary table and
``results.json``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from .config import ExperimentConfig
from .record import (
    NOTE_TAG,
    config_text,
    log_inputs,
    log_sweep_children,
    run_tags,
)
from .results import Result
from .tracking.runs import Tracker

__all__ = ["SYSTEM_TAG", "Stopwatch", "System", "log_systems", "summary_table"]


#: The tag naming a run's system (its key in the reproduction).
SYSTEM_TAG = "workbench.system"


@dataclass
class System:
    """One system of a reproduction, as its MLflow run will show it.

    ``started``/``ended``: seconds since the epoch around the system's own work; ``metrics``
    in the shared schema; ``config``: the experiment config it ran (``None``: no config, as
    for the control program); ``result``: logged as ``result.json``; ``figures``: files to
    log under ``figures/``; ``tables``: files to log under ``tables/``; ``sweep``: a sweep
    whose outer folds become the run's children; ``description``: the run page's (Markdown)."""

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
    sweep: Any = None
    description: str = ""

    @property
    def seconds(self) -> float:
        return self.ended - self.started


class Stopwatch:
    """``with watch: ...`` records the block's start and end (:attr:`started`,
    :attr:`ended`: seconds since the epoch; NaN before)."""

    def __init__(self) -> None:
        self.started = self.ended = float("nan")

    def __enter__(self) -> Stopwatch:
        self.started = time.time()
        return self

    def __exit__(self, *exc) -> None:
        self.ended = time.time()


def log_systems(tracker: Tracker, parent: str, systems: list[System], ds, paper_cfg,
                kind: str = "reproduce") -> dict[str, str]:
    """Log each system as a child run of ``parent``; returns system key -> run id. Every run
    gets the training and test rows as datasets (of ``paper_cfg``'s inputs unless the
    system's own config says otherwise)."""
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
            tracker.log_metrics(run, {**system.metrics, "wall_s": system.seconds})
            X_train, X_test, y_train, y_test = ds.split(cfg.family.inputs(cfg, ds))
            log_inputs(tracker, run, cfg, ds, X_train, X_test, y_train, y_test)
            config = config_text(system.config) if system.config is not None else None
            if config is not None and system.config is not None and system.config.path:
                tracker.log_text(run, config, Path(system.config.path).name)
            if system.result is not None:
                tracker.log_dict(run, json.loads(json.dumps(system.result.to_json(),
                                                            default=str)), "result.json")
                tracker.set_tags(run, {"selected": ",".join(system.result.model.selected)})
            for path in dict.fromkeys(system.figures):
                tracker.log_file(run, path, "figures")
            for path in system.tables:
                tracker.log_file(run, path, "tables")
            if system.sweep is not None:
                log_sweep_children(tracker, run, system.sweep, trials=False)
        except BaseException:
            tracker.end_run(run, "FAILED")
            raise
        tracker.end_run(run, end_time=system.ended)
        ids[system.key] = run
    return ids


def summary_table(targets: list[str], systems: list[System]) -> pd.DataFrame:
    """One row per system: its test MAE per target and on average (the shared metric keys,
    to 4 decimals), and its seconds."""
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
