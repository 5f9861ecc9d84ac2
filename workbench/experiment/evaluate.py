"""``workbench evaluate``: fit a config's model on the training rows, score it once on the test rows."""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

import numpy as np

from ..datasets import Dataset
from ..multitarget import MultiTargetBaseBoost
from .config import ExperimentConfig, build_model, load_dataset

__all__ = ["evaluate", "fit_and_score", "format_table"]


def _mae(a, b) -> np.ndarray:
    return np.mean(np.abs(np.asarray(a) - np.asarray(b)), axis=0)


def _mse(a, b) -> np.ndarray:
    return np.mean((np.asarray(a) - np.asarray(b)) ** 2, axis=0)


def _avg(values) -> float:
    return float(np.mean(values))


def evaluate(cfg: ExperimentConfig, progress: TextIO | None | bool = True,
             return_model: bool = False):
    """Fit per target on the training rows (model selection by CV on those rows only), then
    score prior and model on the test rows. Returns the JSON-ready result (and, with
    ``return_model``, the fitted model and the dataset too).

    ``progress``: a stream for progress lines, ``True`` for the current ``sys.stderr``,
    ``None``/``False`` for none."""
    start = time.perf_counter()
    if progress is True:
        progress = sys.stderr
    ds = load_dataset(cfg)
    if progress:
        print(f"[{cfg.name}] fitting {len(ds.target_names)} targets on {len(ds.train_index)} "
              f"training rows (test rows: {len(ds.test_index)})", file=progress, flush=True)
    result, model = fit_and_score(cfg, ds, build_model(cfg, ds))
    result["wall_s"] = time.perf_counter() - start
    return (result, model, ds) if return_model else result


def fit_and_score(cfg: ExperimentConfig, ds: Dataset, model: MultiTargetBaseBoost):
    """Fit ``model`` (one BaseBoostCV per target) on the training rows and score prior and
    model once on the test rows. Returns ``(result, fitted model)``."""
    X_train, X_test, y_train, y_test = ds.split()
    model.fit(X_train, y_train)
    pred = model.predict(X_test).to_numpy()
    prior_test = ds.prior.loc[ds.test_index].to_numpy()
    cvs = model.estimators_
    result = {
        "name": cfg.name,
        "config": str(cfg.path) if cfg.path else None,
        "targets": ds.target_names,
        "n_train": len(X_train),
        "n_test": len(X_test),
        "prior": {
            "test_mae": _mae(y_test, prior_test).tolist(),
            "test_mse": _mse(y_test, prior_test).tolist(),
            "cv_mae": [float(-np.mean(e.cv_scores_prior_)) for e in cvs],
        },
        "model": {
            "test_mae": _mae(y_test, pred).tolist(),
            "test_mse": _mse(y_test, pred).tolist(),
            "cv_mae": [-e.cv_score_ for e in cvs],
            "cv_mae_boosted": [float(-np.mean(e.cv_scores_boosted_)) for e in cvs],
            "selected": model.selected_,
            "coefs": [e.best_estimator_.coefs_.tolist() if e.selected_ == "boosted" else []
                      for e in cvs],
        },
    }
    for part in ("prior", "model"):
        for key in ("test_mae", "test_mse", "cv_mae"):
            result[part][f"{key}_avg"] = _avg(result[part][key])
    return result, model


def format_table(result: dict[str, Any]) -> str:
    """Per-target table: prior and model test MAE, the model's CV MAE and what was selected."""
    w = max(10, *(len(t) + 2 for t in result["targets"]))
    rule = "-" * (w + 46)
    lines = [f"{'target':<{w}}{'prior MAE':>11}{'model MAE':>11}{'model CV MAE':>14}  selected",
             rule]
    rows = zip(result["targets"], result["prior"]["test_mae"], result["model"]["test_mae"],
               result["model"]["cv_mae"], result["model"]["selected"])
    for name, p, m, c, s in rows:
        lines.append(f"{name:<{w}}{p:>11.3f}{m:>11.3f}{c:>14.3f}  {s}")
    lines.append(rule)
    lines.append(f"{'average':<{w}}{result['prior']['test_mae_avg']:>11.3f}"
                 f"{result['model']['test_mae_avg']:>11.3f}{result['model']['cv_mae_avg']:>14.3f}")
    lines.append(f"test MAE in the targets' units (MHz for the benchmark); "
                 f"wall time {result['wall_s']:.1f} s")
    return "\n".join(lines)
