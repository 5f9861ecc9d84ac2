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

from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ...conformal import ConformalRegressor, interval_coverage, interval_width
from ..families.artifacts import Artifacts
from ..figures import interval_figure

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import ExperimentConfig

__all__ = ["family_model", "interval_artifacts", "interval_scores", "interval_settings",
           "interval_table", "with_intervals"]


def with_intervals(cfg: ExperimentConfig, model: Any) -> Any:
    """Wrap a family's model in a ConformalRegressor as ``[intervals]`` describes.

    Parameters
    ----------
    cfg : ExperimentConfig
        The loaded config (its ``intervals`` method is resolved).
    model : estimator
        The unfitted model the config's family built.

    Returns
    -------
    estimator
        A :class:`~workbench.conformal.ConformalRegressor` around ``model``, or ``model``
        itself when intervals are off.
    """
    iv = cfg.intervals
    if not iv.enabled:
        return model
    return ConformalRegressor(model, method=cast(str, iv.method), alpha=iv.alpha, cv=iv.cv,
                              calibration_fraction=iv.calibration_fraction,
                              random_state=cfg.random_state or 0, n_jobs=cfg.jobs)


def family_model(model: Any) -> Any:
    """Return the family's fitted model, unwrapped from a fitted ConformalRegressor.

    Parameters
    ----------
    model : estimator
        A fitted model, conformal or not.

    Returns
    -------
    estimator
        Its ``estimator_`` inside a ConformalRegressor, else ``model``.
    """
    return model.estimator_ if isinstance(model, ConformalRegressor) else model


def interval_settings(cfg: ExperimentConfig) -> dict[str, Any]:
    """Describe a config's intervals as a result's JSON-ready ``intervals`` section.

    Parameters
    ----------
    cfg : ExperimentConfig
        The loaded config.

    Returns
    -------
    dict
        Method, alpha, level and the method's own setting; empty when intervals are off.
    """
    iv = cfg.intervals
    if not iv.enabled:
        return {}
    out: dict[str, Any] = {"method": iv.method, "alpha": iv.alpha, "level": 1 - iv.alpha}
    if iv.method in ("cv_plus", "cv"):
        out["cv"] = iv.cv
    elif iv.method == "split":
        out["calibration_fraction"] = iv.calibration_fraction
    return out


def interval_scores(model: Any, X_test: pd.DataFrame,
                    y_test: ArrayLike) -> dict[str, list[float]]:
    """Score a fitted conformal model's intervals on the test rows and in CV.

    Parameters
    ----------
    model : estimator
        A fitted model; only a ConformalRegressor has intervals.
    X_test : DataFrame
        The test rows' inputs.
    y_test : array-like of shape (n_test, n_targets)
        Their targets.

    Returns
    -------
    dict
        Per target ``test_coverage``, ``test_width``, ``cv_coverage`` and ``cv_width``; empty
        without intervals.
    """
    if not isinstance(model, ConformalRegressor):
        return {}
    iv = model.predict_interval(X_test)
    cv_coverage, cv_width = model.cv_coverage()
    return {"test_coverage": interval_coverage(y_test, iv), "test_width": interval_width(iv),
            "cv_coverage": cv_coverage, "cv_width": cv_width}


def interval_table(model: Any, ds: Dataset, X: pd.DataFrame) -> pd.DataFrame:
    """Tabulate the test rows' measured values, predictions and intervals.

    Parameters
    ----------
    model : ConformalRegressor
        The fitted model.
    ds : Dataset
        The dataset (its test rows and targets).
    X : DataFrame
        The model's inputs for every row of ``ds``.

    Returns
    -------
    DataFrame
        One row per experiment and target: ``experiment``, ``target``, ``measured``,
        ``predicted``, ``lower``, ``upper``, ``covered``.
    """
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


def interval_artifacts(cfg: ExperimentConfig, ds: Dataset, model: Any,
                       setting: str | None = None) -> Artifacts:
    """Make the intervals' figure and table.

    The figure shows measured against predicted values with the interval of every test row,
    a panel per target; the table is :func:`interval_table`.

    Parameters
    ----------
    cfg : ExperimentConfig
        The loaded config (its family gives the inputs).
    ds : Dataset
        The dataset.
    model : estimator
        The fitted model.
    setting : str, default=None
        A line naming the setting, shown on the figure.

    Returns
    -------
    Artifacts
        ``intervals`` figure and ``test_intervals`` table; empty without intervals.
    """
    if not isinstance(model, ConformalRegressor):
        return Artifacts()
    table = interval_table(model, ds, cfg.family.inputs(cfg, ds))
    fig = interval_figure(table, level=1 - model.alpha, unit=ds.unit,
                          title=f"{1 - model.alpha:.0%} conformal intervals "
                                f"({model.method}), test rows", setting=setting)
    return Artifacts(figures={"intervals": fig}, tables={"test_intervals": table})
