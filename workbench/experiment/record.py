"""Record an ``evaluate`` or ``sweep`` in MLflow.

One parent run with the metrics, the config, the figures (MAE/MSE bars, an augmented learning
curve and a SHAP summary per target) and the fitted multi-target model; with prediction
intervals, their coverage and width as metrics, their figure and the test rows' intervals;
for a sweep, a child run per trial and per outer fold. What every run carries (the metric
schema, tags, params, data) is :mod:`.run_fields`.

Beside the MAE/MSE bars every run has, the config's model family supplies its own figures
and tables (:meth:`~workbench.experiment.families.base.ModelFamily.artifacts`: learning curves
and SHAP summaries per target for family eigenvalue, the parameter-space model's tables and
figures for family hamiltonian). Every error is in the dataset's unit
(:attr:`~workbench.datasets.Dataset.unit`).
"""

from __future__ import annotations

import contextlib
import json
import logging
from pathlib import Path
from typing import Any

import pandas as pd

from ..datasets import Dataset
from .config import ExperimentConfig
from .errors import redact
from .evaluate import Evaluation
from .families.artifacts import Artifacts
from .figures import mae_bars
from .intervals import family_model, interval_artifacts
from .results import Result
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
from .seeds import SeedsResult, format_seeds_table, seed_artifacts
from .serving import prediction_frame
from .tracking.models import CHAMPION
from .tracking.runs import Tracker, metric_view
from .tracking.uris import resolve_tracking_uri
from .units import squared, unit_name

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


def _log_error_bars(tracker: Tracker, run_id: str, result: Result, unit: str | None,
                    setting: str) -> None:
    """Log the test MAE and MSE bars of prior and model (``plots/mae_bars.png``, ...)."""
    for metric, name in (("MAE", "mae_bars"), ("MSE", "mse_bars")):
        key = f"test_{metric.lower()}"
        fig = mae_bars(result.targets, getattr(result.prior, key),
                       getattr(result.model, key), metric=metric,
                       prior_ci=result.prior.ci(key), model_ci=result.model.ci(key),
                       unit=unit if metric == "MAE" else squared(unit),
                       title=f"Test {metric} per target", setting=setting)
        tracker.log_figure(run_id, fig, f"plots/{name}.png")


def _log_predictions(tracker: Tracker, run_id: str, cfg: ExperimentConfig, ds: Dataset,
                     model: Any, X_test: pd.DataFrame, targets: list[str], setting: str) -> None:
    """Log the intervals' figure and table, and the test rows' predictions and targets.

    The predictions as ``workbench predict`` and a served model give them; the measured
    targets beside them (``predictions/test_measured.csv``) let ``workbench compare`` pair
    two runs' errors row by row.
    """
    intervals = interval_artifacts(cfg, ds, model, setting)
    for name, fig in intervals.figures.items():
        tracker.log_figure(run_id, fig, f"plots/{name}.png")
    for name, table in intervals.tables.items():
        tracker.log_text(run_id, table.to_csv(index=False), f"intervals/{name}.csv")
    log_test_predictions(tracker, run_id, ds, prediction_frame(model, X_test, targets))


def _log_tables(tracker: Tracker, run_id: str, family: str, extra: Artifacts) -> None:
    """Log the family's tables (``<family>/<name>.csv``) and data (``<name>.json``)."""
    for name, table in extra.tables.items():
        tracker.log_text(run_id, table.to_csv(index=False), f"{family}/{name}.csv")
    for name, data in extra.data.items():
        tracker.log_dict(run_id, data, f"{name}.json")


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


def record(cfg: ExperimentConfig, result: Result, model: Any, ds: Dataset, *, kind: str,
           tracking_uri: str | None = None, sweep: Any = None, run_id: str | None = None,
           register: str | None = None) -> dict[str, str]:
    """Log one evaluate or sweep as a parent run.

    The run holds the metrics, the chosen settings, the config file with its credentials
    redacted, the result, the training and test rows as MLflow datasets, MAE/MSE bars, the
    family's artifacts, the test rows' predictions and the model; for a sweep a child run per
    trial and per outer fold.

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
    family = cfg.family
    X_train, X_test, y_train, y_test = ds.split(family.inputs(cfg, ds))
    tags = {**run_tags(cfg, ds, kind), NOTE_TAG: _description(cfg, ds, kind, result)}
    params = run_params(cfg, result.targets, len(X_train), len(X_test))
    setting = f"{kind} of {cfg.name}"
    live = run_id is not None
    if run_id is not None:
        tracker.set_tags(run_id, tags)
        tracker.log_params(run_id, params)
    with (contextlib.nullcontext(run_id) if run_id is not None
          else tracker.run(f"{kind} {cfg.name}", tags=tags, params=params)) as run_id:
        log.info("[%s] tracking in %s (run %s)", cfg.name, redact(tracker.tracking_uri),
                 run_id)
        # a command's run gets its whole wall time at the end (record_wall_time)
        tracker.log_metrics(run_id, result_metrics(result, wall=not live))
        # the family's figures are computed on the workers while the rest is logged
        finish_artifacts = family.begin_artifacts(cfg, ds, family_model(model), setting)
        log_inputs(tracker, run_id, cfg, ds, X_train, X_test, y_train, y_test)
        config = config_text(cfg)
        if config is not None and cfg.path is not None:  # both or neither
            tracker.log_text(run_id, config, Path(cfg.path).name)
        tracker.log_dict(run_id, json.loads(json.dumps(result.to_json(), default=str)),
                         "result.json")
        _log_error_bars(tracker, run_id, result, ds.unit, setting)
        _log_predictions(tracker, run_id, cfg, ds, model, X_test, result.targets, setting)
        model_uri = tracker.log_model(run_id, model, X_test.head(5), targets=result.targets,
                                      texts={"config.toml": config} if config else None)
        extra = finish_artifacts(lambda name, fig: tracker.log_figure(run_id, fig,
                                                                      f"plots/{name}.png"))
        _log_tables(tracker, run_id, family.name, extra)
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



def record_seed(cfg: ExperimentConfig, run: Evaluation, *, tracking_uri: str | None,
                run_id: str) -> dict[str, str]:
    """Log one seed of ``evaluate --seeds`` into its child run.

    Its metrics (the schema of every evaluate), params (``random_state`` the seed), tags,
    ``result.json`` and the test rows' predictions (so that ``workbench compare`` pairs two
    seeds); no model and no figures (one ``evaluate`` with ``random_state`` the seed has them).

    Parameters
    ----------
    cfg : ExperimentConfig
        The seed's config (``random_state`` the seed).
    run : Evaluation
        Its fit.
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
    X_train, X_test, _, _ = ds.split(cfg.family.inputs(cfg, ds))
    tracker.set_tags(run_id, {**run_tags(cfg, ds, "evaluate"), "workbench.kind": "seed",
                              "workbench.seed": cfg.random_state,
                              NOTE_TAG: _description(cfg, ds, "evaluate", result)})
    tracker.log_params(run_id, run_params(cfg, result.targets, len(X_train), len(X_test)))
    tracker.log_metrics(run_id, result_metrics(result))
    tracker.log_dict(run_id, json.loads(json.dumps(result.to_json(), default=str)),
                     "result.json")
    log_test_predictions(tracker, run_id, ds, prediction_frame(run.model, X_test,
                                                               result.targets))
    return {"tracking_uri": redact(tracker.tracking_uri), "experiment_id": tracker.experiment_id,
            "run_id": run_id}


def record_seeds(cfg: ExperimentConfig, done: SeedsResult, ds: Dataset, *,
                 tracking_uri: str | None, run_id: str,
                 artifacts: Artifacts | None = None) -> dict[str, str]:
    """Log ``evaluate --seeds`` into its parent run, whose children are the seeds.

    The summary's metrics (:meth:`~.seeds.SeedSummary.metrics`), the config's params with
    ``seeds`` (no ``random_state``: each child has its own), the tags, a description with
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
    artifacts : Artifacts, optional
        The figure and table (:func:`~.seeds.seed_artifacts`); made here when not given.

    Returns
    -------
    dict of str to str
        The parent run's ids.
    """
    tracker = tracker_for(cfg, tracking_uri)
    X_train, X_test, y_train, y_test = ds.split(cfg.family.inputs(cfg, ds))
    seeds = ",".join(str(s) for s in done.seeds)
    note = (f"`workbench evaluate --seeds {seeds}` of "
            f"{f'`{cfg.path}`' if cfg.path else repr(cfg.name)} on {ds.name}: one child run "
            f"per seed (the seed its `random_state`).\n\n"
            + format_seeds_table(done, markdown=True))
    tracker.set_tags(run_id, {**run_tags(cfg, ds, "evaluate"), "workbench.seeds": seeds,
                              NOTE_TAG: note})
    params = run_params(cfg, done.summary.targets, len(X_train), len(X_test))
    params.pop("random_state")
    tracker.log_params(run_id, {**params, "seeds": seeds})
    tracker.log_metrics(run_id, {**done.summary.metrics(), "wall_s": done.wall_s})
    log_inputs(tracker, run_id, cfg, ds, X_train, X_test, y_train, y_test)
    config = config_text(cfg)
    if config is not None and cfg.path is not None:
        tracker.log_text(run_id, config, Path(cfg.path).name)
    extra = artifacts or seed_artifacts(done, f"evaluate of {cfg.name}")
    for name, fig in extra.figures.items():
        tracker.log_figure(run_id, fig, f"plots/{name}.png")
    for name, table in extra.tables.items():
        tracker.log_text(run_id, table.to_csv(index=False), f"seeds/{name}.csv")
    out = {"tracking_uri": redact(tracker.tracking_uri), "experiment_id": tracker.experiment_id,
           "run_id": run_id}
    done.mlflow = out
    tracker.log_dict(run_id, json.loads(json.dumps(done.to_json(), default=str)),
                     "result.json")
    tracker.share_view(metric_view(done.summary.targets))
    return out
