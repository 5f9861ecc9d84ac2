"""The model-family interface, with defaults for a family whose one model predicts every
target together (a sweep's study unit is then "all targets")."""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar

import numpy as np
import pandas as pd
from pydantic import BaseModel, ValidationError
from sklearn.base import clone
from sklearn.exceptions import ConvergenceWarning

from ..._io import atomic_write
from ...design import DesignProblem, ensemble_blocks, robust_sd
from ..errors import listing
from ..figures import save_figure
from ..results import ModelScores, Scores, mae, mse
from ..space import SearchSpace, SpaceError

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import DataConfig, ExperimentConfig

__all__ = ["ALL_TARGETS", "Artifacts", "ModelFamily", "Report"]

#: The study unit of a family whose one model predicts every target.
ALL_TARGETS = "all"

#: Fold models whose spread is a family's default uncertainty for ``workbench design``.
DESIGN_FOLDS = 5

#: ``report(fold, mae, prior_mae)``: called by an objective after each inner fold.
Report = Callable[[int, float, float], None]


@dataclass
class Artifacts:
    """A fitted model's extra outputs: figures (name -> matplotlib Figure), tables (name ->
    DataFrame, written as CSV without the index) and JSON-ready data."""

    figures: dict[str, Any] = field(default_factory=dict)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)

    def write(self, directory, *, tables: bool = True, figures: bool = True) -> dict[str, Any]:
        """Tables as ``<directory>/<name>.csv`` (no index column), figures as PNG; returns
        name -> path."""
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        written: dict[str, Any] = {}
        for name, table in (self.tables.items() if tables else ()):
            written[name] = atomic_write(directory / f"{name}.csv", table.to_csv(index=False))
        for name, fig in (self.figures.items() if figures else ()):
            written[name] = save_figure(fig, directory / f"{name}.png")
        return written


def quiet_fit(model, X, y):
    """``model.fit(X, y)`` without scikit-learn's convergence warnings (an MLP's max_iter is
    the search's business, not noise)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        return model.fit(X, y)


class ModelFamily:
    """One kind of model. Subclasses set :attr:`name` and implement :meth:`build`; the other
    methods have defaults for a family whose one model predicts every target at once."""

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

    @property
    def writes_outputs(self) -> bool:
        """Whether :meth:`outputs` has tables and figures for ``evaluate --out`` (the family
        overrides it)."""
        return type(self).outputs is not ModelFamily.outputs

    # ------------------------------------------------------------------ config
    def parse_settings(self, table: dict[str, Any] | None) -> BaseModel | None:
        """``[model.<name>]``, validated (``None`` when the family has no settings)."""
        if self.settings is None:
            if table:
                raise ValueError(f"family {self.name!r} has no settings of its own")
            return None
        return self.settings.model_validate(table or {})

    def parse_search(self, table: dict[str, Any]) -> SearchSpace:
        """``[search]``, with ``[search.<name>]`` varying this family's settings (each value a
        search can take is checked against :attr:`settings`)."""
        return SearchSpace.from_table(table, family=self.name if self.settings else None,
                                      check=self._check_setting)

    def _check_setting(self, key: str, value: Any) -> None:
        settings = self.settings
        assert settings is not None  # [search.<name>] is read only with settings (parse_search)
        fields_ = settings.model_fields
        if key not in fields_:
            shown = key if len(key) <= 40 else key[:37] + "..."
            raise SpaceError(f"{self.name}.{shown}: unknown key; valid keys are "
                             f"{listing(sorted(fields_))}")
        try:
            settings.model_validate({key: value})
        except ValidationError as exc:
            err = exc.errors(include_url=False)[0]
            raise SpaceError(f"{self.name}.{key} = {value!r}: "
                             f"{err['msg'].removeprefix('Value error, ')}") from None

    def check_data(self, data: DataConfig) -> None:
        """Raise ``ValueError`` when ``[data]`` cannot feed this family."""

    # ------------------------------------------------------------------ the model
    def inputs(self, cfg: ExperimentConfig, ds: Dataset) -> pd.DataFrame:
        """The frame the family's model reads (rows: every experiment)."""
        return ds.X

    def build(self, cfg: ExperimentConfig, ds: Dataset):
        """The config's unfitted model over every target (``predict`` returns a frame with
        one column per target)."""
        raise NotImplementedError

    def with_trial(self, cfg: ExperimentConfig, trial, targets: list[str]) -> ExperimentConfig:
        """``cfg`` with a trial's values (an Optuna trial, or ``FixedTrial`` of a finished
        one): the ``[search]`` entries for these targets' boosting settings (one parameter
        shared by them) and the ``[search.<name>]`` entries for the family's settings."""
        chosen = dict(cfg.chosen)
        if cfg.search.table:
            chosen.update({t: cfg.search.sample(trial, cfg.model_for(t)) for t in targets})
        settings = cfg.family_settings
        if settings is not None:
            settings = cfg.search.sample_family(trial, settings)
        return dataclasses.replace(cfg, chosen=chosen, family_settings=settings)

    def fixed_choices(self, model):
        """An unfitted copy of a fitted model that keeps the choices it made on its training
        rows where refitting would remake them differently (default: a clone)."""
        return clone(model)

    # ------------------------------------------------------------------ sweeps
    def units(self, targets: list[str]) -> dict[str, list[str]]:
        """A sweep's study units: unit name -> the targets its studies choose for."""
        return {ALL_TARGETS: list(targets)}

    def objective(self, cfg: ExperimentConfig, ds: Dataset, targets: list[str], X, Y, trial,
                  cv, report: Report) -> None:
        """Score a trial on a study's rows by inner CV: ``report(fold, mae, prior_mae)``
        after each fold (MAE averaged over ``targets``)."""
        model = self.build(self.with_trial(cfg, trial, targets), ds)
        prior = ds.prior.loc[X.index].to_numpy()[:, [ds.target_names.index(t) for t in targets]]
        for i, (train, val) in enumerate(cv.split(X)):
            fitted = quiet_fit(clone(model), X.iloc[train], Y.iloc[train])
            pred = np.asarray(fitted.predict(X.iloc[val]), dtype=float)
            y_val = Y.iloc[val].to_numpy(dtype=float)
            report(i, float(np.mean(mae(y_val, pred))), float(np.mean(mae(y_val, prior[val]))))

    def refit_predict(self, cfg: ExperimentConfig, ds: Dataset, targets: list[str],
                      params: dict[str, Any], X, Y, train, val) -> tuple[np.ndarray, str]:
        """An outer fold: a study's best settings refitted on ``train`` rows; returns the
        predictions on ``val`` rows (one column per target of the unit) and what was
        selected."""
        from optuna.trial import FixedTrial  # (b) Optuna: not for evaluate

        model = self.build(self.with_trial(cfg, FixedTrial(params), targets), ds)
        quiet_fit(model, X.iloc[train], Y.iloc[train])
        pred = np.asarray(model.predict(X.iloc[val]), dtype=float)
        return pred, ",".join(self.selected(model, targets))

    def chosen_config(self, cfg: ExperimentConfig, ds: Dataset,
                      best: dict[str, dict[str, Any] | None]) -> ExperimentConfig:
        """``cfg`` with the final studies' choices (unit -> best params; a unit without a
        completed trial keeps the config's own settings)."""
        from optuna.trial import FixedTrial  # (b) Optuna: not for evaluate

        for unit, targets in self.units(ds.target_names).items():
            params = best.get(unit)
            if params is not None:
                cfg = self.with_trial(cfg, FixedTrial(params), targets)
        return cfg

    def final_model(self, cfg: ExperimentConfig, ds: Dataset):
        """The unfitted model a sweep refits on all training rows (``cfg`` holds its
        choices, from :meth:`chosen_config`)."""
        return self.build(cfg, ds)

    # ------------------------------------------------------------------ design
    def design_problem(self, model, X: pd.DataFrame, Y: pd.DataFrame,
                       candidates: pd.DataFrame, random_state: int | None = None
                       ) -> DesignProblem:
        """What the ``model`` fitted on ``X``, ``Y`` does not know at the ``candidates``
        (frames of :meth:`inputs`' columns), for ``workbench design``.

        Default: the spread of :data:`DESIGN_FOLDS` fold models (the fitted model's choices
        kept, :meth:`fixed_choices`, each refitted without one fold of the rows), with each
        target's noise sd the robust sd of the fold models' out-of-fold residuals
        (:func:`~workbench.design.ensemble_blocks`)."""
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

    # ------------------------------------------------------------------ results
    def selected(self, model, targets: list[str]) -> list[str]:
        """What the fitted model chose per target (default: its ``selected_`` or "model")."""
        return list(getattr(model, "selected_", ["model"] * len(targets)))

    def scores(self, ds: Dataset, model, Y_train: pd.DataFrame,
               prior_test, y_test, pred) -> tuple[Scores, ModelScores, dict[str, Any]]:
        """Prior and model scores of a fitted model, and the family's JSON-ready details.

        Default: no CV inside the model, so the prior's CV error is its training error (it
        is not fitted) and the model's CV error is unknown (NaN) unless ``[evaluation]``
        asks for a repeated CV."""
        prior_train = ds.prior.loc[Y_train.index].to_numpy()
        nan = [float("nan")] * len(ds.target_names)
        prior = Scores(test_mae=mae(y_test, prior_test), test_mse=mse(y_test, prior_test),
                       cv_mae=mae(Y_train, prior_train), cv_mse=mse(Y_train, prior_train))
        scores = ModelScores(test_mae=mae(y_test, pred), test_mse=mse(y_test, pred),
                             cv_mae=list(nan), cv_mse=list(nan),
                             selected=self.selected(model, ds.target_names))
        return prior, scores, {}

    def begin_artifacts(self, cfg: ExperimentConfig, ds: Dataset, model, setting: str,
                        quick: bool = False) -> Callable[..., Artifacts]:
        """The figures and tables logged with a run (beside the MAE/MSE bars every run has).

        In two halves: start what can run on the worker processes (e.g. learning-curve
        fits) and return a function ``finish(emit=None)`` that waits for it, draws the
        figures and returns the :class:`Artifacts`, so the run's other records are written
        meanwhile. ``emit(name, figure)``, if given, receives every figure as soon as it is
        drawn (e.g. to log it while later ones are computed).

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
            ``finish(emit=None) -> Artifacts``. Default: nothing started; ``finish``
            returns :meth:`outputs` (or nothing).
        """
        def finish(emit=None) -> Artifacts:
            out = self.outputs(model, ds, setting) or Artifacts()
            for name, fig in out.figures.items():
                if emit is not None:
                    emit(name, fig)
            return out

        return finish

    def outputs(self, model, ds: Dataset, setting: str) -> Artifacts | None:
        """What ``evaluate --out DIR`` writes (``None``: the family writes nothing)."""
        return None
