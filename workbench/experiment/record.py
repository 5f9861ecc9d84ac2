"""Record an ``evaluate`` or ``sweep`` in MLflow: one parent run with the metrics, the config,
the figures (MAE/MSE bars, an augmented learning curve and a SHAP summary per target) and the
fitted multi-target model; with prediction intervals, their coverage and width as metrics,
their figure and the test rows' intervals; for a sweep, a child run per trial and per outer
fold.

Beside the MAE/MSE bars every run has, the config's model family supplies its own figures
and tables (:meth:`~workbench.experiment.families.base.ModelFamily.artifacts`: learning curves
and SHAP summaries per target for family eigenvalue, the parameter-space model's tables and
figures for family hamiltonian)."""

from __future__ import annotations

import contextlib
import json
import logging
from pathlib import Path
from typing import Any

import pandas as pd

from ..datasets import BENCHMARKS
from .config import ExperimentConfig
from .errors import redact, redact_config
from .figures import mae_bars
from .intervals import family_model, interval_artifacts
from .results import INTERVAL_KEYS, Result, Scores, squared
from .serving import prediction_frame
from .tracking.models import CHAMPION
from .tracking.records import dataset_hash, git_commit
from .tracking.runs import Tracker, metric_view
from .tracking.uris import resolve_tracking_uri

__all__ = ["NOTE_TAG", "config_text", "log_inputs", "log_sweep_children", "record",
           "record_wall_time", "result_metrics", "run_params", "run_tags", "score_metrics",
           "tracker_for"]

log = logging.getLogger("workbench")


def tracker_for(cfg: ExperimentConfig, tracking_uri: str | None = None) -> Tracker:
    """The tracker of a config: ``--tracking-uri`` > $MLFLOW_TRACKING_URI > [tracking] >
    ``sqlite:///<cwd>/mlruns/mlflow.db``."""
    uri = resolve_tracking_uri(tracking_uri, cfg.tracking.tracking_uri, Path.cwd())
    return Tracker(uri, cfg.tracking.experiment or cfg.name)


def _flat(prefix: str, settings: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for key, value in settings.items():
        if isinstance(value, dict):
            out.update(_flat(f"{prefix}{key}.", value))
        else:
            out[f"{prefix}{key}"] = value
    return out


def score_metrics(targets: list[str], scores: Scores, prefix: str = "") -> dict[str, float]:
    """One system's errors in the metric schema every run shares (``evaluate``, ``sweep``
    and each of ``reproduce``'s systems): ``<prefix>test_mae/<target>`` and
    ``<prefix>test_mae_avg``, the same for ``test_mse``, ``cv_mae`` and ``cv_mse`` (a key
    whose list is empty is left out). The ``/`` groups a metric's targets in MLflow's charts
    and lines them up in its compare view. With bootstrap intervals, the average's 95%
    interval as ``<prefix>test_mae_avg_ci_low`` / ``_high`` (``test_mse``, and a model's
    paired ``test_mae_diff`` against the prior, likewise)."""
    m: dict[str, float] = {}
    for key in ("test_mae", "test_mse", "cv_mae", "cv_mse"):
        values = getattr(scores, key)
        if values:
            m[f"{prefix}{key}_avg"] = scores.avg(key)
            m.update({f"{prefix}{key}/{t}": v for t, v in zip(targets, values)})
    for key in ("test_mae", "test_mse", "test_mae_diff"):  # bootstrap 95% intervals
        bounds = getattr(scores, f"{key}_avg_ci", None)
        if bounds:
            m[f"{prefix}{key}_avg_ci_low"], m[f"{prefix}{key}_avg_ci_high"] = bounds
    return m


def result_metrics(result: Result, wall: bool = True) -> dict[str, float]:
    m: dict[str, float] = {"wall_s": result.wall_s} if wall else {}
    m.update(score_metrics(result.targets, result.model))
    m.update(score_metrics(result.targets, result.prior, "prior_"))
    for key in INTERVAL_KEYS:  # prediction intervals (none: empty)
        values = getattr(result.model, key)
        if values:
            m[f"{key}_avg"] = result.model.avg(key)
            for t, v in zip(result.targets, values):
                m[f"{key}/{t}"] = v
    for key in ("repeated_cv", "nested_cv_all"):
        est = getattr(result, key)
        if est is not None:
            m[f"{key}_mae_avg"] = est.model_mae_avg
            m[f"prior_{key}_mae_avg"] = est.prior_mae_avg
            for t, v in zip(result.targets, est.model_mae):
                m[f"{key}_mae/{t}"] = v
    if result.sweep is not None:
        s = result.sweep
        m["nested_cv_mae_avg"] = s.nested_cv_mae_avg
        m["prior_nested_cv_mae_avg"] = s.nested_cv_prior_mae_avg
        for t, v, p in zip(result.targets, s.nested_cv_mae, s.nested_cv_prior_mae):
            m[f"nested_cv_mae/{t}"] = v
            m[f"prior_nested_cv_mae/{t}"] = p
    return m


def log_sweep_children(tracker: Tracker, parent: str, sweep, trials: bool = True) -> None:
    for name, study in (sweep.studies.items() if trials else ()):
        for t in study.get_trials(deepcopy=False):
            if t.user_attrs.get("surplus"):
                continue
            run = tracker.start_run(f"{name} #{t.number}", parent_run_id=parent,
                                    tags={"workbench.kind": "trial", "study": name,
                                          "trial": t.number, "state": t.state.name},
                                    params=t.params)
            metrics = {"inner_cv_mae": t.value} if t.value is not None else {}
            if "prior_cv_mae" in t.user_attrs:
                metrics["prior_inner_cv_mae"] = t.user_attrs["prior_cv_mae"]
            for step, mae in enumerate(t.user_attrs.get("fold_mae", [])):
                tracker.log_metrics(run, {"fold_mae": mae}, step=step)
            tracker.log_metrics(run, metrics)
            tracker.end_run(run, "FINISHED" if t.state.name in ("COMPLETE", "PRUNED")
                            else "FAILED")
    for fold in sweep.outer_folds:
        run = tracker.start_run(f"{fold.unit} outer fold {fold.fold}", parent_run_id=parent,
                                tags={"workbench.kind": "outer_fold", "study": fold.study,
                                      "selected": fold.selected},
                                params=fold.params or {"prior_only": True})
        tracker.log_metrics(run, {"outer_mae": fold.mae, "prior_outer_mae": fold.prior_mae,
                                  "n_train": fold.n_train, "n_val": fold.n_val})
        tracker.end_run(run)


def _data_source(cfg: ExperimentConfig) -> str | None:
    """The file the dataset was read from (``None`` if unknown)."""
    base = cfg.path.parent if cfg.path is not None else Path.cwd()
    if cfg.data.csv:
        return str((base / cfg.data.csv).resolve())
    try:
        data_dir = (base / cfg.data.data_dir).resolve() if cfg.data.data_dir else None
        return str(BENCHMARKS[cfg.data.source].directory(data_dir, download=False))
    except Exception:  # the source is a label only
        return None


def config_text(cfg: ExperimentConfig) -> str | None:
    """The config file's text with every credential redacted (a storage or tracking URL's
    password), as the run and the model log it; ``None`` without a file."""
    if cfg.path is None:
        return None
    return redact_config(Path(cfg.path).read_text(encoding="utf-8"), str(cfg.path))


def source_tags(cfg: ExperimentConfig, kind: str, commit: str | None) -> dict[str, str]:
    """MLflow's source tags (the UI's "Source" column): the command and the git commit."""
    tags = {"mlflow.source.type": "LOCAL",
            "mlflow.source.name": f"workbench {kind} {cfg.path or cfg.name}"}
    if commit:
        tags["mlflow.source.git.commit"] = commit
    return tags


def run_tags(cfg: ExperimentConfig, ds, kind: str) -> dict[str, str]:
    """A run's tags: what made it (``workbench.kind``, the config, MLflow's source and git
    commit) and on which data (the dataset's name and content hash)."""
    commit = git_commit(Path(__file__).resolve().parents[2])
    return {"workbench.kind": kind, "config": str(cfg.path) if cfg.path else "",
            "dataset": ds.name, "dataset_hash": dataset_hash(ds.X, ds.targets),
            "git_commit": commit or "unknown", **source_tags(cfg, kind, commit)}


def run_params(cfg: ExperimentConfig, targets: list[str], n_train: int,
               n_test: int) -> dict[str, Any]:
    """A run's params: the seed, the split's sizes, the family, every target's model
    settings (``<target>.<setting>``), the family's and the intervals' settings."""
    family = cfg.family
    params: dict[str, Any] = {"random_state": cfg.random_state, "n_train": n_train,
                              "n_test": n_test, "family": family.name}
    for target in targets:
        params.update(_flat(f"{target}.", cfg.model_for(target)))
    if cfg.family_settings is not None:
        params.update(_flat(f"{family.name}.", cfg.family_settings.model_dump()))
    params.update(_flat("intervals.", cfg.intervals.model_dump()))
    return params


def log_inputs(tracker: Tracker, run_id: str, cfg: ExperimentConfig, ds, X_train, X_test,
               y_train, y_test) -> None:
    """The training and test rows (inputs and targets) as the run's MLflow datasets."""
    source = _data_source(cfg)
    for context, X, Y in (("training", X_train, y_train), ("test", X_test, y_test)):
        tracker.log_dataset(run_id, pd.concat([X, Y], axis=1), name=ds.name,
                            context=context, source=source)


#: MLflow's tag for a run's description (the run page's "Description", Markdown).
NOTE_TAG = "mlflow.note.content"


#: How a summary names the errors' unit when the data name none.
UNITS = "the targets' units"


def _description(cfg: ExperimentConfig, ds, kind: str, result: Result) -> str:
    """The run page's description: what ran on which rows, and how to read the metrics."""
    source = f"`{cfg.path}`" if cfg.path else f"config {cfg.name!r}"
    return (f"`workbench {kind}` of {source} (family {cfg.family.name}) on {ds.name}: fitted "
            f"on {result.n_train} training rows, every choice by CV on them; the "
            f"{result.n_test} test rows scored once. Metrics `test_mae/<target>`, "
            "`test_mae_avg`, `cv_mae/<target>`, ... (the control program's: `prior_...`) in "
            f"{ds.unit or UNITS} (MSE: squared).")


def record(cfg: ExperimentConfig, result: Result, model, ds, *, kind: str,
           tracking_uri: str | None = None, sweep=None, run_id: str | None = None,
           register: str | None = None) -> dict[str, str]:
    """Log one evaluate/sweep as a parent run (metrics, the chosen settings, the config file
    with its credentials redacted, the result, the training and test rows as MLflow datasets,
    MAE/MSE bars, the family's artifacts, the test rows' predictions, the model; for a sweep
    a child run per trial and per outer fold). Returns ids and URIs to add to the result.
    ``run_id``: log into this live run (see :func:`.lifecycle.command_run`; a sweep's trials
    are its children already) instead of a new one. ``register``: also register the model
    under this name in the store's Model Registry (the new version gets the alias
    ``champion``)."""
    tracker = tracker_for(cfg, tracking_uri)
    family = cfg.family
    X_train, X_test, y_train, y_test = ds.split(family.inputs(cfg, ds))
    tags = {**run_tags(cfg, ds, kind), NOTE_TAG: _description(cfg, ds, kind, result)}
    digest = tags["dataset_hash"]
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
        for metric, name in (("MAE", "mae_bars"), ("MSE", "mse_bars")):
            key = f"test_{metric.lower()}"
            fig = mae_bars(result.targets, getattr(result.prior, key),
                           getattr(result.model, key), metric=metric,
                           prior_ci=result.prior.ci(key), model_ci=result.model.ci(key),
                           unit=ds.unit if metric == "MAE" else squared(ds.unit),
                           title=f"Test {metric} per target", setting=setting)
            tracker.log_figure(run_id, fig, f"plots/{name}.png")
        intervals = interval_artifacts(cfg, ds, model, setting)
        for name, fig in intervals.figures.items():
            tracker.log_figure(run_id, fig, f"plots/{name}.png")
        for name, table in intervals.tables.items():
            tracker.log_text(run_id, table.to_csv(index=False), f"intervals/{name}.csv")
        # the test rows' predictions, as `workbench predict` and a served model give them
        predictions = prediction_frame(model, X_test, result.targets)
        tracker.log_text(run_id, predictions.to_csv(index_label="row"), "predictions/test.csv")
        model_uri = tracker.log_model(run_id, model, X_test.head(5), targets=result.targets,
                                      texts={"config.toml": config} if config else None)
        extra = finish_artifacts(lambda name, fig: tracker.log_figure(run_id, fig,
                                                                      f"plots/{name}.png"))
        for name, table in extra.tables.items():
            tracker.log_text(run_id, table.to_csv(index=False), f"{family.name}/{name}.csv")
        for name, data in extra.data.items():
            tracker.log_dict(run_id, data, f"{name}.json")
        tracker.set_tags(run_id, {"model_uri": model_uri,
                                  "selected": ",".join(result.model.selected)})
        tracker.share_view(metric_view(result.targets))  # `workbench ui`'s link opens it
        out = {"tracking_uri": redact(tracker.tracking_uri), "experiment_id": tracker.experiment_id,
               "run_id": run_id, "model_uri": model_uri}
        if register:
            version = tracker.register_model(
                model_uri, register, run_id=run_id,
                tags={"workbench.kind": kind, "config": tags["config"],
                      "config_name": cfg.name, "dataset": ds.name, "dataset_hash": digest,
                      "git_commit": tags["git_commit"], "family": family.name,
                      "test_mae_avg": f"{result.model.avg('test_mae'):.6g}",
                      "cv_mae_avg": f"{result.model.avg('cv_mae'):.6g}",
                      "prior_test_mae_avg": f"{result.prior.avg('test_mae'):.6g}"},
                description=f"{kind} of {cfg.name} (run {run_id})")
            log.info("[%s] registered %s version %s (alias %s)", cfg.name, register, version,
                     CHAMPION)
            tracker.set_tags(run_id, {"registered_model": f"{register}/{version}"})
            out.update(registered_model=register, registered_version=version,
                       registered_uri=f"models:/{register}@{CHAMPION}")
        if sweep is not None:
            log_sweep_children(tracker, run_id, sweep, trials=not live)
    return out


def record_wall_time(cfg: ExperimentConfig, result: Result, *, tracking_uri: str | None,
                     run_id: str) -> None:
    """The command's whole wall time, once everything else is logged: the run's ``wall_s``
    metric and its ``result.json`` get the figure the command prints and ``--json``
    writes."""
    tracker = tracker_for(cfg, tracking_uri)
    tracker.log_metrics(run_id, {"wall_s": result.wall_s})
    tracker.log_dict(run_id, json.loads(json.dumps(result.to_json(), default=str)),
                     "result.json")

