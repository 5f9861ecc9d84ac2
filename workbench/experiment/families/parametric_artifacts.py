"""Family ``parametric``'s run figures: a learning curve and SHAP summaries of the correction.

A tracked run of the family gets what the eigenvalue family's runs get, for a model that
predicts every target at once:

* ``learning_curve``: the augmented learning curve of the fitted model with its choices kept
  (the chosen candidate and covariates, refitted at each size), the MAE averaged over the
  targets, against the incumbent, the user's model at its start values (the prior);
* ``shap_<target>`` and ``shap_correction_<target>``: SHAP values of the whole prediction and
  of the correction, the prediction less the prior (the user's model at its start values):
  what calibration, drift and stage learned, per input column.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin, clone

from ...curves import augmented_learning_curve
from ...parametric import resolve_model
from ..figures import correction_shap_figure, learning_curve_figure, shap_figure
from ..scoring.explain import target_shap_values
from ..splits.folds import curve_cv, largest_curve_size
from .artifacts import Artifacts
from .eigenvalue import curve_sizes

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import ExperimentConfig

__all__ = ["AllTargets", "StartModel", "run_artifacts"]


class StartModel(RegressorMixin, BaseEstimator):
    """The user's model at its start values (the prior), as a regressor: fitting is a no-op.

    Parameters
    ----------
    model : ParametricModel or str
        The model, or its file.
    n_targets : int, default=1
        The targets it predicts.
    """

    def __init__(self, model: Any = None, n_targets: int = 1) -> None:
        self.model = model
        self.n_targets = n_targets

    def fit(self, X: pd.DataFrame, y: Any = None) -> StartModel:
        """Do nothing (the start values are not fitted)."""
        self.fitted_ = True
        return self

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """Return the model at its start values, shape ``(rows, targets)``."""
        model = resolve_model(self.model)
        return model.predict(model.start(X), X, self.n_targets)


class AllTargets(RegressorMixin, BaseEstimator):
    """A model of every target, fitted on the rows ``y`` names (row positions in ``Y``).

    For one learning curve over all targets: ``y`` carries each row's position, the
    scorer (:func:`mean_mae_scorer`) compares the predictions with those rows of ``Y``.

    Parameters
    ----------
    estimator : estimator
        The multi-target model (cloned when fitted).
    Y : DataFrame or ndarray of shape (rows, targets)
        The targets of every row (a frame keeps the targets' names, which a model with
        per-target settings needs).
    """

    def __init__(self, estimator: Any = None, Y: Any = None) -> None:
        self.estimator = estimator
        self.Y = Y

    def fit(self, X: pd.DataFrame, y: Any) -> AllTargets:
        """Fit the estimator on ``X`` and the rows of ``Y`` that ``y`` names."""
        rows = np.asarray(y).astype(int)
        Y = self.Y.iloc[rows] if isinstance(self.Y, pd.DataFrame) else np.asarray(self.Y)[rows]
        self.estimator_ = clone(self.estimator).fit(X, Y)
        return self

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """Predict every target."""
        return np.asarray(self.estimator_.predict(X), dtype=float)


def mean_mae_scorer(Y: np.ndarray) -> Callable[[Any, pd.DataFrame, Any], float]:
    """Return a scorer: minus the MAE over all targets of the rows ``y`` names."""
    def score(estimator: Any, X: pd.DataFrame, y: Any) -> float:
        rows = np.asarray(y).astype(int)
        pred = np.asarray(estimator.predict(X), dtype=float).reshape(len(rows), -1)
        return -float(np.mean(np.abs(pred - Y[rows])))
    return score


class _TargetView:
    """One target of a fitted multi-target model, with the prior as ``predict_prior``."""

    def __init__(self, model: Any, prior: StartModel, j: int) -> None:
        self.model, self.prior, self.j = model, prior, j

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        return np.asarray(self.model.predict(X), dtype=float).reshape(len(X), -1)[:, self.j]

    def predict_prior(self, X: pd.DataFrame) -> np.ndarray:
        return self.prior.predict(X)[:, self.j]


def run_artifacts(cfg: ExperimentConfig, ds: Dataset, X: pd.DataFrame, model: Any,
                  fixed: Any, setting: str, quick: bool = False) -> Artifacts:
    """Compute the family's learning curve and SHAP summaries (see the module's docstring).

    Parameters
    ----------
    cfg : ExperimentConfig
        The run's config.
    ds : Dataset
        Its dataset.
    X : DataFrame
        The family's inputs of every row.
    model : estimator
        The fitted model.
    fixed : estimator
        The model with its choices kept, unfitted (``ModelFamily.fixed_choices``).
    setting : str
        What the figures' titles say the run was.
    quick : bool, default=False
        Two sizes instead of three (tests).

    Returns
    -------
    Artifacts
        The figures, and the curve as data (``learning_curves``).
    """
    log = logging.getLogger("workbench")
    X_train = X.loc[ds.train_index]
    Y_frame = ds.targets.loc[ds.train_index].astype(float)  # the targets' names: the stage's
    Y_train = Y_frame.to_numpy()                                # per-target settings need them
    targets = ds.target_names
    prior = StartModel(model.physics_.model, len(targets)).fit(X_train)
    cv = curve_cv(cfg, ds)
    sizes = curve_sizes(len(X_train), cfg.selection.cv, 2 if quick else 3,
                        largest=largest_curve_size(cv, X_train))
    log.info("[%s] figures: a learning curve at sizes %s and SHAP summaries of %d targets",
             cfg.name, sizes, len(targets))
    positions = np.arange(len(X_train), dtype=float)
    curve = augmented_learning_curve(AllTargets(fixed, Y_frame), X_train, positions,
                                     train_sizes=sizes, cv=cv, incumbent=prior,
                                     scoring=mean_mae_scorer(Y_train),
                                     random_state=cfg.random_state, n_jobs=cfg.jobs)
    curve = dataclasses.replace(curve, scoring="neg_mean_absolute_error")
    label = "all targets" if len(targets) > 1 else targets[0]
    out = Artifacts()
    out.figures["learning_curve"] = learning_curve_figure(
        curve, target=f"{label} (mean)" if len(targets) > 1 else label, unit=ds.unit,
        setting=setting)
    out.data["learning_curves"] = {label: curve.to_dict()}
    for j, target in enumerate(targets):
        explained = target_shap_values(_TargetView(model, prior, j), X_train,
                                       random_state=cfg.random_state or 0)
        whole = explained.prediction
        assert whole is not None  # asked for
        out.figures[f"shap_{target}"] = shap_figure(
            whole.values, whole.expected, whole.rows, target=target, unit=ds.unit,
            setting=setting, explained="prediction")
        out.figures[f"shap_correction_{target}"] = correction_shap_figure(
            explained.correction, target=target, unit=ds.unit, note=explained.note,
            setting=setting)
    return out
