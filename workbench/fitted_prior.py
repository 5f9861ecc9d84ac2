"""Base boosting on top of a fitted multi-output physics model.

:class:`FittedPriorBoost` first fits a multi-output model of all targets (for instance the
parameter-space :class:`~workbench.param_select.HamiltonianSelectionCV`), then uses its
prediction for target ``j`` as the prior of a per-target base-boosting stage
(:class:`~workbench.MultiTargetBaseBoost` of :class:`~workbench.BaseBoostCV`, so each target
keeps the physics model alone unless cross-validation says boosting helps).

The boosting stage is trained on *out-of-fold* prior values, as scikit-learn's stacking does:
on the training rows the prior column holds predictions of models refitted without each row
(with the physics model's own choices fixed, e.g. the selected covariates); on new rows it
holds the fitted physics model's predictions. Boosting the in-sample residuals of a flexible
physics model would learn from residuals that are smaller than the ones it meets later.
"""

from __future__ import annotations

from numbers import Integral
from typing import Any, Self

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, MetaEstimatorMixin, RegressorMixin, clone
from sklearn.model_selection import check_cv
from sklearn.utils._param_validation import HasMethods, StrOptions
from sklearn.utils.validation import check_is_fitted

from ._progress import Progress
from .multitarget import MultiTargetBaseBoost, check_targets
from .parallel import Task, map_tasks

__all__ = ["FittedPriorBoost"]


def _refittable(fitted: Any) -> tuple[Any, dict[str, Any]]:
    """An unfitted estimator with the fitted model's choices fixed (``estimator_`` of a
    selection wrapper such as HamiltonianSelectionCV, else the model itself), and the fit
    parameters that warm-start it from the fitted model: ``coef_init`` for a model that
    takes it and whose fitted form has ``coef_dict`` (e.g.
    :class:`~workbench.param_regressor.HamiltonianParameterRegressor`)."""
    chosen = getattr(fitted, "estimator_", fitted)
    start = getattr(chosen, "coef_dict", None)
    return clone(chosen), ({"coef_init": start()} if callable(start) else {})


def _fold_prediction(model: Any, fit_params: dict[str, Any], X: pd.DataFrame, Y: np.ndarray,
                     train: np.ndarray, val: np.ndarray) -> np.ndarray:
    """``model`` fitted on the rows ``train`` and predicting the rows ``val``."""
    model.fit(X.iloc[train], Y[train], **fit_params)
    return np.asarray(model.predict(X.iloc[val]), dtype=float)


class FittedPriorBoost(MetaEstimatorMixin, RegressorMixin, BaseEstimator):
    r"""A multi-output model as the prior of per-target base boosting.

    Parameters
    ----------
    physics : regressor
        Multi-output regressor of all targets, fitted on ``(X, Y)``; ``predict`` returns
        ``(n, n_targets)``.
    boost : MultiTargetBaseBoost, default=None
        The per-target stage (``None``: ``MultiTargetBaseBoost()``, i.e. ``BaseBoostCV`` with
        its defaults). Its ``priors`` are set to the prior columns added here.
    prior_prefix : str, default="prior\_"
        The prior of target ``t`` is added to ``X`` as column ``prior_prefix + t``; the
        boosting stage's ``basis_features`` may name these columns.
    cv : int or CV splitter, default=5
        Folds of the out-of-fold prior on the training rows. Each fold refits the physics
        model with its choices fixed, warm-started from the fit on all rows where the model
        takes ``coef_init``. Rows no fold holds out (forward-chaining folds' earliest block)
        take the model refitted on those rows themselves, so no later row reaches their
        prior (their ``prior_folds_`` is -1).
    boost_stage : bool, default=True
        ``False`` fits the physics model alone (``predict`` is its prediction).
    cv_predictions : bool, default=True
        Without a stage and without ``fallback``, whether ``fit`` still computes the
        out-of-fold prior (``cv_predictions_``, e.g. for out-of-fold prediction intervals);
        ``False`` saves its ``cv`` refits (``cv_predictions_`` then raises). A stage or a
        fallback always needs it.
    n_jobs : int, default=None
        Processes for the out-of-fold refits (:mod:`workbench.parallel`; ``None``: 1,
        ``-1``: every core). The results do not depend on it.
    fallback : list of str or regressor, default=None
        The control model's own prediction of each target: columns of ``X`` holding it, or a
        regressor of all targets making it (e.g. a user's model at its start values,
        ``ParametricRegressor(max_iter=0, calibrate=False)``; fitted on the rows, its
        out-of-fold prediction on the same folds as the physics model's is the evidence). If
        given, a target keeps the physics model only where its out-of-fold MAE on the
        training rows is below the control prediction's MAE there; elsewhere the control
        prediction is the prior (so where the control model is already right, fitting
        corrections that only chase noise is not kept).
    alternative : regressor, dict of str -> regressor or "candidates", default=None
        Other physics models of all targets whose prediction may be the stage's prior
        instead (the parametric family's calibrated model beside its drift): one (named
        ``"alternative"``), several by name (simplest first), or ``"candidates"``, the
        fitted physics model's ``other_candidates_`` (e.g.
        :class:`~workbench.parametric_boost.ParametricBoostRegressor`'s candidates its own
        CV did not choose, their choices kept). With a stage, the stage is fitted on the
        out-of-fold prior of each, and a target keeps the prior on which the stage's CV MAE
        is lowest (ties: the earliest alternative, the physics model last): the stage is
        scored as it is used, where the physics model's own CV scored it without the stage.
        Not with ``fallback``.
    stage_mean : bool, default=False
        With alternatives: also score, per target, the mean of the stages over every prior
        (the physics model's and each alternative's, each stage on its own prior) by the MAE
        of the mean of their CV predictions (the stages share their folds), and keep it
        where that is the lowest stage CV MAE (ties: a single prior). Mixing the physics
        path with the generic one helps where new rows are like the training rows; the
        random folds that choose it do not see extrapolation, where it can be worse.
    verbose : bool, default=False
        Report the phases of ``fit`` after the physics model's own (the out-of-fold refits,
        the stage): INFO records of the ``workbench.fitted_prior`` logger, or printed to
        standard error where no logging is set up (:mod:`workbench._progress`). The physics
        model reports through its own ``verbose``. No number depends on it.

    Attributes
    ----------
    physics_ : regressor
        The fitted physics model.
    physics_selected_ : ndarray of bool
        Per target, whether the physics model is the prior (all true without ``fallback``).
    fallback_ : regressor
        With a regressor as ``fallback``: it, fitted on the rows.
    alternatives_ : dict of str -> regressor
        The fitted alternatives by name (empty without any, or without a stage).
    prior_choice_ : ndarray of str
        Per target, the stage's prior: ``"physics"``, an alternative's name, or ``"mean"``
        (``stage_mean``: the mean of the stages over every prior).
    stages_ : dict of str -> MultiTargetBaseBoost
        Where a target keeps the mean: the stage fitted on each prior, by name (``physics``
        and the alternatives'); else empty.
    alternative_selected_ : ndarray of bool
        Per target, whether an alternative is the prior (all false without one).
    stage_cv_mae_ : DataFrame or None
        With alternatives: per target (rows) the stage's CV MAE on the physics model's
        prior (column ``physics``) and on each alternative's (its name); with
        ``stage_mean``, of their mean (``mean``).
    boost_ : MultiTargetBaseBoost
        The fitted boosting stage (``boost_stage=True``).
    prior_columns_ : list of str
        The prior columns added to ``X``.
    oof_prior_ : DataFrame
        The out-of-fold prior on the training rows (not set when nothing needs it: no
        stage, no fallback, ``cv_predictions=False``).
    prior_folds_ : ndarray of shape (n_samples,)
        The fold of each row in ``oof_prior_`` (-1: held out by none, fitted on itself).
    target_names_ : list of str
        The targets, in the order of the prediction's columns.
    """

    _parameter_constraints: dict = {
        "physics": [HasMethods(["fit", "predict"])],
        "boost": [None, HasMethods(["fit", "predict"])],
        "prior_prefix": [str],
        "cv": ["cv_object"],
        "boost_stage": ["boolean"],
        "fallback": [None, list, tuple, HasMethods(["fit", "predict"])],
        "cv_predictions": ["boolean"],
        "n_jobs": [None, Integral],
        "alternative": [None, HasMethods(["fit", "predict"]), dict,
                        StrOptions({"candidates"})],
        "stage_mean": ["boolean"],
        "verbose": ["boolean"],
    }

    def __init__(self, physics: Any = None, boost: Any = None, *, prior_prefix: str = "prior_",
                 cv: Any = 5, boost_stage: bool = True, fallback: Any = None,
                 cv_predictions: bool = True, n_jobs: int | None = None,
                 alternative: Any = None, stage_mean: bool = False,
                 verbose: bool = False) -> None:
        self.physics = physics
        self.boost = boost
        self.prior_prefix = prior_prefix
        self.cv = cv
        self.boost_stage = boost_stage
        self.fallback = fallback
        self.cv_predictions = cv_predictions
        self.n_jobs = n_jobs
        self.alternative = alternative
        self.stage_mean = stage_mean
        self.verbose = verbose

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickle, giving a model pickled before ``alternative`` and ``verbose`` existed
        their defaults, and one fitted with a single ``alternative_`` its ``alternatives_``
        and ``prior_choice_`` (a registered model keeps ``get_params``, ``clone``, ``repr``
        and ``predict``)."""
        super().__setstate__(state)
        for name, default in (("alternative", None), ("stage_mean", False),
                              ("verbose", False)):
            if name not in self.__dict__:
                setattr(self, name, default)
        if "physics_" in self.__dict__ and "stages_" not in self.__dict__:
            self.stages_: dict[str, Any] = {}
        if "physics_" in self.__dict__ and "prior_choice_" not in self.__dict__:
            single = self.__dict__.pop("alternative_", None)
            chose = self.__dict__.get("alternative_selected_",
                                      np.zeros(len(self.target_names_), dtype=bool))
            self.alternatives_: dict[str, Any] = ({} if single is None
                                                  else {"alternative": single})
            self.prior_choice_ = np.where(chose, "alternative", "physics").astype(object)
            self.alternative_selected_ = np.asarray(chose, dtype=bool)

    def _with_prior(self, X: pd.DataFrame, prior: np.ndarray) -> pd.DataFrame:
        clash = [c for c in self.prior_columns_ if c in X.columns]
        if clash:
            raise ValueError(f"X already has column(s) {clash}; choose another prior_prefix")
        added = pd.DataFrame(prior, columns=self.prior_columns_, index=X.index)
        return pd.concat([X, added], axis=1)

    def fit(self, X: pd.DataFrame, Y: Any) -> Self:
        """Fit the physics model on all rows, its out-of-fold prior, then the stage on top.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The inputs, by column name.
        Y : array-like of shape (n_samples, n_targets)
            The targets.

        Returns
        -------
        self
            The fitted model.
        """
        self._validate_params()
        say = Progress(__name__, self.verbose, "stage: ")
        if not isinstance(X, pd.DataFrame):
            raise ValueError(f"X must be a pandas DataFrame, got {type(X).__name__}")
        Y_arr, names = check_targets(X, Y)
        self.target_names_ = names
        self.prior_columns_ = [f"{self.prior_prefix}{t}" for t in names]
        self.physics_ = clone(self.physics).fit(X, Y_arr)
        self.n_features_in_ = X.shape[1]
        self.feature_names_in_ = np.asarray([str(c) for c in X.columns], dtype=object)
        self.physics_selected_ = np.ones(len(names), dtype=bool)
        if isinstance(self.fallback, (list, tuple)) and len(self.fallback) != len(names):
            raise ValueError(f"fallback names {len(self.fallback)} column(s) for "
                             f"{len(names)} targets")
        if self.alternative is not None and self.fallback is not None:
            raise ValueError("alternative and fallback cannot be combined: give one")
        # the out-of-fold prior: the stage's training prior, the fallback's evidence, and
        # (without a stage) the model's own out-of-fold predictions (cv_predictions_)
        self.alternatives_ = {}
        self.stages_ = {}
        self.prior_choice_ = np.full(len(names), "physics", dtype=object)
        self.alternative_selected_ = np.zeros(len(names), dtype=bool)
        self.stage_cv_mae_: pd.DataFrame | None = None
        if not (self.boost_stage or self.fallback is not None or self.cv_predictions):
            return self
        splits = list(check_cv(self.cv).split(X))
        held = np.zeros(len(X), dtype=bool)
        for _, val in splits:
            held[val] = True
        never = np.flatnonzero(~held)  # e.g. the earliest rows of forward-chaining folds
        tasks = [*splits, *([(never, never)] if len(never) else [])]
        say(f"out-of-fold priors: {len(tasks)} refits of the physics model, its choices kept")
        oof = self._out_of_fold(self.physics_, X, Y_arr, tasks)
        folds = np.full(len(X), -1, dtype=int)
        for k, (_, val) in enumerate(splits):
            folds[val] = k
        self.prior_folds_ = folds
        if self.fallback is not None:
            if isinstance(self.fallback, (list, tuple)):
                control = self._control(X)
            else:  # its out-of-fold prediction, as the physics model's
                self.fallback_ = clone(self.fallback).fit(X, Y_arr)
                control = self._out_of_fold(self.fallback_, X, Y_arr, tasks)
            self.physics_selected_ = (np.mean(np.abs(Y_arr - oof), axis=0)
                                      < np.mean(np.abs(Y_arr - control), axis=0))
            oof = np.where(self.physics_selected_, oof, control)
        if not self.boost_stage:
            self.oof_prior_ = pd.DataFrame(oof, columns=self.prior_columns_, index=X.index)
            return self
        boost = MultiTargetBaseBoost() if self.boost is None else clone(self.boost)
        boost.set_params(priors=self.prior_columns_)
        Y_frame = pd.DataFrame(Y_arr, columns=names, index=X.index)
        say(f"base boosting {len(names)} target(s) from the out-of-fold priors "
            f"({say.elapsed()})")
        self.boost_ = clone(boost).fit(self._with_prior(X, oof), Y_frame)
        if self.alternative is not None:
            oof = self._choose_prior(X, Y_arr, Y_frame, tasks, oof, boost, say)
        if say:
            kept = sum(s == "boosted" for s in self.selected_)
            say(f"kept on {kept} of {len(names)} target(s) ({say.elapsed()})")
        self.oof_prior_ = pd.DataFrame(oof, columns=self.prior_columns_, index=X.index)
        return self

    def _out_of_fold(self, fitted: Any, X: pd.DataFrame, Y: np.ndarray,
                     tasks: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """``fitted``'s out-of-fold prediction: refitted with its choices fixed per task."""
        model, fit_params = _refittable(fitted)
        preds = map_tasks([Task(_fold_prediction, model, fit_params, X, Y, train, val)
                           for train, val in tasks], self.n_jobs)
        oof = np.empty_like(Y)
        for (_, val), pred in zip(tasks, preds, strict=True):
            oof[val] = pred
        return oof

    def _alternatives(self) -> dict[str, Any]:
        """The unfitted alternatives by name, simplest first."""
        if isinstance(self.alternative, str):  # "candidates": the physics model's own
            others = getattr(self.physics_, "other_candidates_", None)
            if not isinstance(others, dict):
                raise ValueError(f'alternative="candidates" needs a physics model with '
                                 f"other_candidates_ (e.g. ParametricBoostRegressor); "
                                 f"{type(self.physics_).__name__} has none")
            return dict(others)
        if isinstance(self.alternative, dict):
            if "physics" in self.alternative:
                raise ValueError('"physics" names the physics model\'s own prior: give the '
                                 "alternative another name")
            return dict(self.alternative)
        return {"alternative": self.alternative}

    def _choose_prior(self, X: pd.DataFrame, Y: np.ndarray, Y_frame: pd.DataFrame,
                      tasks: list[tuple[np.ndarray, np.ndarray]], oof: np.ndarray,
                      boost: Any, say: Progress) -> np.ndarray:
        """Fit each alternative and the stage on its out-of-fold prior; per target keep the
        prior whose stage scored the lowest CV MAE (ties: the earliest alternative, the
        physics model last); return the out-of-fold prior the final stage is trained on."""
        priors, stages = {"physics": oof}, {"physics": self.boost_}
        cv = {"physics": [-e.cv_score_ for e in self.boost_.estimators_]}
        choosable = []
        for name, model in self._alternatives().items():
            say(f"the alternative prior {name!r}: its fit, {len(tasks)} refits and its stage "
                f"({say.elapsed()})")
            self.alternatives_[name] = clone(model).fit(X, Y)
            priors[name] = self._out_of_fold(self.alternatives_[name], X, Y, tasks)
            if np.array_equal(priors[name], oof):  # the physics model itself: one stage
                cv[name] = cv["physics"]
                continue
            stages[name] = clone(boost).fit(self._with_prior(X, priors[name]), Y_frame)
            cv[name] = [-e.cv_score_ for e in stages[name].estimators_]
            choosable.append(name)
        order = [*choosable, "physics"]
        if self.stage_mean and choosable:
            names = ["physics", *choosable]
            folds = [np.asarray(stages[k].cv_folds_) for k in names]
            if not all(np.array_equal(folds[0], f) for f in folds):
                raise ValueError("stage_mean needs the stages' CV folds to agree; the stage's "
                                 "cv must be a fixed splitter or seeded")
            mean = np.mean([np.asarray(stages[k].cv_predictions_, dtype=float)
                            for k in names], axis=0)
            cv["mean"] = list(np.mean(np.abs(Y - mean), axis=0))
            order.append("mean")
        self.stage_cv_mae_ = pd.DataFrame(cv, index=list(Y_frame.columns))
        table = self.stage_cv_mae_[order].to_numpy()
        self.prior_choice_ = np.asarray([order[int(np.argmin(row))] for row in table],
                                        dtype=object)
        self.alternative_selected_ = self.prior_choice_ != "physics"
        if say:
            for t, kept in zip(Y_frame.columns, self.prior_choice_, strict=True):
                say(f"{t}: the stage's CV MAE on each prior: " + ", ".join(
                    f"{'the physics model' if c == 'physics' else c} "
                    f"{self.stage_cv_mae_.loc[t, c]:.4g}" + (" (kept)" if c == kept else "")
                    for c in ["physics", *choosable, *order[len(choosable) + 1:]]))
        if "mean" in self.prior_choice_:  # its targets: every stage, each on its prior
            self.stages_ = {k: stages[k] for k in ["physics", *choosable]}
            priors["mean"] = np.mean([priors[k] for k in self.stages_], axis=0)
        # the targets that keep the mean take the physics model's stage in boost_ (its
        # prediction there is replaced by the stages' mean)
        single = np.where(self.prior_choice_ == "mean", "physics", self.prior_choice_)
        chosen = set(single)
        if len(chosen) == 1:
            (only,) = chosen
            self.boost_ = stages[only]
        else:
            mixed = np.column_stack([priors[c][:, j] for j, c in enumerate(single)])
            self.boost_ = clone(boost).fit(self._with_prior(X, mixed), Y_frame)
        return np.column_stack([priors[c][:, j] for j, c in enumerate(self.prior_choice_)])

    def _control(self, X: pd.DataFrame) -> np.ndarray:
        """The control prediction (``fallback``'s columns, or its fitted regressor's)."""
        if isinstance(self.fallback, (list, tuple)):
            return X[list(self.fallback)].to_numpy(dtype=float)
        return np.asarray(self.fallback_.predict(X), dtype=float).reshape(len(X), -1)

    def predict_prior(self, X: pd.DataFrame) -> np.ndarray:
        """The prior of the stage: the physics model's prediction (the control prediction for
        targets where it fell back, an alternative's where the stage chose it), shape
        ``(n, n_targets)``.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The inputs, by column name.

        Returns
        -------
        ndarray of shape (n_samples, n_targets)
            The prior.
        """
        check_is_fitted(self)
        return self._priors(X)["chosen"]

    def _priors(self, X: pd.DataFrame) -> dict[str, np.ndarray]:
        """Every prior the stages use, by name (``physics``: the physics model's prediction,
        the control prediction where it fell back), and ``chosen``: per target the prior
        :attr:`prior_choice_` names (the mean of the stages' priors for ``"mean"``)."""
        physics = np.asarray(self.physics_.predict(X), dtype=float)
        if self.fallback is not None and not self.physics_selected_.all():
            physics = np.where(self.physics_selected_, physics, self._control(X))
        names = set(self.prior_choice_) | set(self.stages_)
        out = {"physics": physics}
        for name in sorted(names - {"physics", "mean"}):
            out[name] = np.asarray(self.alternatives_[name].predict(X),
                                   dtype=float).reshape(physics.shape)
        if self.stages_:
            out["mean"] = np.mean([out[k] for k in self.stages_], axis=0)
        chosen = physics.copy()
        for j, name in enumerate(self.prior_choice_):
            chosen[:, j] = out[name][:, j]
        out["chosen"] = chosen
        return out

    def predict(self, X: pd.DataFrame) -> pd.DataFrame:
        """Predictions as a DataFrame with one column per target.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The inputs, by column name.

        Returns
        -------
        pandas.DataFrame of shape (n_samples, n_targets)
            The predictions, indexed as ``X``.
        """
        check_is_fitted(self)
        priors = self._priors(X)
        if not self.boost_stage:
            return pd.DataFrame(priors["chosen"], columns=self.target_names_, index=X.index)
        if not self.stages_:
            return self.boost_.predict(self._with_prior(X, priors["chosen"]))
        mean = self.prior_choice_ == "mean"
        each = {name: stage.predict(self._with_prior(X, priors[name]))
                for name, stage in self.stages_.items()}
        if self.boost_ is self.stages_.get("physics"):  # every other target on the physics
            pred = each["physics"].copy()                # prior: that stage's prediction
        else:
            single = np.where(mean, priors["physics"], priors["chosen"])
            pred = self.boost_.predict(self._with_prior(X, single))
        stages = [np.asarray(p, dtype=float) for p in each.values()]
        pred.loc[:, mean] = np.mean(stages, axis=0)[:, mean]
        return pred

    def _check_oof(self) -> None:
        """Raise where fit computed no out-of-fold prior (``cv_predictions=False``)."""
        if not hasattr(self, "prior_folds_"):
            raise AttributeError("no out-of-fold predictions: fitted with "
                                 "cv_predictions=False (and neither a stage nor a fallback)")

    @property
    def cv_predictions_(self) -> np.ndarray:
        """Out-of-fold predictions on the training rows, ``(n_samples, n_targets)``: the
        boosting stage's own (:attr:`MultiTargetBaseBoost.cv_predictions_`, from its folds
        over the out-of-fold prior), or without a stage the out-of-fold prior itself. The
        physics model's own choices (e.g. its selected covariates) were made on all rows.
        """
        check_is_fitted(self)
        if self.boost_stage:
            cv = np.array(self.boost_.cv_predictions_, dtype=float)
            mean = self.prior_choice_ == "mean"
            if mean.any():  # the mean of the stages' own (their folds agree)
                cv[:, mean] = np.mean([np.asarray(s.cv_predictions_, dtype=float)
                                       for s in self.stages_.values()], axis=0)[:, mean]
            return cv
        self._check_oof()
        return self.oof_prior_.to_numpy()

    @property
    def cv_folds_(self) -> np.ndarray:
        """Per training row (and target), the fold that held it out in
        :attr:`cv_predictions_`."""
        check_is_fitted(self)
        if self.boost_stage:
            return self.boost_.cv_folds_
        self._check_oof()
        return self.prior_folds_

    @property
    def selected_(self) -> list[str]:
        """Per target: ``"prior"`` (the physics model alone) or ``"boosted"`` (for a target
        keeping the mean of the stages: ``"boosted"`` where any of them boosted)."""
        check_is_fitted(self)
        if not self.boost_stage:
            return ["prior"] * len(self.target_names_)
        selected = list(self.boost_.selected_)
        for j, name in enumerate(self.prior_choice_):
            if name == "mean":
                selected[j] = ("boosted" if any(s.selected_[j] == "boosted"
                                                for s in self.stages_.values()) else "prior")
        return selected

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "physics_")
