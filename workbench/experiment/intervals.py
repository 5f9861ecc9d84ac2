"""Conformal prediction intervals in the experiment layer (``[intervals]``).

One place wraps every family's model: :func:`with_intervals` puts the model a family builds
inside a :class:`~workbench.conformal.ConformalRegressor` (when ``[intervals] enabled``, the
default), so the fitted model that ``evaluate`` and ``sweep`` keep, log to MLflow and return
has ``predict`` (unchanged point predictions), ``predict_interval`` and ``predict_frame``
(``<target>``, ``<target>_lower``, ``<target>_upper`` columns). A family's own methods
(scores, tables, figures) receive the family's fitted model, :func:`family_model`.

Coverage and width are scored on the test rows (once) and estimated by cross-validation on
the training rows from the conformal fit's own out-of-fold residuals
(:meth:`~workbench.conformal.ConformalRegressor.cv_coverage`: each fold's rows against the
conformal quantile of the other folds' residuals; no extra fit). The CV+ folds refit the
family's whole model, every choice (covariate selection, prior or boosted) remade inside each
fold, so the residuals are honest out-of-fold residuals; ``[evaluation]``'s repeated CV keeps
the choices made on all training rows fixed (cheaper, optimistic), which would make the
intervals too narrow, so it is not used for them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..conformal import ConformalRegressor, interval_coverage, interval_width
from .families.base import Artifacts
from .figures import interval_figure

if TYPE_CHECKING:
    from ..datasets import Dataset
    from .config import ExperimentConfig

__all__ = ["family_model", "interval_artifacts", "interval_scores", "interval_settings",
           "interval_table", "with_intervals"]


def with_intervals(cfg: ExperimentConfig, model):
    """``model`` (unfitted, built by the config's family) inside a ConformalRegressor as
    ``[intervals]`` describes; ``model`` itself when intervals are off."""
    iv = cfg.intervals
    if not iv.enabled:
        return model
    return ConformalRegressor(model, method=iv.method, alpha=iv.alpha, cv=iv.cv,
                              calibration_fraction=iv.calibration_fraction,
                              random_state=cfg.random_state or 0, n_jobs=cfg.jobs)


def family_model(model):
    """The family's fitted model (inside a fitted ConformalRegressor, its ``estimator_``)."""
    return model.estimator_ if isinstance(model, ConformalRegressor) else model


def interval_settings(cfg: ExperimentConfig) -> dict[str, Any]:
    """The JSON-ready ``intervals`` section of a result (empty when intervals are off)."""
    iv = cfg.intervals
    if not iv.enabled:
        return {}
    out: dict[str, Any] = {"method": iv.method, "alpha": iv.alpha, "level": 1 - iv.alpha}
    if iv.method in ("cv_plus", "cv"):
        out["cv"] = iv.cv
    elif iv.method == "split":
        out["calibration_fraction"] = iv.calibration_fraction
    return out


def interval_scores(model, X_test, y_test) -> dict[str, list[float]]:
    """Per-target coverage and mean width on the test rows and in CV (empty without
    intervals): keys ``test_coverage``, ``test_width``, ``cv_coverage``, ``cv_width``."""
    if not isinstance(model, ConformalRegressor):
        return {}
    iv = model.predict_interval(X_test)
    cv_coverage, cv_width = model.cv_coverage()
    return {"test_coverage": interval_coverage(y_test, iv), "test_width": interval_width(iv),
            "cv_coverage": cv_coverage, "cv_width": cv_width}


def interval_table(model, ds: Dataset, X: pd.DataFrame) -> pd.DataFrame:
    """The test rows' measured values, predictions and intervals, one row per experiment
    and target (columns ``experiment``, ``target``, ``measured``, ``predicted``, ``lower``,
    ``upper``, ``covered``)."""
    X_test = X.loc[ds.test_index]
    pred = np.asarray(model.predict(X_test), dtype=float).reshape(len(X_test), -1)
    iv = model.predict_interval(X_test)
    y = ds.targets.loc[ds.test_index].to_numpy(dtype=float)
    parts = []
    for j, target in enumerate(model.target_names_):
        parts.append(pd.DataFrame({
            "experiment": X_test.index, "target": target, "measured": y[:, j],
            "predicted": pred[:, j], "lower": iv[:, j, 0], "upper": iv[:, j, 1],
            "covered": (y[:, j] >= iv[:, j, 0]) & (y[:, j] <= iv[:, j, 1])}))
    return pd.concat(parts, ignore_index=True)


def interval_artifacts(cfg: ExperimentConfig, ds: Dataset, model,
                       setting: str | None = None) -> Artifacts:
    """The intervals' figure (measured against predicted with the interval of every test
    row, a panel per target) and table (:func:`interval_table`); nothing without
    intervals."""
    if not isinstance(model, ConformalRegressor):
        return Artifacts()
    table = interval_table(model, ds, cfg.family.inputs(cfg, ds))
    fig = interval_figure(table, level=1 - model.alpha, unit=ds.unit,
                          title=f"{1 - model.alpha:.0%} conformal intervals "
                                f"({model.method}), test rows", setting=setting)
    return Artifacts(figures={"intervals": fig}, tables={"test_intervals": table})
