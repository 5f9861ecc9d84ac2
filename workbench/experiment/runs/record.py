"""Record an ``evaluate`` or ``sweep`` in MLflow: log what was computed, compute nothing.

One parent run with the metrics, the config, the figures (MAE/MSE bars, an augmented learning
curve and a SHAP summary per target) and the fitted multi-target model; with prediction
intervals, their coverage and width as metrics, their figure and the test rows' intervals;
for a sweep, a child run per trial and per outer fold. What every run carries (the metric
schema, tags, params, data) is :mod:`.run_fields`.

Every figure, table and prediction is made before the record, by
:func:`~workbench.experiment.runs.run_outputs.compute_outputs` (the figures as PNG files): beside
the MAE/MSE bars every run has, the config's model family's tables and figures
(:meth:`~workbench.experiment.families.base.ModelFamily.outputs` and
:meth:`~workbench.experiment.families.base.ModelFamily.begin_artifacts`: learning curves and
SHAP summaries per target for family eigenvalue, the parameter-space model's tables and
figures for family hamiltonian). :func:`record` logs those files and values. Every error is in
the dataset's unit (:attr:`~workbench.datasets.Dataset.unit`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import posixpath
from pathlib import Path
from typing import Any

import pandas as pd

from ...datasets import Dataset
from ..config import ExperimentConfig
from ..families.artifacts import Artifacts
from ..process.errors import redact
from ..scoring.results import Result
from ..scoring.units import unit_name
from ..tracking.models import CHAMPION
from ..tracking.runs import Tracker
from ..tracking.uris import resolve_tracking_uri
from ..tracking.views import metric_view
from .evaluate import Evaluation
from .run_fields import (
    NOTE_TAG,
    config_text,
    log_inputs,
    log_sweep_children,
    log_test_predictions,
    result_metrics,
    run_params,
    run_tags,
)
from .run_outputs import RunOutputs
from .seeds import SeedsResult, format_seeds_table

__all__ = ["record", "record_seed", "record_seeds", "record_wall_time", "tracker_for"]

log = logging.getLogger("workbench")


def tracker_for(cfg: ExperimentConfig, tracking_uri: str | None = None) -> Tracker:
    """Open the MLflow experiment a config logs to.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config (its ``[tracking]`` section and name).
    tracking_uri : str, optional
        ``--tracking-uri``: before $MLFLOW_TRACKING_URI, then ``[tracking]``, then
        ``sqlite:///<cwd>/mlruns/mlflow.db``.

    Returns
    -------
    Tracker
        The experiment ``[tracking] experiment`` (default: the config's name).
    """
    uri = resolve_tracking_uri(tracking_uri, cfg.tracking.tracking_uri, Path.cwd())
    return Tracker(uri, cfg.tracking.experiment or cfg.name)


def _description(cfg: ExperimentConfig, ds: Dataset, kind: str, result: Result) -> str:
    """Write the run page's description: what ran on which rows, how to read the metrics."""
    source = f"`{cfg.path}`" if cfg.path else f"config {cfg.name!r}"
    return (f"`workbench {kind}` of {source} (family {cfg.family.name}) on {ds.name}: fitted "
            f"on {result.n_train} training rows, every choice by CV on them; the "
            f"{result.n_test} test rows scored once. Metrics `test_mae/<target>`, "
            "`test_mae_avg`, `cv_mae/<target>`, ... (the control program's: `prior_...`) in "
            f"{unit_name(ds.unit)} (MSE: squared).")


def _log_outputs(tracker: Tracker, run_id: str, ds: Dataset, computed: RunOutputs) -> None:
    """Log the computed figures' files, tables, data and the test rows' predictions.

    The predictions as ``workbench predict`` and a served model give them; the measured
    targets beside them (``predictions/test_measured.csv``) let ``workbench compare`` pair
    two runs' errors row by row.
    """
    for artifact, path in computed.files.items():
        tracker.log_file(run_id, path, posixpath.dirname(artifact) or None)
    for artifact, table in computed.tables.items():
        tracker.log_text(run_id, table.to_csv(index=False), artifact)
    for artifact, data in computed.data.items():
        tracker.log_dict(run_id, data, artifact)
    if computed.predictions is not None:
        log_test_predictions(tracker, run_id, ds, computed.predictions)


def _register(tracker: Tracker, run_id: str, model_uri: str, name: str, cfg: ExperimentConfig,
              result: Result, dataset: str, tags: dict[str, str], kind: str) -> dict[str, Any]:
    """Register the run's model as a new version of ``name`` (alias ``champion``).

    Returns the keys to add to the record's ids.
    """
    version = tracker.register_model(
        model_uri, name, run_id=run_id,
        tags={"workbench.kind": kind, "config": tags["config"],
              "config_name": cfg.name, "dataset": dataset, "dataset_hash": tags["dataset_hash"],
              "git_commit": tags["git_commit"], "family": cfg.family.name,
              "test_mae_avg": f"{result.model.avg('test_mae'):.6g}",
              "cv_mae_avg": f"{result.model.avg('cv_mae'):.6g}",
              "prior_test_mae_avg": f"{result.prior.avg('test_mae'):.6g}"},
        description=f"{kind} of {cfg.name} (run {run_id})")
    log.info("[%s] registered %s version %s (alias %s)", cfg.name, name, version, CHAMPION)
    tracker.set_tags(run_id, {"registered_model": f"{name}/{version}"})
    return {"registered_model": name, "registered_version": version,
            "registered_uri": f"models:/{name}@{CHAMPION}"}


def record(cfg: ExperimentConfig, result: Result, model: Any, ds: Dataset,
           computed: RunOutputs, *, kind: str, tracking_uri: str | None = None,
           sweep: Any = None, run_id: str | None = None,
           register: str | None = None) -> dict[str, str]:
    """Log one evaluate or sweep as a parent run; compute nothing.

    The run holds the metrics, the chosen settings, the config file with its credentials
    redacted, the result, the training and test rows as MLflow datasets, and what
    :func:`~.run_outputs.compute_outputs` made before: the MAE/MSE bars, the intervals' and
    the family's figures and tables, the test rows' predictions; then the model; for a sweep
    a child run per trial and per outer fold.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run.
    result : Result
        Its result.
    model : estimator
        The fitted model (with intervals, the conformal wrapper).
    ds : Dataset
        The data it was fitted on.
    computed : RunOutputs
        The run's figures (as files), tables, data and predictions
        (:func:`~.run_outputs.compute_outputs` with a scratch directory).
    kind : str
        The command (``"evaluate"``, ``"sweep"``).
    tracking_uri : str, optional
        ``--tracking-uri`` (see :func:`tracker_for`).
    sweep : Sweep, optional
        The sweep whose trials and outer folds become child runs.
    run_id : str, optional
        Log into this live run (see :func:`.lifecycle.command_run`; a sweep's trials are its
        children already) instead of a new one.
    register : str, optional
        Also register the model under this name in the store's Model Registry (the new
        version gets the alias ``champion``).

    Returns
    -------
    dict of str to str
        Ids and URIs to add to the result (tracking URI, experiment, run, model, version).
    """
    tracker = tracker_for(cfg, tracking_uri)
    X_train, X_test, y_train, y_test = computed.rows
    tags = {**run_tags(cfg, ds, kind), NOTE_TAG: _description(cfg, ds, kind, result)}
    params = run_params(cfg, result.targets, len(X_train), len(X_test), result.folds)
    live = run_id is not None
    if run_id is not None:
        tracker.set_tags(run_id, tags)
        tracker.log_params(run_id, params)
    with (contextlib.nullcontext(run_id) if run_id is not None
          else tracker.run(f"{kind} {cfg.name}", tags=tags, params=params)) as run_id:
        log.info("[%s] tracking in %s (run %s)", cfg.name, redact(tracker.tracking_uri),
                 run_id)
        # a command's run gets its whole wall time at the end (record_wall_time)
        tracker.log_metrics(run_id, {**result_metrics(result, wall=not live),
                                     **cfg.family.run_metrics(result.details)})
        log_inputs(tracker, run_id, cfg, ds, X_train, X_test, y_train, y_test)
        config = config_text(cfg)
        if config is not None and cfg.path is not None:  # both or neither
            tracker.log_text(run_id, config, Path(cfg.path).name)
        tracker.log_dict(run_id, json.loads(json.dumps(result.to_json(), default=str)),
                         "result.json")
        _log_outputs(tracker, run_id, ds, computed)
        model_uri = tracker.log_model(run_id, model, X_test.head(5), targets=result.targets,
                                      texts={"config.toml": config} if config else None)
        tracker.set_tags(run_id, {"model_uri": model_uri,
                                  "selected": ",".join(result.model.selected)})
        tracker.share_view(metric_view(result.targets))  # `workbench ui`'s link opens it
        out = {"tracking_uri": redact(tracker.tracking_uri), "experiment_id": tracker.experiment_id,
               "run_id": run_id, "model_uri": model_uri}
        if register:
            out.update(_register(tracker, run_id, model_uri, register, cfg, result, ds.name,
                                 tags, kind))
        if sweep is not None:
            log_sweep_children(tracker, run_id, sweep, trials=not live)
    return out


def record_wall_time(cfg: ExperimentConfig, result: Result, *, tracking_uri: str | None,
                     run_id: str) -> None:
    """Log the command's whole wall time, once everything else is logged.

    The run's ``wall_s`` metric and its ``result.json`` get the figure the command prints and
    ``--json`` writes.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run (its tracker).
    result : Result
        The result, its ``wall_s`` final.
    tracking_uri : str or None
        ``--tracking-uri``.
    run_id : str
        The command's run.
    """
    tracker = tracker_for(cfg, tracking_uri)
    tracker.log_metrics(run_id, {"wall_s": result.wall_s})
    tracker.log_dict(run_id, json.loads(json.dumps(result.to_json(), default=str)),
                     "result.json")



def record_seed(cfg: ExperimentConfig, run: Evaluation, predictions: pd.DataFrame, *,
                tracking_uri: str | None, run_id: str) -> dict[str, str]:
    """Log one seed of ``evaluate --random-states`` into its child run.

    Its metrics (the schema of every evaluate), params (``random_state`` the seed), tags,
    ``result.json`` and the test rows' predictions (so that ``workbench compare`` pairs two
    seeds); no model and no figures (one ``evaluate`` with ``random_state`` the seed has them).

    Parameters
    ----------
    cfg : ExperimentConfig
        The seed's config (``random_state`` the seed).
    run : Evaluation
        Its fit.
    predictions : DataFrame
        The test rows' predictions (:func:`~.serving.prediction_frame`), computed already.
    tracking_uri : str or None
        ``--tracking-uri``.
    run_id : str
        The seed's child run.

    Returns
    -------
    dict of str to str
        The child run's ids.
    """
    tracker = tracker_for(cfg, tracking_uri)
    ds, result = run.dataset, run.result
    tracker.set_tags(run_id, {**run_tags(cfg, ds, "evaluate"), "workbench.kind": "seed",
                              "workbench.random_state": cfg.random_state,
                              NOTE_TAG: _description(cfg, ds, "evaluate", result)})
    tracker.log_params(run_id, run_params(cfg, result.targets, result.n_train, result.n_test,
                                          result.folds))
    tracker.log_metrics(run_id, result_metrics(result))
    tracker.log_dict(run_id, json.loads(json.dumps(result.to_json(), default=str)),
                     "result.json")
    log_test_predictions(tracker, run_id, ds, predictions)
    return {"tracking_uri": redact(tracker.tracking_uri), "experiment_id": tracker.experiment_id,
            "run_id": run_id}


def record_seeds(cfg: ExperimentConfig, done: SeedsResult, ds: Dataset, *,
                 tracking_uri: str | None, run_id: str,
                 artifacts: Artifacts) -> dict[str, str]:
    """Log ``evaluate --random-states`` into its parent run, whose children are the seeds.

    The summary's metrics (:meth:`~.seeds.SeedSummary.metrics`), the config's params with
    ``random_states`` (no ``random_state``: each child has its own), the tags, a description with
    the per-target table, the config file, the data as MLflow datasets, the spread figure
    (``plots/seed_spread.png``), each seed's test MAE (``seeds/seed_test_mae.csv``) and
    ``result.json`` (what ``--json`` writes).

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run.
    done : SeedsResult
        The result; its ``wall_s`` final.
    ds : Dataset
        The data.
    tracking_uri : str or None
        ``--tracking-uri``.
    run_id : str
        The command's run.
    artifacts : Artifacts
        The figure and table (:func:`~.seeds.seed_artifacts`), drawn already.

    Returns
    -------
    dict of str to str
        The parent run's ids.
    """
    tracker = tracker_for(cfg, tracking_uri)
    X_train, X_test, y_train, y_test = ds.split(cfg.family.inputs(cfg, ds))
    seeds = ",".join(str(s) for s in done.random_states)
    note = (f"`workbench evaluate --random-states {seeds}` of "
            f"{f'`{cfg.path}`' if cfg.path else repr(cfg.name)} on {ds.name}: one child run "
            f"per seed (the seed its `random_state`).\n\n"
            + format_seeds_table(done, markdown=True))
    tracker.set_tags(run_id, {**run_tags(cfg, ds, "evaluate"), "workbench.random_states": seeds,
                              NOTE_TAG: note})
    params = run_params(cfg, done.summary.targets, len(X_train), len(X_test))
    params.pop("random_state")
    tracker.log_params(run_id, {**params, "random_states": seeds})
    tracker.log_metrics(run_id, {**done.summary.metrics(), "wall_s": done.wall_s})
    log_inputs(tracker, run_id, cfg, ds, X_train, X_test, y_train, y_test)
    config = config_text(cfg)
    if config is not None and cfg.path is not None:
        tracker.log_text(run_id, config, Path(cfg.path).name)
    for name, fig in artifacts.figures.items():
        tracker.log_figure(run_id, fig, f"plots/{name}.png")
    for name, table in artifacts.tables.items():
        tracker.log_text(run_id, table.to_csv(index=False), f"seeds/{name}.csv")
    out = {"tracking_uri": redact(tracker.tracking_uri), "experiment_id": tracker.experiment_id,
           "run_id": run_id}
    done.mlflow = out
    tracker.log_dict(run_id, json.loads(json.dumps(done.to_json(), default=str)),
                     "result.json")
    tracker.share_view(metric_view(done.summary.targets))
    return out
