"""Family ``parametric``: a user's physics model, corrected in its own parameter space.

The user hands over the model itself, a Python file (:mod:`workbench.parametric`'s
contract: ``PARAMETERS``, ``predict(params, data)``, optionally ``jacobian``), named by
``[model.parametric] model`` relative to the config file. The physics model
(:class:`~workbench.parametric_boost.ParametricBoostRegressor`) chooses by CV on the
training rows among the prior (the model at its start values), the calibrated model (robust
global calibration of the parameters, no drift) and linear drifts of the parameters in
covariates chosen by forward selection; an eigenvalue-space (output-space) boosting stage on
top (``[model]`` keys, one BaseBoostCV per target, trained on out-of-fold priors) is kept per
target only where CV says it helps (:class:`~workbench.fitted_prior.FittedPriorBoost`).

Tables: ``choices`` (each candidate's CV MAE and the winner), ``calibration`` (each
parameter's start and calibrated offset), ``coefficients`` (the corrections'),
``corrected_parameters`` (per experiment) and ``selection_path``; figures: the corrected
parameters against their start values and against the covariates they drift with, and the
selection path; a tracked run adds a learning curve and SHAP summaries of the correction
(:mod:`.parametric_artifacts`).

Progress: where the ``workbench`` logger shows INFO lines (a command's), a fit the family
builds reports a line per phase, CV fold and selection step (the estimators' ``verbose``,
:mod:`workbench._progress`), e.g. ``parametric: calibrated model: CV fold 2/5 (3 s)``,
``parametric: selection step 1: tau <- temp  cv_mae=0.0123 (4 s)``, ``stage: out-of-fold
priors: 5 refits of the physics model, its choices kept``. A sweep's trials report none (its
progress is a line per trial); refits with the choices kept (repeated CV, learning curves,
intervals) neither.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal, cast

import numpy as np
import pandas as pd
from pydantic import Field, field_validator
from sklearn.base import clone
from sklearn.model_selection import KFold

from ...design import DesignProblem, drift_problem
from ...fitted_prior import FittedPriorBoost
from ...param_regressor import ParametricRegressor
from ...parametric import ModelError, load_model
from ...parametric_boost import RIDGE_ALPHAS, ParametricBoostRegressor
from ...parametric_gbm import ParameterSpaceBoostRegressor, make_regressor
from ..config.schema import Section
from ..config.toml_text import toml_string
from ..process.errors import ConfigError
from ..scoring.scores import ModelScores, Scores, mae, mse
from ..splits.folds import describe_folds, family_cv
from .artifacts import Artifacts
from .base import ModelFamily, showing_progress
from .hamiltonian_figures import parameter_corrections, selection_path_figure
from .parametric_artifacts import run_artifacts
from .parametric_figures import drift_axes, parameter_drift_figure
from .stage import per_target_boost, stage_scores

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import ExperimentConfig

__all__ = ["ParametricFamily", "ParametricSettings", "make_parametric"]

#: Prefix of the columns holding the physics model's prediction (the stage's prior).
PRIOR_PREFIX = "prior_"

class ParameterBoostSettings(Section):
    """``[model.parametric.boost]``: boosting in the model's parameter space, a candidate.

    ``regressor``: the regressor fitted per parameter and round to the parameter-space
    pseudo-residuals, ``"tree"`` (a decision tree, default ``max_depth = 3``) or a basis name
    (``"lightgbm"``, ``"ridge"``, ...), with ``params``; ``rounds`` the most rounds (CV on
    the choice's folds picks how many), ``learning_rate`` the shrinkage, ``step``
    ``"newton"`` (curvature-weighted) or ``"gradient"``, ``update`` ``"joint"`` (every
    parameter each round) or ``"greedy"`` (the best one), ``subsample`` the rows each round
    sees, ``parameters`` the parameters boosted (empty: all), ``start`` ``"calibrated"`` or
    ``"drift"`` (the linear drift, where there is one: with ``drift = "both"`` the one,
    forward or ridge, that CV scored best).
    """

    regressor: str = "tree"
    params: dict[str, Any] = Field(default_factory=dict)
    rounds: int = Field(default=200, ge=1, le=100_000)
    learning_rate: float = Field(default=0.1, gt=0, le=1)
    step: Literal["newton", "gradient"] = "newton"
    update: Literal["joint", "greedy"] = "joint"
    subsample: float = Field(default=1.0, gt=0, le=1)
    parameters: list[str] = Field(default_factory=list)
    start: Literal["calibrated", "drift"] = "calibrated"

    @field_validator("regressor")
    @classmethod
    def _known(cls, value: str) -> str:
        make_regressor(value)  # an unknown name: the error lists the valid ones
        return value


class ParametricSettings(Section):
    """``[model.parametric]``: the user's model and how its parameters are corrected.

    ``model``: the model file, relative to the config file. ``start``: covariates every drift
    model has, per parameter; ``candidates``: the forward selection's pool, per parameter,
    or ``"auto"`` (the dataset's features, their squares and pairwise products, for every
    parameter) or ``"none"`` (no drift candidate); ``drift``: how the drift candidates are
    made from that pool, ``"forward"`` (forward selection), ``"ridge"`` (every covariate of
    the pool at once, the ridge penalty chosen by CV from ``ridge_alphas``: the
    ``ridge_drift`` candidate) or ``"both"`` (the two, CV choosing). ``loss``,
    ``huber_delta``, ``alpha``, ``alpha_l1``, ``max_iter``: the Gauss-Newton fit's (and the
    calibration's loss); ``selection_cv``, ``selection_repeats``, ``max_steps``,
    ``min_improvement``: the CV that chooses among prior, calibrated model and drifts, and
    the selection's (``min_improvement`` in the targets' unit, at most 1% of the prior's
    training MAE); ``prior_cv``
    the folds of the out-of-fold priors the stage on top trains on. Both follow the data
    as BaseBoostCV's folds do (:func:`~..splits.folds.family_cv`): forward-chaining by
    ``[data] order_column``, whole groups with ``[selection] groups``, else shuffled
    K-fold; ``selection_repeats`` repeats shuffled K-fold only (above 1 with an order or
    groups: a ConfigError).
    ``out_of_bounds``: what a new row outside the box the training rows span gets:
    ``"calibrated"``, the calibrated model's parameters (no drift, no parameter-space
    boosting there); ``"clip"``, its covariates clipped to their training range (the drift's
    corrections at the nearest training point); the default ``"extrapolate"``, the drift's
    squares and products grown beyond them.
    ``stage_priors``: which priors the stage on top is fitted on, keeping per target the
    one on which it scores the lowest CV MAE (``FittedPriorBoost``'s ``alternative``): the
    choice above scores the physics models without the stage. ``"chosen"`` (default), the
    chosen model's only; ``"calibrated"``, also the calibrated model's (the generic path);
    ``"candidates"``, every candidate's the choice scored (calibrated, drifts, the
    parameter-space boost; the prior only where chosen). ``stage_mean = true`` (with
    ``stage_priors`` other than ``"chosen"``) also scores the mean of those stages, each on
    its own prior, by the MAE of the mean of their CV predictions, and keeps it per target
    where that is lowest: the physics path mixed with the generic one, for new rows like
    the training rows (random folds choose it, and they do not see extrapolation).
    ``selection``: how the forward selection scores a candidate, ``"forward"`` (default:
    a refit on every fold) or ``"linearised"`` (one Gauss-Newton step from the current fit,
    only the best-scored candidates refitted: for large pools and costly models, as the
    Hamiltonian family's ``selection = "linearised"``).
    ``fallback = true``: per target, the model at its start values (the control
    prediction) where the chosen physics model's out-of-fold MAE is not below its own, as the
    Hamiltonian family's ``fallback`` (with ``stage_priors = "chosen"`` only: the other
    settings choose per target among priors already).
    ``boost``: the table :class:`ParameterBoostSettings`, parameter-space boosting as a
    fourth candidate (absent: none). ``calibrate = false`` starts every fit's offsets at 0
    instead of a robust least-squares calibration, and ``solver = "irls"`` keeps IRLS
    weights where the default ``"newton"`` takes Newton steps near the optimum: together they
    are the Hamiltonian family's Gauss-Newton fit (``experiments/parametric_device.toml``).
    """

    model: str
    loss: Literal["squared_error", "absolute_error", "huber"] = "huber"
    huber_delta: float = Field(default=1.0, gt=0)
    alpha: float = Field(default=1.0, ge=0)
    alpha_l1: float = Field(default=0.0, ge=0)
    max_iter: int = Field(default=20, ge=0, le=100_000)
    out_of_bounds: Literal["extrapolate", "clip", "calibrated"] = "extrapolate"
    calibrate: bool = True
    solver: Literal["newton", "irls"] = "newton"
    start: dict[str, list[str]] = Field(default_factory=dict)
    candidates: Literal["auto", "none"] | dict[str, list[str]] = "auto"
    squares: bool = True
    products: bool = True
    selection_cv: int = Field(default=5, ge=2, le=10_000)
    selection_repeats: int = Field(default=1, ge=1, le=1000)
    max_steps: int = Field(default=20, ge=0, le=100_000)
    min_improvement: float = Field(default=1e-3, ge=0)
    drift: Literal["forward", "ridge", "both"] = "forward"
    selection: Literal["forward", "linearised"] = "forward"
    ridge_alphas: list[float] = Field(default_factory=lambda: list(RIDGE_ALPHAS), min_length=1)
    boost_stage: bool = True
    fallback: bool = False
    stage_priors: Literal["chosen", "calibrated", "candidates"] = "chosen"
    stage_mean: bool = False
    prior_cv: int = Field(default=5, ge=2, le=10_000)
    boost: ParameterBoostSettings | None = None

    renamed: ClassVar[dict[str, str]] = {"calibrated_stage": 'stage_priors = "calibrated"'}

    @field_validator("ridge_alphas")
    @classmethod
    def _penalties(cls, value: list[float]) -> list[float]:
        if any(not math.isfinite(a) or a < 0 for a in value):
            raise ValueError("every ridge penalty must be finite and >= 0")
        return value


def model_path(cfg: ExperimentConfig, settings: ParametricSettings) -> Path:
    """Return the model file, relative to the config file (or the working folder)."""
    base = cfg.path.parent if cfg.path is not None else Path.cwd()
    return (base / settings.model).resolve()


def make_parametric(cfg: ExperimentConfig, ds: Dataset) -> ParametricBoostRegressor:
    """Make the physics model that ``[model.parametric]`` describes (unfitted).

    Raises
    ------
    ConfigError
        For a model file that cannot be used (one line naming the problem).
    """
    s = cast(ParametricSettings, cfg.family_settings)
    path = model_path(cfg, s)
    try:
        model = load_model(path)  # pickled with its source code: the fitted model needs no file
    except ModelError as exc:
        raise ConfigError(f"[model.parametric] model: {exc}") from None
    candidates: Any = (None if s.candidates == "none" else s.candidates)
    return ParametricBoostRegressor(
        model=model, start=s.start or None, candidates=candidates, features=ds.feature_names,
        squares=s.squares, products=s.products, cv=choice_cv(cfg, ds),
        n_repeats=s.selection_repeats, max_steps=s.max_steps,
        method="linearised" if s.selection == "linearised" else "refit",
        min_improvement=float(s.min_improvement), drift=s.drift,
        ridge_alphas=[float(a) for a in s.ridge_alphas], alpha=float(s.alpha),
        alpha_l1=float(s.alpha_l1), loss=s.loss, huber_delta=float(s.huber_delta),
        max_iter=s.max_iter, out_of_bounds=s.out_of_bounds, calibrate=s.calibrate,
        solver=s.solver, random_state=cfg.random_state,
        n_jobs=cfg.n_jobs, verbose=showing_progress(),
        boost=_booster(s.boost, ds.feature_names))


def choice_cv(cfg: ExperimentConfig, ds: Dataset) -> Any:
    """Return the physics model's ``cv``: the folds of its selection and choice.

    :func:`~..splits.folds.family_cv`'s folds where they follow the data (its order or
    groups); else ``selection_cv`` as an int, the estimator's own repeated shuffled K-fold
    (``selection_repeats``; one repeat is the shuffled ``KFold`` ``family_cv`` makes).

    Raises
    ------
    ConfigError
        For ``selection_repeats`` above 1 where the folds follow the data (made once).
    """
    s = cast(ParametricSettings, cfg.family_settings)
    folds = family_cv(cfg, ds, s.selection_cv)
    if isinstance(folds, KFold):
        return s.selection_cv
    if s.selection_repeats > 1:
        raise ConfigError(f"[model.parametric] selection_repeats = {s.selection_repeats} "
                          f"repeats shuffled folds, but the folds follow the data "
                          f"({describe_folds(folds)}) and are made once: set "
                          f"selection_repeats = 1")
    return folds


def _booster(b: ParameterBoostSettings | None,
             features: list[str]) -> ParameterSpaceBoostRegressor | None:
    """Make the ``boost`` candidate's template (the choice sets its model, loss and seed)."""
    if b is None:
        return None
    return ParameterSpaceBoostRegressor(
        estimator=make_regressor(b.regressor, b.params), n_estimators=b.rounds,
        learning_rate=float(b.learning_rate), step=b.step, update=b.update,
        subsample=float(b.subsample), parameters=list(b.parameters) or None,
        init="drift" if b.start == "drift" else None, features=list(features))


def config_section(entry: str, path: str | os.PathLike[str]) -> str:
    """Return a first ``[model.parametric]`` table for ``workbench init --model``.

    Parameters
    ----------
    entry : str
        The model file as the config names it (relative to the config).
    path : str or path-like
        The model file, checked here.

    Raises
    ------
    ConfigError
        For a model file that cannot be used (one line naming the problem).
    """
    try:
        load_model(path)
    except ModelError as exc:
        raise ConfigError(str(exc)) from None
    return "\n".join([
        "", "[model.parametric]",
        f"model = {toml_string(entry)}   # PARAMETERS, predict(params, data), optionally jacobian",
        'loss = "squared_error"       # or "huber", huber_delta in the targets\' unit',
        'candidates = "auto"          # each parameter\'s drift: features, squares, products',
        "max_steps = 10",
        'stage_priors = "candidates"  # the stage on every candidate; its CV keeps the best',
        "stage_mean = false           # true: also their mean (random splits: up to 7% better;",
        "                             # beyond the training rows: up to 2x worse)",
        ""])


def _frame(ds: Dataset) -> pd.DataFrame:
    return ds.X_physics if ds.hamiltonian is not None else ds.X


def _computed_prior(cfg: ExperimentConfig) -> bool:
    """Tell whether the prior is the model's own (a CSV that names no prior columns)."""
    return cfg.data.source == "csv" and cfg.data.prior is None


def _test_row_notes(regressor: Any, X_test: pd.DataFrame, info: dict[str, Any],
                    mean_targets: int = 0) -> list[str]:
    """Count the test rows outside the training rows' covariate box and those whose
    corrected parameters leave the model's domain (into ``info``); a line for each kind
    that occurs, and one where rows lie outside the box and ``mean_targets`` targets keep
    the mean of the stages. Only the rows' features are used, never their targets."""
    n, notes = len(X_test), []
    beyond = int(regressor.outside(X_test).sum())
    info["outside_box_test_rows"] = beyond
    if beyond:
        there = ("they get the calibrated model's parameters (out_of_bounds = \"calibrated\")"
                 if regressor.out_of_bounds == "calibrated" else
                 "the drift is clipped to the box there" if regressor.out_of_bounds == "clip"
                 else "the drift extrapolates there; [model.parametric] out_of_bounds = "
                 "\"calibrated\" would keep the calibrated model")
        notes.append(f"{beyond} of {n} test rows lie outside the box the training rows' "
                     f"covariates span: {there}")
        if mean_targets:
            notes.append(f"{mean_targets} target(s) keep the mean of the stages, chosen on "
                         "folds of the training rows; beyond them it has extrapolated worse "
                         "than a single stage on some fields: [model.parametric] stage_mean "
                         "= false keeps a single stage")
    outside = int(regressor.outside_domain(X_test).sum())
    info["outside_domain_test_rows"] = outside
    if outside:
        notes.append(f"{outside} of {n} test rows: the corrected parameters leave the model's "
                     "domain (its prediction is not finite there); they get the calibrated "
                     "model's prediction")
    return notes


def _used_regressor(model: Any) -> Any:
    """The parametric regressor whose prediction the stage's priors use: the chosen
    physics model's where any target keeps it (alone or in the stages' mean), else the one
    alternative every target has (None where they mix alternatives)."""
    chosen = set(getattr(model, "prior_choice_", ["physics"]))
    if chosen & {"physics", "mean"}:
        return model.physics_.estimator_
    return model.alternatives_[chosen.pop()] if len(chosen) == 1 else None


def _records(table: pd.DataFrame) -> list[dict[str, Any]]:
    return table.astype(object).where(table.notna(), None).to_dict(orient="records")


class ParametricFamily(ModelFamily):
    """A user's model: calibrated, its parameters' drifts chosen by CV, boosted on top."""

    name = "parametric"
    settings: ClassVar = ParametricSettings
    interval_method = "oof"
    computes_prior = True

    def complete_data(self, cfg: ExperimentConfig, ds: Dataset) -> Dataset:
        """Fill in the prior of a dataset without prior columns.

        The prior is the model at its start values, columns ``model_<target>``.
        """
        if len(ds.prior.columns):
            return ds
        s = cast(ParametricSettings, cfg.family_settings)
        try:
            model = load_model(model_path(cfg, s))
            X = _frame(ds)
            value = model.predict(model.start(X), X, len(ds.target_names))
        except ModelError as exc:
            raise ConfigError(f"[model.parametric] model: {exc}") from None
        prior = pd.DataFrame(value, index=ds.targets.index,
                             columns=[f"model_{t}" for t in ds.target_names])
        return dataclasses.replace(ds, prior=prior)

    def inputs(self, cfg: ExperimentConfig, ds: Dataset) -> pd.DataFrame:
        """Return the dataset's features and prior, and its Hamiltonian columns if any.

        A model file may read any of them. A prior the family computed (a CSV without
        prior columns, :meth:`complete_data`) is left out: the model makes it from the
        features, so new rows (``workbench predict``, serving) need only those.
        """
        X = _frame(ds)
        if _computed_prior(cfg):
            X = X.drop(columns=ds.prior_names)
        return X

    def build(self, cfg: ExperimentConfig, ds: Dataset) -> FittedPriorBoost:
        """Build a :class:`FittedPriorBoost` over :func:`make_parametric`.

        Both report their progress (``verbose``) where the ``workbench`` logger shows INFO
        lines, except in a sweep's trials (:func:`~.base.showing_progress`).
        """
        s = cast(ParametricSettings, cfg.family_settings)
        priors = [f"{PRIOR_PREFIX}{t}" for t in ds.target_names]
        boost = per_target_boost(cfg, ds, priors, boost_from_prior=False)
        physics = make_parametric(cfg, ds)
        alternative = (None if not s.boost_stage or s.stage_priors == "chosen" else
                       {"calibrated": physics.calibrated_model()}
                       if s.stage_priors == "calibrated" else "candidates")
        fallback = None
        if s.fallback:
            if alternative is not None:
                raise ConfigError(f'[model.parametric] fallback = true needs stage_priors = '
                                  f'"chosen" (stage_priors = "{s.stage_priors}" chooses per '
                                  "target among the candidates' priors already)")
            # the control prediction: the user's model at its start values
            fallback = ParametricRegressor(model=physics.model, max_iter=0, calibrate=False)
        return FittedPriorBoost(physics, boost, prior_prefix=PRIOR_PREFIX,
                                alternative=alternative, fallback=fallback,
                                stage_mean=s.stage_mean and alternative is not None,
                                cv=family_cv(cfg, ds, s.prior_cv),
                                boost_stage=s.boost_stage,
                                cv_predictions=cfg.intervals.enabled
                                and cfg.intervals.method == "oof", n_jobs=cfg.jobs,
                                verbose=showing_progress())

    def folds_used(self, cfg: ExperimentConfig, ds: Dataset) -> str:
        """Say which folds made the choices: the stage's, the physics model's and its priors'.

        E.g. ``"stage 5 contiguous; parametric choice 5 shuffled; out-of-fold priors 5
        shuffled"``, or ``"5 forward-chaining by `date`"`` for all three alike; without a
        stage (``boost_stage = false``) the choice's, and the priors' where out-of-fold
        intervals need them.
        """
        s = cast(ParametricSettings, cfg.family_settings)
        cv = choice_cv(cfg, ds)
        choice = (describe_folds(cv) if not isinstance(cv, int) else
                  f"{cv} shuffled" + (f" x {s.selection_repeats} repeats"
                                      if s.selection_repeats > 1 else ""))
        parts = {"parametric choice": choice}
        if s.boost_stage:
            parts = {"stage": super().folds_used(cfg, ds), **parts}
        if s.boost_stage or (cfg.intervals.enabled and cfg.intervals.method == "oof"):
            parts["out-of-fold priors"] = describe_folds(family_cv(cfg, ds, s.prior_cv))
        if len(set(parts.values())) == 1:
            return choice
        return "; ".join(f"{k} {v}" for k, v in parts.items())

    def fixed_choices(self, model: Any) -> Any:
        """Keep the physics model's choice (and selected covariates), and the stage's priors
        where ``stage_priors`` chose among several (the one prior where every target has
        it); no progress lines."""
        fixed = clone(model).set_params(physics=clone(model.physics_.estimator_),
                                        alternative=None, verbose=False)
        chosen = list(dict.fromkeys(getattr(model, "prior_choice_", ["physics"])))
        if chosen == ["physics"] or not model.boost_stage:
            return fixed
        if len(chosen) == 1 and chosen != ["mean"]:
            return fixed.set_params(physics=clone(model.alternatives_[chosen[0]]))
        used = dict.fromkeys([*getattr(model, "stages_", {}), *chosen])
        return fixed.set_params(alternative={name: clone(model.alternatives_[name])
                                             for name in used
                                             if name not in ("physics", "mean")})

    def selected(self, model: Any, targets: list[str]) -> list[str]:
        """Label per target ``"parametric:<prior|calibrated|drift|ridge_drift|boost>"``.

        ``" (error not a drift)"`` follows the prior or the calibrated model: CV found no
        drift of the parameters that helps.

        ``"parametric:control ..."`` where ``fallback`` kept the model at its start values.
        ``"+boosted"`` is added where the stage was kept. With ``stage_priors``, a target
        on another candidate's prior says ``"<candidate> (the stage did better on it)"``,
        one on the stages' mean (``stage_mean``) ``"mean of the stages on drift,
        calibrated"``.
        """
        physics = getattr(model.physics_, "choice_", "fixed")
        if physics in ("prior", "calibrated"):  # the table says the drift did not help
            physics += " (error not a drift)"
        stages = model.boost_.estimators_ if model.boost_stage else [None] * len(targets)
        chose = getattr(model, "prior_choice_", ["physics"] * len(targets))
        mixed = ", ".join(physics.split(" (")[0] if k == "physics" else k
                          for k in getattr(model, "stages_", {}))
        names = {"physics": physics, "mean": f"mean of the stages on {mixed}"}
        kept = getattr(model, "physics_selected_", [True] * len(targets))
        return [(f"parametric:{names.get(c) or f'{c} (the stage did better on it)'}"
                 if k else "parametric:control (the model at its start values: fallback)")
                + (f"+{(c != 'mean' and getattr(e, 'selected_candidate_', None)) or 'boosted'}"
                   if s == "boosted" else "")
                for s, e, c, k in zip(model.selected_, stages, chose, kept)]

    def scores(self, ds: Dataset, model: Any, Y_train: pd.DataFrame, prior_test: Any,
               y_test: Any, pred: Any) -> tuple[Scores, ModelScores, dict[str, Any]]:
        """Score prior and model, with the physics model's choice and corrections."""
        prior_train = ds.prior.loc[Y_train.index].to_numpy()
        nan = [float("nan")] * len(ds.target_names)
        Y = Y_train.to_numpy(dtype=float)
        staged = model.boost_stage
        s: dict[str, list[Any]] = stage_scores(model.boost_.estimators_, Y) if staged else {}
        mean = [j for j, p in enumerate(getattr(model, "prior_choice_", [])) if p == "mean"]
        if mean:  # the stages' mean: its CV figures, no single stage's
            cv = model.cv_predictions_  # the mean over the stages, computed once
            for j in mean:
                s["cv_mae"][j] = float(model.stage_cv_mae_.iloc[j]["mean"])
                s["cv_mse"][j] = float(np.mean((Y[:, j] - cv[:, j]) ** 2))
                s["coefs"][j] = []
        prior = Scores(test_mae=mae(y_test, prior_test), test_mse=mse(y_test, prior_test),
                       cv_mae=mae(Y_train, prior_train), cv_mse=mse(Y_train, prior_train))
        stage_cv = s["prior_cv_mae"] if staged else nan
        scores = ModelScores(test_mae=mae(y_test, pred), test_mse=mse(y_test, pred),
                             cv_mae=s["cv_mae"] if staged else stage_cv,
                             cv_mse=s["cv_mse"] if staged else nan,
                             selected=self.selected(model, ds.target_names),
                             coefs=s["coefs"] if staged else [[] for _ in nan],
                             extra={"cv_mae_parametric": stage_cv})
        physics = model.physics_
        regressor = physics.estimator_
        info: dict[str, Any] = {
            "choice": physics.choice_, "note": physics.note_,
            "choices": _records(physics.choices_),
            "calibration": _records(regressor.calibration_),
            "coefficients": _records(regressor.coefficient_table()),
            "n_iter": regressor.n_iter_}
        if physics.selection_ is not None:
            sel = physics.selection_
            info["selection"] = {"cv_mae": sel.cv_mae, "steps": len(sel.path) - 1,
                                 "path": _records(sel.path), "seconds": sel.seconds}
        if getattr(physics, "ridge_path_", None) is not None:
            info["ridge_path"] = _records(physics.ridge_path_)
        if getattr(model, "stage_cv_mae_", None) is not None:
            table = model.stage_cv_mae_.rename_axis("target").reset_index()
            info["stage_cv_mae"] = _records(table.assign(stage_prior=model.prior_choice_))
        details: dict[str, Any] = {"parametric": info}
        used = _used_regressor(model)
        if hasattr(used, "outside") and hasattr(used, "outside_domain"):
            details["notes"] = _test_row_notes(used, _frame(ds).loc[ds.test_index], info,
                                               len(mean))
        return prior, scores, details

    def design_problem(self, model: Any, X: pd.DataFrame, Y: pd.DataFrame,
                       candidates: pd.DataFrame, random_state: int | None = None
                       ) -> DesignProblem:
        """Give the Fisher information of the drift's coefficients, as the Hamiltonian
        family does.

        Gauss-Newton: the model's Jacobian times the covariates
        (:meth:`~workbench.param_regressor.ParametricRegressor.coef_jacobian`), plus the ridge
        penalty as the coefficients' prior; one noise sd for every target, the robust sd of
        the model's training residuals. The coefficients are those of every covariate the
        selection could choose (the optional parameters' among them), not only the chosen
        ones (at the fitted model, the others at 0: DuMouchel and Jones's "potential
        terms"). The stage on top is not part of it. Where the physics model the priors use
        is no drift regressor (the parameter-space boost, or targets mixing alternatives):
        the default, the spread of fold models.
        """
        regressor = _used_regressor(model)
        if not isinstance(regressor, ParametricRegressor):
            return super().design_problem(model, X, Y, candidates, random_state)
        return drift_problem(regressor, model.physics_.candidate_pool(X), X, Y, candidates,
                             "the model's parameters the selection could use")

    def begin_artifacts(self, cfg: ExperimentConfig, ds: Dataset, model: Any, setting: str,
                        quick: bool = False) -> Callable[..., Artifacts]:
        """Draw a tracked run's learning curve and SHAP summaries of the correction.

        :func:`~.parametric_artifacts.run_artifacts`: one augmented learning curve over all
        targets (the model with its choices kept, against the user's model at its start
        values), and per target the SHAP summaries of the whole prediction and of the
        correction (prediction less that prior). Computed when ``finish`` is called.
        """
        def finish(emit: Callable[[str, Any], None] | None = None) -> Artifacts:
            out = run_artifacts(cfg, ds, self.inputs(cfg, ds), model,
                                self.fixed_choices(model), setting, quick=quick)
            for name, fig in out.figures.items():
                if emit is not None:
                    emit(name, fig)
            return out

        return finish

    def run_metrics(self, details: dict[str, Any]) -> dict[str, float]:
        """Log the calibration and the choice as metrics, to compare runs by them.

        ``parametric/calibrated/<p>`` (start plus offset; a parameter that starts from a
        column has its ``parametric/offset/<p>`` only) and ``parametric/cv_mae/<candidate>``
        (prior, calibrated, drift: the CV MAE the choice was made on); with
        ``stage_priors``, ``parametric/stage_cv_mae/<prior>/<target>`` (the stage's CV
        MAE on the chosen model's prior, ``physics``, and on each other candidate's).
        """
        info = details.get("parametric") or {}
        out: dict[str, float] = {}
        for row in info.get("calibration", []):
            p, offset, start = row["parameter"], row["offset"], row.get("start")
            out[f"parametric/offset/{p}"] = float(offset)
            if isinstance(start, (int, float)):
                out[f"parametric/calibrated/{p}"] = float(start) + float(offset)
        for row in info.get("choices", []):
            if row.get("cv_mae") is not None:
                out[f"parametric/cv_mae/{row['candidate']}"] = float(row["cv_mae"])
        for row in info.get("stage_cv_mae", []):
            for side, value in row.items():
                if side not in ("target", "stage_prior"):
                    out[f"parametric/stage_cv_mae/{side}/{row['target']}"] = float(value)
        return out

    def outputs(self, model: Any, ds: Dataset, setting: str | None = None) -> Artifacts:
        """Make the choice, calibration, coefficient, corrected-parameter and path tables."""
        physics = model.physics_
        regressor = physics.estimator_
        X = _frame(ds)
        start = regressor.start_parameters(X)
        corrected = regressor.corrected_parameters(X)
        split = pd.Series("test", index=X.index, name="split")
        split.loc[ds.train_index] = "train"
        columns = {"experiment": pd.Series(X.index, index=X.index), "split": split}
        for p in regressor.parameter_names_:
            columns[f"{p}_start"] = start[p]
            columns[f"{p}_corrected"] = corrected[p]
            columns[f"{p}_correction"] = corrected[p] - start[p]
        out = Artifacts(tables={"choices": physics.choices_,
                                "calibration": regressor.calibration_,
                                "coefficients": regressor.coefficient_table(),
                                "corrected_parameters": pd.DataFrame(columns)})
        out.figures["parameter_corrections"] = parameter_corrections(
            start, corrected, groups={"training rows": ds.train_index,
                                      "test rows": ds.test_index}, unit=None,
            title="Corrected parameters against their start values", setting=setting,
            reference="start")
        coefficients = out.tables["coefficients"]
        axes_by = drift_axes(coefficients, X)
        if axes_by:  # the drift was chosen: each parameter against what it drifts with
            cal = regressor.calibration_
            calibrated = {str(p): float(start) + float(offset) for p, start, offset
                          in zip(cal["parameter"], cal["start"], cal["offset"])
                          if not isinstance(start, str)}
            out.figures["parameter_drift"] = parameter_drift_figure(
                corrected, axes_by, calibrated=calibrated,
                groups={"training rows": ds.train_index, "test rows": ds.test_index},
                setting=setting)
        if getattr(physics, "ridge_path_", None) is not None:
            out.tables["ridge_path"] = physics.ridge_path_
        if physics.selection_ is not None:
            sel = physics.selection_
            out.tables["selection_path"] = sel.path
            out.figures["selection_path"] = selection_path_figure(
                sel.path, title=f"Forward covariate selection ({sel.n_rows} training rows, "
                                "CV MAE over all targets)", unit=ds.unit, setting=setting)
        return out
