"""``workbench evaluate``: fit a config's model on the training rows, score it once on the test rows."""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

import numpy as np
import pandas as pd
from sklearn.base import clone
from sklearn.model_selection import KFold

from ..datasets import Dataset
from ..fitted_prior import FittedPriorBoost
from ..param_select import HamiltonianSelectionCV
from .config import ExperimentConfig, build_model, load_dataset, model_inputs

__all__ = ["evaluate", "fit_and_score", "fixed_choices", "format_table", "nested_cv_all",
           "physics_regressor", "repeated_cv"]


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
    ev = cfg.evaluation
    if ev["cv_repeats"] > 0:
        _say(progress, f"[{cfg.name}] repeated CV of the chosen model on the training rows "
                       f"({ev['cv_repeats']} x {ev['cv_folds']} folds)")
        rep = repeated_cv(cfg, ds, fixed_choices(model))
        result["repeated_cv"] = rep
        if cfg.family == "hamiltonian":
            for key in ("mae", "mse"):
                result["model"][f"cv_{key}"] = rep[f"model_{key}"]
                result["model"][f"cv_{key}_avg"] = rep[f"model_{key}_avg"]
    if ev["nested_folds"] > 0:
        _say(progress, f"[{cfg.name}] nested CV over all {len(ds.targets)} rows "
                       f"({ev['nested_folds']} outer folds, every choice remade inside)")
        result["nested_cv_all"] = nested_cv_all(cfg, ds, progress=progress)
    result["wall_s"] = time.perf_counter() - start
    return (result, model, ds) if return_model else result


def _say(progress, text: str) -> None:
    if progress:
        print(text, file=progress, flush=True)


def fixed_choices(model):
    """An unfitted copy of a fitted model with the choices it made on its training rows kept
    (the parameter-space model's selected covariates); other models are cloned as they are
    (BaseBoostCV repeats its own selection wherever it is fitted)."""
    if isinstance(model, FittedPriorBoost) and isinstance(model.physics_, HamiltonianSelectionCV):
        return clone(model).set_params(physics=model.physics_.selection_.estimator())
    return clone(model)


def _oof(model, X: pd.DataFrame, Y: pd.DataFrame, splits, progress=None, label=""
         ) -> np.ndarray:
    """Out-of-fold predictions of ``model`` refitted on each split's training rows."""
    pred = np.empty(Y.shape)
    for k, (train, val) in enumerate(splits):
        fitted = clone(model).fit(X.iloc[train], Y.iloc[train])
        pred[val] = np.asarray(fitted.predict(X.iloc[val]), dtype=float)
        if label:
            _say(progress, f"{label}: outer fold {k + 1}/{len(splits)} MAE "
                           f"{np.abs(pred[val] - Y.iloc[val].to_numpy()).mean():.3f}")
    return pred


def repeated_cv(cfg: ExperimentConfig, ds: Dataset, model) -> dict[str, Any]:
    """Repeated K-fold CV MAE (``[evaluation]`` cv_folds, cv_repeats, seeds cv_seed...) of
    ``model`` (unfitted) on the training rows only, with the control program's MAE there."""
    ev = cfg.evaluation
    X = model_inputs(cfg, ds).loc[ds.train_index]
    Y = ds.targets.loc[ds.train_index]
    preds = [_oof(model, X, Y, KFold(ev["cv_folds"], shuffle=True,
                                     random_state=ev["cv_seed"] + r).split(X))
             for r in range(ev["cv_repeats"])]
    per_repeat = [_mae(Y, p) for p in preds]
    mae = np.mean(per_repeat, axis=0)
    mse = np.mean([_mse(Y, p) for p in preds], axis=0)
    prior = _mae(Y, ds.prior.loc[ds.train_index].to_numpy())
    return {"folds": ev["cv_folds"], "repeats": ev["cv_repeats"], "seed": ev["cv_seed"],
            "model_mae": mae.tolist(), "model_mae_avg": _avg(mae),
            "model_mse": mse.tolist(), "model_mse_avg": _avg(mse),
            "model_mae_avg_per_repeat": [_avg(m) for m in per_repeat],
            "prior_mae": prior.tolist(), "prior_mae_avg": _avg(prior)}


def nested_cv_all(cfg: ExperimentConfig, ds: Dataset, progress: TextIO | None = None
                  ) -> dict[str, Any]:
    """Nested CV over every row (training and test): in each of ``nested_folds`` outer folds
    the whole model, every choice included, is fitted on the other rows and scored on the
    fold's rows. The least noisy estimate for small data; no choice is made from it."""
    ev = cfg.evaluation
    X, Y = model_inputs(cfg, ds), ds.targets
    splits = list(KFold(ev["nested_folds"], shuffle=True,
                        random_state=ev["nested_seed"]).split(X))
    pred = _oof(build_model(cfg, ds), X, Y, splits, progress, f"[{cfg.name}] nested CV")
    mae, mse = _mae(Y, pred), _mse(Y, pred)
    prior = _mae(Y, ds.prior.to_numpy())
    return {"folds": ev["nested_folds"], "seed": ev["nested_seed"], "n_rows": len(Y),
            "model_mae": mae.tolist(), "model_mae_avg": _avg(mae),
            "model_mse": mse.tolist(), "model_mse_avg": _avg(mse),
            "prior_mae": prior.tolist(), "prior_mae_avg": _avg(prior)}


def fit_and_score(cfg: ExperimentConfig, ds: Dataset, model):
    """Fit ``model`` (the config's, from :func:`build_model`) on the training rows and score
    prior and model once on the test rows. Returns ``(result, fitted model)``."""
    X_train, X_test, y_train, y_test = ds.split(model_inputs(cfg, ds))
    model.fit(X_train, y_train)
    pred = model.predict(X_test).to_numpy()
    prior_test = ds.prior.loc[ds.test_index].to_numpy()
    if cfg.family == "hamiltonian":
        result = _hamiltonian_result(cfg, ds, model, pred, prior_test, y_test, y_train)
    else:
        result = _eigenvalue_result(cfg, ds, model, pred, prior_test, y_test, y_train)
    for part in ("prior", "model"):
        for key in ("test_mae", "test_mse", "cv_mae", "cv_mse"):
            result[part][f"{key}_avg"] = _avg(result[part][key])
    return result, model


def _cv_mse(y, predictions) -> float:
    """MSE of out-of-fold predictions (rows without one, e.g. failed folds, left out)."""
    y, p = np.asarray(y, dtype=float), np.asarray(predictions, dtype=float)
    ok = np.isfinite(p)
    return float(np.mean((y[ok] - p[ok]) ** 2)) if ok.any() else float("nan")


def _eigenvalue_result(cfg, ds, model, pred, prior_test, y_test, y_train) -> dict[str, Any]:
    """Result of family eigenvalue: CV figures are BaseBoostCV's own (its folds of the
    training rows): ``cv_mae`` the mean fold score, ``cv_mse`` from the out-of-fold
    predictions."""
    cvs = model.estimators_
    Y = y_train.to_numpy(dtype=float)
    n_train = len(Y)
    return {
        "name": cfg.name,
        "config": str(cfg.path) if cfg.path else None,
        "targets": ds.target_names,
        "family": cfg.family,
        "n_train": n_train,
        "n_test": len(y_test),
        "prior": {
            "test_mae": _mae(y_test, prior_test).tolist(),
            "test_mse": _mse(y_test, prior_test).tolist(),
            "cv_mae": [float(-np.mean(e.cv_scores_prior_)) for e in cvs],
            "cv_mse": [_cv_mse(Y[:, j], e.cv_predictions_prior_) for j, e in enumerate(cvs)],
        },
        "model": {
            "test_mae": _mae(y_test, pred).tolist(),
            "test_mse": _mse(y_test, pred).tolist(),
            "cv_mae": [-e.cv_score_ for e in cvs],
            "cv_mse": [_cv_mse(Y[:, j], e.cv_predictions_) for j, e in enumerate(cvs)],
            "cv_mae_boosted": [float(-np.mean(e.cv_scores_boosted_)) for e in cvs],
            "selected": model.selected_,
            "coefs": [e.best_estimator_.coefs_.tolist() if e.selected_ == "boosted" else []
                      for e in cvs],
        },
    }


def _records(table: pd.DataFrame) -> list[dict[str, Any]]:
    """Rows as JSON-ready dicts (NaN -> None)."""
    return table.astype(object).where(table.notna(), None).to_dict(orient="records")


def physics_regressor(model: FittedPriorBoost):
    """The fitted :class:`~workbench.param_boost.HamiltonianParameterRegressor` inside a
    fitted family-hamiltonian model (after its covariate selection, if any)."""
    physics = model.physics_
    return physics.estimator_ if isinstance(physics, HamiltonianSelectionCV) else physics


def _hamiltonian_result(cfg, ds, model: FittedPriorBoost, pred, prior_test, y_test,
                        y_train) -> dict[str, Any]:
    """Result of family hamiltonian. ``model.cv_mae`` is the CV MAE of the parameter-space
    model's fixed choices on the training rows (replaced by the repeated CV when
    ``[evaluation] cv_repeats`` > 0); ``selected`` says, per target, whether the
    eigenvalue-space stage was kept."""
    physics = model.physics_
    regressor = physics_regressor(model)
    prior_train = ds.prior.loc[ds.train_index].to_numpy()
    ham: dict[str, Any] = {
        "covariates": regressor.covariate_names_,
        "coefficients": _records(regressor.coefficient_table()),
        "n_iter": regressor.n_iter_,
    }
    if isinstance(physics, HamiltonianSelectionCV):
        sel = physics.selection_
        ham["selection"] = {"cv_mae": sel.cv_mae, "steps": len(sel.path) - 1,
                            "folds": physics.cv, "repeats": physics.n_repeats,
                            "path": _records(sel.path),
                            "seconds": sel.seconds}
    boosted = model.boost_stage
    cvs = model.boost_.estimators_ if boosted else []
    Y = y_train.to_numpy(dtype=float)
    nan = [float("nan")] * len(ds.target_names)
    stage_cv = [float(-np.mean(e.cv_scores_prior_)) for e in cvs] if boosted else nan
    return {
        "name": cfg.name,
        "config": str(cfg.path) if cfg.path else None,
        "family": cfg.family,
        "targets": ds.target_names,
        "n_train": len(y_train),
        "n_test": len(y_test),
        "prior": {
            "test_mae": _mae(y_test, prior_test).tolist(),
            "test_mse": _mse(y_test, prior_test).tolist(),
            "cv_mae": _mae(y_train, prior_train).tolist(),  # no fit: CV MAE = training MAE
            "cv_mse": _mse(y_train, prior_train).tolist(),
        },
        "model": {
            "test_mae": _mae(y_test, pred).tolist(),
            "test_mse": _mse(y_test, pred).tolist(),
            "cv_mae": [-e.cv_score_ for e in cvs] if boosted else stage_cv,
            "cv_mse": ([_cv_mse(Y[:, j], e.cv_predictions_) for j, e in enumerate(cvs)]
                       if boosted else nan),
            "cv_mae_hamiltonian": stage_cv,
            "selected": ["hamiltonian+boosted" if s == "boosted" else "hamiltonian"
                         for s in model.selected_],
            "coefs": [e.best_estimator_.coefs_.tolist() if e.selected_ == "boosted" else []
                      for e in cvs],
        },
        "hamiltonian": ham,
    }


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
    if "repeated_cv" in result:
        r = result["repeated_cv"]
        lines.append(f"repeated CV on the training rows ({r['repeats']} x {r['folds']} folds): "
                     f"model {r['model_mae_avg']:.3f}, prior {r['prior_mae_avg']:.3f}")
    if "nested_cv_all" in result:
        r = result["nested_cv_all"]
        lines.append(f"nested CV over all {r['n_rows']} rows ({r['folds']} outer folds): "
                     f"model {r['model_mae_avg']:.3f}, prior {r['prior_mae_avg']:.3f}")
    return "\n".join(lines)
