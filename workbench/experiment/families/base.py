"""The model-family interface.

Its defaults suit a family whose one model predicts every target together (a sweep's study
block is then "all targets").
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import pandas as pd
from pydantic import BaseModel, ValidationError
from sklearn.base import clone

from ..._text import clip
from ...design import DesignProblem, ensemble_blocks, robust_sd
from ..config.space import SearchSpace, SpaceError
from ..process.errors import listing
from ..scoring.scores import ModelScores, Scores, mae, mse
from ..splits.folds import describe_folds, selection_cv
from .artifacts import Artifacts
from .fitting import quiet_fit

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import DataConfig, ExperimentConfig

__all__ = ["ALL_TARGETS", "ModelFamily", "Report", "quiet_progress", "showing_progress"]

#: Whether the fits a family builds now report their progress (off inside a sweep's trials).
_PROGRESS: ContextVar[bool] = ContextVar("family_progress", default=True)


def showing_progress() -> bool:
    """Tell whether a fit a family builds now reports its progress (its ``verbose``).

    It does where the ``workbench`` logger shows INFO lines (a command set it up, or a test
    captures it), except inside :func:`quiet_progress` (a sweep's trials). No number depends
    on it.

    Returns
    -------
    bool
        The ``verbose`` to build with.
    """
    return _PROGRESS.get() and logging.getLogger("workbench").isEnabledFor(logging.INFO)


@contextmanager
def quiet_progress() -> Iterator[None]:
    """Build fits that report no progress inside the ``with`` block.

    Yields
    ------
    None
    """
    token = _PROGRESS.set(False)
    try:
        yield
    finally:
        _PROGRESS.reset(token)

#: The study block of a family whose one model predicts every target.
ALL_TARGETS = "all"

#: Fold models whose spread is a family's default uncertainty for ``workbench design``.
DESIGN_FOLDS = 5

#: ``report(fold, mae, prior_mae)``: called by an objective after each inner fold.
Report = Callable[[int, float, float], None]


class ModelFamily:
    """One kind of model.

    Subclasses set :attr:`name` and implement :meth:`build`; the other methods have defaults
    for a family whose one model predicts every target at once.
    """

    #: The value of ``[model] family``.
    name: ClassVar[str] = ""
    #: The schema of ``[model.<name>]`` (``None``: the family has no settings of its own).
    settings: ClassVar[type[BaseModel] | None] = None
    #: Whether ``[evaluation]``'s repeated CV gives the model's CV figures in the result
    #: (false when the model cross-validates itself).
    cv_from_repeats: ClassVar[bool] = True
    #: ``[intervals] method`` when the config gives none: "oof" (no extra fit) where the
    #: family's fitted model keeps out-of-fold predictions of its own (``cv_predictions_``
    #: and ``cv_folds_``, see :class:`~workbench.conformal.ConformalRegressor`), else
    #: "cv_plus" (the model refitted once per fold).
    interval_method: ClassVar[str] = "cv_plus"

    # ------------------------------------------------------------------ config
    def parse_settings(self, table: dict[str, Any] | None) -> BaseModel | None:
        """Validate ``[model.<name>]``.

        Parameters
        ----------
        table : dict or None
            The table as read (``None``: not given).

        Returns
        -------
        BaseModel or None
            The settings (``None`` when the family has no settings).

        Raises
        ------
        ValueError
            For a table given to a family without settings (pydantic's ``ValidationError``,
            a ``ValueError``, for bad values).
        """
        if self.settings is None:
            if table:
                raise ValueError(f"family {self.name!r} has no settings of its own")
            return None
        return self.settings.model_validate(table or {})

    def parse_search(self, table: dict[str, Any]) -> SearchSpace:
        """Parse ``[search]``, with ``[search.<name>]`` varying this family's settings.

        Each value a search can take is checked against :attr:`settings`.

        Parameters
        ----------
        table : dict
            The ``[search]`` table as read.

        Returns
        -------
        SearchSpace
            The checked search space.

        Raises
        ------
        SpaceError
            For an unknown key or a value the settings refuse.
        """
        return SearchSpace.from_table(table, family=self.name if self.settings else None,
                                      check=self._check_setting)

    def _check_setting(self, key: str, value: Any) -> None:
        settings = self.settings
        assert settings is not None  # [search.<name>] is read only with settings (parse_search)
        fields_ = settings.model_fields
        if key not in fields_:
            shown = clip(key, 40)
            raise SpaceError(f"{self.name}.{shown}: unknown key; valid keys are "
                             f"{listing(sorted(fields_))}")
        try:
            settings.model_validate({key: value})
        except ValidationError as exc:
            # only this key's errors: a required setting the search does not vary (family
            # parametric's model file) is missing from the one-key table, not wrong
            errors = [e for e in exc.errors(include_url=False) if e["loc"][:1] == (key,)]
            if errors:
                raise SpaceError(f"{self.name}.{key} = {value!r}: "
                                 f"{errors[0]['msg'].removeprefix('Value error, ')}") from None

    #: Whether the family computes the prior itself (a CSV then needs no prior columns).
    computes_prior: ClassVar[bool] = False

    def complete_data(self, cfg: ExperimentConfig, ds: Dataset) -> Dataset:
        """Return the dataset with what the family supplies (its prior; default: as is).

        Parameters
        ----------
        cfg : ExperimentConfig
            The config.
        ds : Dataset
            The data as the source loaded them.

        Returns
        -------
        Dataset
            The data the family's model is fitted on.
        """
        return ds

    def check_data(self, data: DataConfig) -> None:
        """Check that ``[data]`` can feed this family.

        Parameters
        ----------
        data : DataConfig
            The config's ``[data]``.

        Raises
        ------
        ValueError
            When it cannot (default: a CSV needs its prior columns unless the family
            :attr:`computes_prior`).
        """
        if data.source == "csv" and data.prior is None and not self.computes_prior:
            raise ValueError(f"source = \"csv\" needs 'prior' (one column per target: the "
                             f"physics model's prediction) for family {self.name!r}")

    # ------------------------------------------------------------------ the model
    def inputs(self, cfg: ExperimentConfig, ds: Dataset) -> pd.DataFrame:
        """Make the frame the family's model reads.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config.
        ds : Dataset
            Its dataset.

        Returns
        -------
        DataFrame
            One row per experiment (default: the dataset's features and prior, ``ds.X``).
        """
        return ds.X

    def build(self, cfg: ExperimentConfig, ds: Dataset) -> Any:
        """Build the config's unfitted model over every target.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config (with a search's choices, if any).
        ds : Dataset
            Its dataset.

        Returns
        -------
        estimator
            Its ``predict`` returns one column per target.
        """
        raise NotImplementedError

    def with_trial(self, cfg: ExperimentConfig, trial: Any,
                   targets: list[str]) -> ExperimentConfig:
        """Return ``cfg`` with a trial's values.

        The ``[search]`` entries for these targets' boosting settings (one parameter shared
        by them) and the ``[search.<name>]`` entries for the family's settings.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config.
        trial : optuna.trial.BaseTrial
            An Optuna trial, or ``FixedTrial`` of a finished one.
        targets : list of str
            The study block's targets.

        Returns
        -------
        ExperimentConfig
            The copy with the trial's choices.
        """
        chosen = dict(cfg.chosen)
        if cfg.search.table:
            chosen.update({t: cfg.search.sample(trial, cfg.model_for(t)) for t in targets})
        settings = cfg.family_settings
        if settings is not None:
            settings = cfg.search.sample_family(trial, settings)
        return dataclasses.replace(cfg, chosen=chosen, family_settings=settings)

    def folds_used(self, cfg: ExperimentConfig, ds: Dataset) -> str:
        """Say which CV folds made the model's choices (``evaluate``'s ``folds:`` line).

        Default: BaseBoostCV's, ``[selection]``'s (:func:`~..splits.folds.selection_cv`); a
        family with CVs of its own says theirs too.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config.
        ds : Dataset
            The dataset (its order and groups).

        Returns
        -------
        str
            E.g. ``"5 forward-chaining by `date`"`` (:func:`~..splits.folds.describe_folds`).
        """
        return describe_folds(selection_cv(cfg, ds))

    def fixed_choices(self, model: Any) -> Any:
        """Return an unfitted copy of a fitted model that keeps the choices it made.

        The choices made on its training rows are kept where refitting would remake them
        differently.

        Parameters
        ----------
        model : estimator
            The family's fitted model.

        Returns
        -------
        estimator
            Unfitted (default: a clone).
        """
        return clone(model)

    # ------------------------------------------------------------------ sweeps
    def blocks(self, targets: list[str]) -> dict[str, list[str]]:
        """Group the targets into a sweep's study blocks (the targets tuned together).

        Parameters
        ----------
        targets : list of str
            The dataset's targets.

        Returns
        -------
        dict
            Block name -> the targets its studies choose for (default: one block, all).
        """
        return {ALL_TARGETS: list(targets)}

    def objective(self, cfg: ExperimentConfig, ds: Dataset, targets: list[str], X: pd.DataFrame,
                  Y: pd.DataFrame, trial: Any, cv: Any, report: Report) -> None:
        """Score a trial on a study's rows by inner CV.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config.
        ds : Dataset
            Its dataset.
        targets : list of str
            The study block's targets.
        X, Y : DataFrame
            The study's rows: inputs and the block's targets.
        trial : optuna.trial.Trial
            The trial.
        cv : cross-validator
            The inner folds.
        report : callable
            ``report(fold, mae, prior_mae)``, called after each fold (MAE averaged over
            ``targets``).
        """
        with quiet_progress():  # a sweep's progress is its line per trial
            model = self.build(self.with_trial(cfg, trial, targets), ds)
        prior = ds.prior.loc[X.index].to_numpy()[:, [ds.target_names.index(t) for t in targets]]
        for i, (train, val) in enumerate(cv.split(X)):
            fitted = quiet_fit(clone(model), X.iloc[train], Y.iloc[train])
            pred = np.asarray(fitted.predict(X.iloc[val]), dtype=float)
            y_val = Y.iloc[val].to_numpy(dtype=float)
            report(i, float(np.mean(mae(y_val, pred))), float(np.mean(mae(y_val, prior[val]))))

    def refit_predict(self, cfg: ExperimentConfig, ds: Dataset, targets: list[str],
                      params: dict[str, Any], X: pd.DataFrame, Y: pd.DataFrame, train: Any,
                      val: Any) -> tuple[np.ndarray, str]:
        """Refit a study's best settings on an outer fold's ``train`` rows, predict ``val``.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config.
        ds : Dataset
            Its dataset.
        targets : list of str
            The study block's targets.
        params : dict
            The study's best trial's parameters.
        X, Y : DataFrame
            The rows: inputs and the block's targets.
        train, val : array-like of int
            Positions of the fold's training and validation rows.

        Returns
        -------
        pred : ndarray
            Predictions on ``val`` rows, one column per target of the block.
        selected : str
            What was selected, comma-separated.
        """
        from optuna.trial import FixedTrial  # (b) Optuna: not for evaluate

        model = self.build(self.with_trial(cfg, FixedTrial(params), targets), ds)
        quiet_fit(model, X.iloc[train], Y.iloc[train])
        pred = np.asarray(model.predict(X.iloc[val]), dtype=float)
        return pred, ",".join(self.selected(model, targets))

    def chosen_config(self, cfg: ExperimentConfig, ds: Dataset,
                      best: dict[str, dict[str, Any] | None]) -> ExperimentConfig:
        """Return ``cfg`` with the final studies' choices.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config.
        ds : Dataset
            Its dataset.
        best : dict
            Block -> best params; a block without a completed trial (``None``) keeps the
            config's own settings.

        Returns
        -------
        ExperimentConfig
            The copy with the choices.
        """
        from optuna.trial import FixedTrial  # (b) Optuna: not for evaluate

        for block, targets in self.blocks(ds.target_names).items():
            params = best.get(block)
            if params is not None:
                cfg = self.with_trial(cfg, FixedTrial(params), targets)
        return cfg

    def final_model(self, cfg: ExperimentConfig, ds: Dataset) -> Any:
        """Build the unfitted model a sweep refits on all training rows.

        Parameters
        ----------
        cfg : ExperimentConfig
            The config with the sweep's choices (:meth:`chosen_config`).
        ds : Dataset
            Its dataset.

        Returns
        -------
        estimator
            Unfitted.
        """
        return self.build(cfg, ds)

    # ------------------------------------------------------------------ results
    @property
    def writes_outputs(self) -> bool:
        """Whether :meth:`outputs` has tables and figures for ``evaluate --out``.

        True when the family overrides it.
        """
        return type(self).outputs is not ModelFamily.outputs

    def selected(self, model: Any, targets: list[str]) -> list[str]:
        """Say what the fitted model chose per target.

        Parameters
        ----------
        model : estimator
            The family's fitted model.
        targets : list of str
            Its targets.

        Returns
        -------
        list of str
            One label per target (default: its ``selected_`` or "model").
        """
        return list(getattr(model, "selected_", ["model"] * len(targets)))

    def scores(self, ds: Dataset, model: Any, Y_train: pd.DataFrame, prior_test: Any,
               y_test: Any, pred: Any) -> tuple[Scores, ModelScores, dict[str, Any]]:
        """Score the prior and a fitted model, and collect the family's details.

        Default: no CV inside the model, so the prior's CV error is its training error (it
        is not fitted) and the model's CV error is unknown (NaN) unless ``[evaluation]``
        asks for a repeated CV.

        Parameters
        ----------
        ds : Dataset
            The dataset.
        model : estimator
            The family's fitted model.
        Y_train : DataFrame
            The training rows' targets.
        prior_test, y_test, pred : ndarray
            The test rows' prior, measured targets and predictions.

        Returns
        -------
        prior : Scores
            The prior's scores.
        model : ModelScores
            The model's scores.
        details : dict
            The family's JSON-ready details.
        """
        prior_train = ds.prior.loc[Y_train.index].to_numpy()
        nan = [float("nan")] * len(ds.target_names)
        prior = Scores(test_mae=mae(y_test, prior_test), test_mse=mse(y_test, prior_test),
                       cv_mae=mae(Y_train, prior_train), cv_mse=mse(Y_train, prior_train))
        scores = ModelScores(test_mae=mae(y_test, pred), test_mse=mse(y_test, pred),
                             cv_mae=list(nan), cv_mse=list(nan),
                             selected=self.selected(model, ds.target_names))
        return prior, scores, {}

    def run_metrics(self, details: dict[str, Any]) -> dict[str, float]:
        """Give the MLflow metrics a tracked run has beyond every run's scores.

        Parameters
        ----------
        details : dict
            The family's section of the result (:meth:`scores`' details).

        Returns
        -------
        dict of str to float
            Metric name -> value (default: none).
        """
        return {}

    def begin_artifacts(self, cfg: ExperimentConfig, ds: Dataset, model: Any, setting: str,
                        quick: bool = False) -> Callable[..., Artifacts]:
        """Start the figures and tables a tracked run has beyond :meth:`outputs`.

        They come beside the MAE/MSE bars every run has and the family's :meth:`outputs`
        (which a run logs too); they are computed before the run is recorded
        (``workbench.experiment.runs.run_outputs.compute_outputs``).

        In two halves: start what can run on the worker processes (e.g. learning-curve
        fits) and return a function ``finish(emit=None)`` that waits for it, draws the
        figures and returns the :class:`Artifacts`, so the run's other figures are drawn
        meanwhile. ``emit(name, figure)``, if given, receives every figure as soon as it is
        drawn.

        Parameters
        ----------
        cfg : ExperimentConfig
            The run's config.
        ds : Dataset
            The run's dataset.
        model : estimator
            The family's fitted model.
        setting : str
            What the figures' titles say the run was.
        quick : bool, default=False
            Fewer points and rows (tests).

        Returns
        -------
        callable
            ``finish(emit=None) -> Artifacts``. Default: nothing started, nothing beyond
            :meth:`outputs`.
        """
        def finish(emit: Callable[[str, Any], None] | None = None) -> Artifacts:
            return Artifacts()

        return finish

    def outputs(self, model: Any, ds: Dataset, setting: str) -> Artifacts | None:
        """Make what ``evaluate --out DIR`` writes.

        Parameters
        ----------
        model : estimator
            The family's fitted model.
        ds : Dataset
            The dataset it was fitted on.
        setting : str
            What the figures' titles say the run was.

        Returns
        -------
        Artifacts or None
            ``None``: the family writes nothing (the default).
        """
        return None

    # ------------------------------------------------------------------ design
    def design_problem(self, model: Any, X: pd.DataFrame, Y: pd.DataFrame,
                       candidates: pd.DataFrame, random_state: int | None = None
                       ) -> DesignProblem:
        """Say what the ``model`` fitted on ``X``, ``Y`` does not know at the ``candidates``.

        For ``workbench design``. Default: the spread of :data:`DESIGN_FOLDS` fold models
        (the fitted model's choices kept, :meth:`fixed_choices`, each refitted without one
        fold of the rows), with each target's noise sd the robust sd of the fold models'
        out-of-fold residuals (:func:`~workbench.design.ensemble_blocks`).

        Parameters
        ----------
        model : estimator
            The family's model, fitted on ``X``, ``Y``.
        X, Y : DataFrame
            The measured rows: :meth:`inputs`' columns and the targets.
        candidates : DataFrame
            The candidate settings, :meth:`inputs`' columns.
        random_state : int, optional
            Seeds the folds.

        Returns
        -------
        DesignProblem
            The information blocks of the candidates and the noise sd per target.
        """
        from sklearn.model_selection import KFold

        folds = KFold(min(DESIGN_FOLDS, len(X)), shuffle=True,
                      random_state=random_state or 0)
        preds, resid = [], np.empty(Y.shape)
        for train, val in folds.split(X):
            fold = quiet_fit(self.fixed_choices(model), X.iloc[train], Y.iloc[train])
            preds.append(np.asarray(fold.predict(candidates), dtype=float))
            resid[val] = Y.iloc[val].to_numpy(dtype=float) - np.asarray(
                fold.predict(X.iloc[val]), dtype=float)
        noise = robust_sd(resid, axis=0)
        blocks, information = ensemble_blocks(np.stack(preds), noise)
        k = len(preds)
        names = [str(t) for t in Y.columns for _ in range(k)]
        return DesignProblem(blocks, information, noise, names,
                             f"the spread of {k} fold models",
                             informs="the fold models' spread of {name} falls {fraction:.0%}")
