"""What every MLflow run of the workbench carries, in one schema.

The metrics every run shares (``evaluate``, ``sweep`` and each of ``reproduce``'s systems:
``test_mae/<target>``, ``test_mae_avg``, ...), the tags naming what made the run and on
which data, the params, the training and test rows as MLflow datasets, the config's text
with its credentials redacted, and a sweep's trials and outer folds as child runs.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

import pandas as pd

from ...datasets import BENCHMARKS, Dataset
from ..config import ExperimentConfig
from ..config.overrides import apply_overrides, dump_config, format_overrides
from ..process.errors import redact_config
from ..scoring.results import Result
from ..scoring.scores import INTERVAL_KEYS, Scores
from ..tracking.records import dataset_hash, git_commit
from ..tracking.runs import Tracker

__all__ = ["NOTE_TAG", "config_text", "log_inputs", "log_sweep_children", "result_metrics",
           "run_params", "run_tags", "score_metrics", "source_tags"]


def _flat(prefix: str, settings: dict[str, Any]) -> dict[str, Any]:
    """Flatten nested settings into ``<prefix><key>.<key>`` params."""
    out = {}
    for key, value in settings.items():
        if isinstance(value, dict):
            out.update(_flat(f"{prefix}{key}.", value))
        else:
            out[f"{prefix}{key}"] = value
    return out


def score_metrics(targets: list[str], scores: Scores, prefix: str = "") -> dict[str, float]:
    """Write one system's errors in the metric schema every run shares.

    The schema of ``evaluate``, ``sweep`` and each of ``reproduce``'s systems:
    ``<prefix>test_mae/<target>`` and ``<prefix>test_mae_avg``, the same for ``test_mse``,
    ``cv_mae`` and ``cv_mse`` (a key whose list is empty is left out). The ``/`` groups a
    metric's targets in MLflow's charts and lines them up in its compare view. With bootstrap
    intervals, the average's 95% interval as ``<prefix>test_mae_avg_ci_low`` / ``_high``
    (``test_mse``, and a model's paired ``test_mae_diff`` against the prior, likewise).

    Parameters
    ----------
    targets : list of str
        The targets, in the scores' order.
    scores : Scores
        The system's errors.
    prefix : str, default=""
        Before every key (``"prior_"`` for the control program beside a model).

    Returns
    -------
    dict of str to float
        The metrics.
    """
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
    """Write a result's metrics: the model's and the prior's errors, intervals and CV.

    Parameters
    ----------
    result : Result
        The result.
    wall : bool, default=True
        Include ``wall_s`` (a command's run gets it at the end instead).

    Returns
    -------
    dict of str to float
        :func:`score_metrics` of the model and (``prior_``) of the prior, the prediction
        intervals' coverage and width, and the repeated, nested and sweep CV estimates.
    """
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


def log_sweep_children(tracker: Tracker, parent: str, sweep: Any, trials: bool = True) -> None:
    """Log a sweep's trials and outer folds as child runs of ``parent``.

    Parameters
    ----------
    tracker : Tracker
        The MLflow experiment.
    parent : str
        The parent run's id.
    sweep : Sweep
        The finished sweep (:func:`~workbench.experiment.sweep.search.run_sweep`).
    trials : bool, default=True
        Log a run per trial too (a live command's trials are logged as they finish).
    """
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
        run = tracker.start_run(f"{fold.block} outer fold {fold.fold}", parent_run_id=parent,
                                tags={"workbench.kind": "outer_fold", "study": fold.study,
                                      "selected": fold.selected},
                                params=fold.params or {"prior_only": True})
        tracker.log_metrics(run, {"outer_mae": fold.mae, "prior_outer_mae": fold.prior_mae,
                                  "n_train": fold.n_train, "n_val": fold.n_val})
        tracker.end_run(run)


def _data_source(cfg: ExperimentConfig) -> str | None:
    """Name the file the dataset was read from (``None`` if unknown)."""
    base = cfg.path.parent if cfg.path is not None else Path.cwd()
    if cfg.data.csv:
        return str((base / cfg.data.csv).resolve())
    try:
        data_dir = (base / cfg.data.data_dir).resolve() if cfg.data.data_dir else None
        return str(BENCHMARKS[cfg.data.source].directory(data_dir, download=False))
    except Exception:  # the source is a label only
        return None


def config_text(cfg: ExperimentConfig) -> str | None:
    """Read the config file with every credential redacted, as the run and the model log it.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.

    Returns
    -------
    str or None
        The file's text, a storage or tracking URL's password redacted; ``None`` without a
        file. With ``--set`` overrides, the file's tables with them applied, written anew
        (its comments lost) below a header naming the file and the overrides.
    """
    if cfg.path is None:
        return None
    text = Path(cfg.path).read_text(encoding="utf-8")
    if cfg.overrides:
        header = f"{cfg.path} with --set {format_overrides(cfg.overrides)}"
        text = dump_config(apply_overrides(tomllib.loads(text), cfg.overrides), header)
    return redact_config(text, str(cfg.path))


def source_tags(cfg: ExperimentConfig, kind: str, commit: str | None) -> dict[str, str]:
    """Write MLflow's source tags (the UI's "Source" column): the command and the git commit.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run.
    kind : str
        The command.
    commit : str or None
        The git commit, if known.

    Returns
    -------
    dict of str to str
        The tags.
    """
    tags = {"mlflow.source.type": "LOCAL",
            "mlflow.source.name": f"workbench {kind} {cfg.path or cfg.name}"}
    if commit:
        tags["mlflow.source.git.commit"] = commit
    return tags


def run_tags(cfg: ExperimentConfig, ds: Dataset, kind: str) -> dict[str, str]:
    """Write a run's tags: what made it and on which data.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run.
    ds : Dataset
        Its data.
    kind : str
        The command.

    Returns
    -------
    dict of str to str
        ``workbench.kind``, the config, MLflow's source and git commit, the dataset's name
        and content hash.
    """
    commit = git_commit(Path(__file__).resolve().parents[2])
    return {"workbench.kind": kind, "config": str(cfg.path) if cfg.path else "",
            "dataset": ds.name, "dataset_hash": dataset_hash(ds.X, ds.targets),
            "git_commit": commit or "unknown", **source_tags(cfg, kind, commit)}


def run_params(cfg: ExperimentConfig, targets: list[str], n_train: int,
               n_test: int, folds: str = "") -> dict[str, Any]:
    """Write a run's params.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run.
    targets : list of str
        Its targets.
    n_train, n_test : int
        The split's sizes.
    folds : str, default=""
        Which CV folds made the choices (:attr:`~.results.Result.folds`; empty: not logged).

    Returns
    -------
    dict
        The seed, the split's sizes, the folds, the family, every target's model settings
        (``<target>.<setting>``), the family's and the intervals' settings, and each
        ``--set`` override as ``set.<SECTION.KEY>``.
    """
    family = cfg.family
    params: dict[str, Any] = {"random_state": cfg.random_state, "n_train": n_train,
                              "n_test": n_test, "family": family.name}
    if folds:
        params["folds"] = folds
    for target in targets:
        params.update(_flat(f"{target}.", cfg.model_for(target)))
    if cfg.family_settings is not None:
        params.update(_flat(f"{family.name}.", cfg.family_settings.model_dump()))
    params.update(_flat("intervals.", cfg.intervals.model_dump()))
    params.update({f"set.{key}": json.dumps(value) for key, value in cfg.overrides.items()})
    return params


def log_inputs(tracker: Tracker, run_id: str, cfg: ExperimentConfig, ds: Dataset,
               X_train: pd.DataFrame, X_test: pd.DataFrame, y_train: pd.DataFrame,
               y_test: pd.DataFrame) -> None:
    """Log the training and test rows (inputs and targets) as the run's MLflow datasets.

    Parameters
    ----------
    tracker : Tracker
        The MLflow experiment.
    run_id : str
        The run.
    cfg : ExperimentConfig
        The config (where the data came from).
    ds : Dataset
        The data (its name).
    X_train, X_test, y_train, y_test : pandas.DataFrame
        The rows, as the model saw them.
    """
    source = _data_source(cfg)
    for context, X, Y in (("training", X_train, y_train), ("test", X_test, y_test)):
        tracker.log_dataset(run_id, pd.concat([X, Y], axis=1), name=ds.name,
                            context=context, source=source)


#: MLflow's tag for a run's description (the run page's "Description", Markdown).
NOTE_TAG = "mlflow.note.content"


def log_test_predictions(tracker: Tracker, run_id: str, ds: Dataset,
                         predictions: pd.DataFrame) -> None:
    """Log the test rows' predictions and, beside them, their measured targets.

    ``predictions/test.csv`` holds the predictions as ``workbench predict`` gives them,
    ``predictions/test_measured.csv`` the targets of the same rows: together they let
    ``workbench compare`` pair two runs' errors row by row.

    Parameters
    ----------
    tracker : Tracker
        The tracker.
    run_id : str
        The run.
    ds : Dataset
        The data the rows come from.
    predictions : DataFrame
        Indexed by test row, one column per target (interval columns may follow).
    """
    targets = [t for t in ds.target_names if t in predictions.columns]
    tracker.log_text(run_id, predictions.to_csv(index_label="row"), "predictions/test.csv")
    measured = ds.targets.loc[predictions.index, targets]
    tracker.log_text(run_id, measured.to_csv(index_label="row"),
                     "predictions/test_measured.csv")
