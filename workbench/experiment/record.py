"""Record an ``evaluate`` or ``sweep`` in MLflow: one parent run with the metrics, the config,
the figures (MAE/MSE bars, an augmented learning curve and a SHAP summary per target) and the
fitted multi-target model; for a sweep, a child run per trial and per outer fold.

For family hamiltonian the per-target learning curves and SHAP summaries (which need one
single-target model per target) are replaced by the parameter-space model's own outputs:
the parameter-correction and selection-path figures and the coefficient, corrected-parameter
and selection-path tables (CSV) of :mod:`workbench.experiment.parameters`."""

from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import pandas as pd

from ..curves import augmented_learning_curve
from ..datasets import Dataset
from .config import ExperimentConfig, model_inputs
from .figures import learning_curve_figure, mae_bars, shap_summary
from .tracking import Tracker, _redact, dataset_hash, git_commit, resolve_tracking_uri

__all__ = ["curve_sizes", "record", "tracker_for"]


def tracker_for(cfg: ExperimentConfig, tracking_uri: str | None = None) -> Tracker:
    """The tracker of a config: ``--tracking-uri`` > $MLFLOW_TRACKING_URI > [tracking] >
    ``sqlite:///<cwd>/mlruns/mlflow.db``."""
    uri = resolve_tracking_uri(tracking_uri, cfg.tracking["tracking_uri"], Path.cwd())
    return Tracker(uri, cfg.tracking["experiment"] or cfg.name)


def curve_sizes(n_rows: int, folds: int, points: int = 5) -> list[int]:
    """Training sizes from a quarter of the fold-training size up to all of it."""
    largest = n_rows - -(-n_rows // folds)  # rows left for training in the largest fold
    return sorted({int(s) for s in np.linspace(max(5, largest // 4), largest, points)})


def _flat(prefix: str, settings: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for key, value in settings.items():
        if isinstance(value, dict):
            out.update(_flat(f"{prefix}{key}.", value))
        else:
            out[f"{prefix}{key}"] = value
    return out


def _metrics(result: dict[str, Any]) -> dict[str, float]:
    m: dict[str, float] = {"wall_s": result["wall_s"]}
    for part, prefix in (("model", ""), ("prior", "prior_")):
        for key in ("test_mae", "test_mse", "cv_mae", "cv_mse"):
            m[f"{prefix}{key}_avg"] = result[part][f"{key}_avg"]
            for t, v in zip(result["targets"], result[part][key]):
                m[f"{prefix}{key}.{t}"] = v
    for key in ("repeated_cv", "nested_cv_all"):
        if key in result:
            m[f"{key}_mae_avg"] = result[key]["model_mae_avg"]
            m[f"prior_{key}_mae_avg"] = result[key]["prior_mae_avg"]
            for t, v in zip(result["targets"], result[key]["model_mae"]):
                m[f"{key}_mae.{t}"] = v
    if "nested_cv_mae" in result:
        m["nested_cv_mae_avg"] = result["nested_cv_mae_avg"]
        m["prior_nested_cv_mae_avg"] = result["nested_cv_prior_mae_avg"]
        for t, v, p in zip(result["targets"], result["nested_cv_mae"],
                           result["nested_cv_prior_mae"]):
            m[f"nested_cv_mae.{t}"] = v
            m[f"prior_nested_cv_mae.{t}"] = p
    return m


def _hamiltonian_artifacts(tracker: Tracker, run_id: str, model, ds: Dataset,
                           setting: str) -> None:
    from .parameters import hamiltonian_outputs

    tables, figures = hamiltonian_outputs(model, ds, setting)
    for name, fig in figures.items():
        tracker.log_figure(run_id, fig, f"plots/{name}.png")
    for name, table in tables.items():
        tracker.log_text(run_id, table.to_csv(index=False), f"hamiltonian/{name}.csv")


def _figures(tracker: Tracker, run_id: str, cfg: ExperimentConfig, result, model, ds: Dataset,
             setting: str, progress) -> dict[str, Any]:
    X_train, _, y_train, _ = ds.split()
    for metric, key, name in (("MAE", "test_mae", "mae_bars"), ("MSE", "test_mse", "mse_bars")):
        fig = mae_bars(result["targets"], result["prior"][key], result["model"][key],
                       metric=metric, unit="MHz" if metric == "MAE" else "MHz²",
                       title=f"Test {metric} per target", setting=setting)
        tracker.log_figure(run_id, fig, f"plots/{name}.png")
    if cfg.family == "hamiltonian":
        _hamiltonian_artifacts(tracker, run_id, model, ds, setting)
        return {}
    folds = cfg.selection["cv"]
    sizes = curve_sizes(len(X_train), folds)
    curves = {}
    for target, est in zip(result["targets"], model.estimators_):
        if progress:
            print(f"[{cfg.name}] figures for {target}: learning curve at sizes {sizes}, SHAP",
                  file=progress, flush=True)
        curve = augmented_learning_curve(est.estimator, X_train, y_train[target].to_numpy(),
                                         train_sizes=sizes, cv=folds,
                                         random_state=cfg.random_state)
        curves[target] = curve.to_dict()
        tracker.log_figure(run_id, learning_curve_figure(curve, target=target, setting=setting),
                           f"plots/learning_curve_{target}.png")
        used = est.best_estimator_
        cols = _columns(used, X_train)
        Xs = X_train[cols]
        base = X_train.iloc[[0]].to_numpy()  # columns the model does not read stay constant

        def predict(a, used=used, cols=cols, base=base):
            frame = pd.DataFrame(np.repeat(base, len(a), axis=0), columns=X_train.columns)
            frame[cols] = a
            return used.predict(frame)

        fig, _ = shap_summary(predict, Xs, target=target, setting=setting,
                              nsamples="auto" if len(cols) <= 10 else 256,
                              background_size=min(30, len(Xs)))
        tracker.log_figure(run_id, fig, f"plots/shap_{target}.png")
    tracker.log_dict(run_id, curves, "learning_curves.json")
    return curves


def _columns(fitted, X: pd.DataFrame) -> list[str]:
    """The columns a fitted per-target model reads: its basis inputs and its prior column."""
    names = list(X.columns)
    prior = getattr(fitted, "prior", None)
    cols = [names[i] for i in getattr(fitted, "basis_columns_", [])]
    if isinstance(prior, str) and prior not in cols:
        cols.append(prior)
    return cols or names


def _record_sweep_children(tracker: Tracker, parent: str, details: dict[str, Any],
                           trials: bool = True) -> None:
    for name, study in (details["studies"].items() if trials else ()):
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
    for fold in details["outer_folds"]:
        run = tracker.start_run(f"{fold['target']} outer fold {fold['fold']}",
                                parent_run_id=parent,
                                tags={"workbench.kind": "outer_fold", "study": fold["study"],
                                      "selected": fold["selected"]},
                                params=fold["params"] or {"prior_only": True})
        tracker.log_metrics(run, {"outer_mae": fold["mae"], "prior_outer_mae": fold["prior_mae"],
                                  "n_train": fold["n_train"], "n_val": fold["n_val"]})
        tracker.end_run(run)


def record(cfg: ExperimentConfig, result: dict[str, Any], model, ds: Dataset, *, kind: str,
           tracking_uri: str | None = None, details: dict[str, Any] | None = None,
           settings: dict[str, dict[str, Any]] | None = None,
           progress: TextIO | None | bool = True, run_id: str | None = None) -> dict[str, str]:
    """Log one evaluate/sweep as a parent run; returns ids and URIs to add to the result.
    ``run_id``: log into this live run (see :func:`.lifecycle.command_run`; a sweep's trials
    are its children already) instead of a new one."""
    if progress is True:
        progress = sys.stderr
    tracker = tracker_for(cfg, tracking_uri)
    X_train, X_test, y_train, y_test = ds.split(model_inputs(cfg, ds))
    tags = {"workbench.kind": kind, "config": str(cfg.path) if cfg.path else "",
            "dataset": ds.name, "dataset_hash": dataset_hash(ds.X, ds.targets),
            "git_commit": git_commit(Path(__file__).resolve().parents[2]) or "unknown"}
    params: dict[str, Any] = {"random_state": cfg.random_state, "n_train": len(X_train),
                              "n_test": len(X_test)}
    for target in result["targets"]:
        chosen = (settings or {}).get(target) or cfg.model_for(target)
        params.update(_flat(f"{target}.", chosen))
    if cfg.family == "hamiltonian":
        params["family"] = "hamiltonian"
        params.update(_flat("hamiltonian.", cfg.hamiltonian))
    setting = f"{kind} of {cfg.name}"
    live = run_id is not None
    if live:
        tracker.set_tags(run_id, tags)
        tracker.log_params(run_id, params)
    with (contextlib.nullcontext(run_id) if live
          else tracker.run(f"{kind} {cfg.name}", tags=tags, params=params)) as run_id:
        if progress:
            print(f"[{cfg.name}] tracking in {_redact(tracker.tracking_uri)} (run {run_id})",
                  file=progress, flush=True)
        tracker.log_metrics(run_id, _metrics(result))
        if cfg.path is not None:
            tracker.log_file(run_id, cfg.path)
        tracker.log_dict(run_id, json.loads(json.dumps(result, default=str)), "result.json")
        _figures(tracker, run_id, cfg, result, model, ds, setting, progress)
        model_uri = tracker.log_model(run_id, model, X_test.head(5))
        tracker.set_tags(run_id, {"model_uri": model_uri, "selected": ",".join(model.selected_)})
        if details is not None:
            _record_sweep_children(tracker, run_id, details, trials=not live)
    return {"tracking_uri": tracker.tracking_uri, "experiment_id": tracker.experiment_id,
            "run_id": run_id, "model_uri": model_uri}
