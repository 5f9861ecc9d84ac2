"""Family ``hamiltonian``: boosting in the Hamiltonian's parameter space.

One model predicts every target: the parameter-space model
(:class:`~workbench.param_regressor.HamiltonianParameterRegressor`, with covariates chosen by
:class:`~workbench.param_select.HamiltonianSelectionCV`) corrects the control model's qubit
frequencies and couplings and re-diagonalises; an eigenvalue-space boosting stage on top
(``[model]`` keys, one BaseBoostCV per target, trained on out-of-fold priors) is kept per target
only where CV says it helps (:class:`~workbench.fitted_prior.FittedPriorBoost`). Its settings
are ``[model.hamiltonian]`` (:class:`HamiltonianSettings`); a sweep varies them through
``[search.hamiltonian]``, one study over all targets.

What the model learned is written as tables and figures:

* ``coefficients``: the selected covariates and coefficients per Hamiltonian parameter
  (in the targets' unit per standard deviation of the covariate, and that standard
  deviation);
* ``corrected_parameters``: per experiment, each parameter's control-model value, corrected
  value and correction, and whether the row is a training or a test row;
* ``selection_path``: the forward selection's CV MAE after each added covariate;

with the figures of :mod:`~workbench.experiment.families.hamiltonian_figures` (``evaluate
--out DIR``, and the MLflow run's artifacts).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, cast

import pandas as pd
from pydantic import Field
from sklearn.base import clone
from sklearn.model_selection import KFold

from ...design import DesignProblem, drift_problem
from ...fitted_prior import FittedPriorBoost
from ...param_boost import default_library
from ...param_regressor import HamiltonianParameterRegressor
from ...param_select import HamiltonianSelectionCV, candidate_pool
from ..config.schema import ParameterOf, Section
from ..process.errors import ConfigError
from ..scoring.scores import ModelScores, Scores, mae, mse
from .artifacts import Artifacts
from .base import ModelFamily, showing_progress
from .hamiltonian_figures import parameter_corrections, selection_path_figure
from .stage import per_target_boost, stage_scores

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import DataConfig, ExperimentConfig

__all__ = ["PRIOR_PREFIX", "HamiltonianFamily", "HamiltonianSettings", "make_hamiltonian",
           "physics_regressor"]

#: Prefix of the columns holding the parameter-space model's prediction (the boosting stage's
#: prior and basis inputs).
PRIOR_PREFIX = "prior_"


#: Keys whose values the parameter-space model's (the selection's) constraints check.
_Regressor = ParameterOf(HamiltonianParameterRegressor)
_Selection = ParameterOf(HamiltonianSelectionCV)


class HamiltonianSettings(Section):
    """``[model.hamiltonian]``: the parameter-space model's settings.

    ``start``: covariates every model has ("default": the default library, "none":
    intercepts only); ``candidates``: the pool ("physical": with neighbours,
    "local": without, "none"); ``selection``: "forward" (forward selection by CV from start
    over the pool, every candidate refitted), "linearised" (the same, candidates scored by one
    Gauss-Newton step: scales to large devices) or "none" (start and pool together,
    regularised by alpha / alpha_l1).

    ``loss``, ``huber_delta``, ``alpha``, ``alpha_l1`` and ``max_iter`` are
    HamiltonianParameterRegressor's parameters; ``selection_cv`` (its ``cv``),
    ``selection_repeats`` (``n_repeats``), ``max_steps`` and ``min_improvement``
    HamiltonianSelectionCV's: their values are checked against the estimators'
    ``_parameter_constraints``. The ``le`` caps are the config's own, declared by no
    estimator: they keep a typo (a million folds, repeats, iterations or steps, each more
    fits) from running for days.
    """

    loss: Annotated[str, _Regressor] = "huber"
    huber_delta: Annotated[float, _Regressor] = 0.5
    alpha: Annotated[float, _Regressor] = 1.0
    alpha_l1: Annotated[float, _Regressor] = 0.0
    max_iter: Annotated[int, _Regressor] = Field(default=20, le=100_000)
    start: Literal["default", "none"] = "default"
    candidates: Literal["physical", "local", "none"] = "physical"
    selection: Literal["forward", "linearised", "none"] = "forward"
    selection_cv: Annotated[int, ParameterOf(HamiltonianSelectionCV, "cv")] = Field(
        default=5, le=10_000)
    selection_repeats: Annotated[int, ParameterOf(HamiltonianSelectionCV, "n_repeats")] = Field(
        default=1, le=1000)
    max_steps: Annotated[int, _Selection] = Field(default=20, le=100_000)
    min_improvement: Annotated[float, _Selection] = 1e-3
    boost_stage: bool = True
    prior_cv: int = Field(default=5, ge=2, le=10_000)
    #: Keep, per target, the control model's prediction where the corrected Hamiltonian does
    #: not beat it in out-of-fold CV on the training rows.
    fallback: bool = False
    #: Couplings the control model lacks, offered to the selection (starting at zero):
    #: "next_nearest" (along a chain or ring), "diagonal" (a grid's), or site pairs.
    parasitic: Literal["none", "next_nearest", "diagonal"] | list[list[int]] = "none"
    #: Offer bias crosstalk terms to the selection (products of a parameter's own bias with
    #: the neighbouring bias lines; see workbench.param_select.candidate_pool).
    crosstalk: bool = False


def make_hamiltonian(settings: HamiltonianSettings, ds: Dataset, *,
                     random_state: int | None = None, n_jobs: int | None = None,
                     verbose: bool = False
                     ) -> HamiltonianParameterRegressor | HamiltonianSelectionCV:
    """Make the parameter-space model that ``[model.hamiltonian]`` describes.

    Parameters
    ----------
    settings : HamiltonianSettings
        ``[model.hamiltonian]``.
    ds : Dataset
        The dataset (its Hamiltonian columns).
    random_state : int, optional
        Seeds the selection's folds.
    n_jobs : int, optional
        The selection's processes.
    verbose : bool, default=False
        The selection reports a line per step (the ``workbench`` logger).

    Returns
    -------
    HamiltonianSelectionCV or HamiltonianParameterRegressor
        A :class:`HamiltonianSelectionCV` (``selection = "forward"`` or ``"linearised"``),
        or a :class:`HamiltonianParameterRegressor` with the start and pool covariates
        together (``selection = "none"``); unfitted.

    Raises
    ------
    ConfigError
        For a dataset without Hamiltonian parameters.
    """
    ham = ds.hamiltonian
    if ham is None:
        raise ConfigError(f"family = \"hamiltonian\" needs a dataset with Hamiltonian "
                          f"parameters; {ds.name!r} has none")
    s = settings
    on, co = list(ham.onsite.columns), list(ham.couplings.columns)
    edges = ham.edge_list
    parasitic = None if s.parasitic == "none" else s.parasitic
    graph: dict[str, Any] = dict(edges=edges, parasitic=parasitic)
    common: dict[str, Any] = dict(onsite=on, couplings=co, sign=ham.sign, loss=s.loss,
                                  huber_delta=float(s.huber_delta), alpha=float(s.alpha),
                                  alpha_l1=float(s.alpha_l1), max_iter=s.max_iter, **graph)
    # parasitic couplings enter through the pool only, so CV decides whether they are kept
    start = default_library(on, co, edges) if s.start == "default" else {}
    pool: dict[str, list[str]]
    if s.candidates == "none":
        pool = {}
    else:
        pool = candidate_pool(on, co, ham.qubit_features, ham.coupler_features, base=None,
                              neighbours=s.candidates == "physical",
                              crosstalk=s.crosstalk, **graph)
    if s.selection == "none":
        names = list(dict.fromkeys([*on, *co, *start, *pool]))
        merged = {p: list(dict.fromkeys(start.get(p, []) + pool.get(p, []))) for p in names}
        return HamiltonianParameterRegressor(covariates=merged, **common)
    return HamiltonianSelectionCV(HamiltonianParameterRegressor(**common), candidates=pool,
                                  start=start or None, cv=s.selection_cv,
                                  n_repeats=s.selection_repeats, max_steps=s.max_steps,
                                  min_improvement=float(s.min_improvement),
                                  method="linearised" if s.selection == "linearised" else "refit",
                                  random_state=random_state, n_jobs=n_jobs, verbose=verbose)


def physics_regressor(model: Any) -> HamiltonianParameterRegressor:
    """Return the fitted parameter-space regressor inside a fitted family-hamiltonian model.

    Parameters
    ----------
    model : FittedPriorBoost
        The family's fitted model.

    Returns
    -------
    HamiltonianParameterRegressor
        Its physics model (after its covariate selection, if any).
    """
    physics = model.physics_
    return getattr(physics, "estimator_", physics)


def _records(table: pd.DataFrame) -> list[dict[str, Any]]:
    """Rows as JSON-ready dicts (NaN -> None)."""
    return table.astype(object).where(table.notna(), None).to_dict(orient="records")


class HamiltonianFamily(ModelFamily):
    """The parameter-space model, with an eigenvalue-space boosting stage on top."""

    name = "hamiltonian"
    settings: ClassVar = HamiltonianSettings
    interval_method = "oof"  # FittedPriorBoost keeps its out-of-fold predictions

    def check_data(self, data: DataConfig) -> None:
        """Require the prior and ``[data.hamiltonian]`` for a CSV."""
        super().check_data(data)
        if data.order_column is not None:  # prior_cv, selection_cv: shuffled K-fold
            raise ValueError(f"[data] order_column = {data.order_column!r}: family = "
                             f"\"hamiltonian\" fits its physics model on shuffled folds of "
                             f"its own and cannot chain them forward; remove order_column "
                             f"(a split_column can still test on the latest rows)")
        if data.source == "csv" and data.hamiltonian is None:
            raise ValueError("family = \"hamiltonian\" needs the Hamiltonian's columns in "
                             "[data.hamiltonian] (onsite, couplings)")

    def inputs(self, cfg: ExperimentConfig, ds: Dataset) -> pd.DataFrame:
        """Return the physics model's inputs (``ds.X_physics``)."""
        return ds.X_physics

    def build(self, cfg: ExperimentConfig, ds: Dataset) -> FittedPriorBoost:
        """Build a :class:`FittedPriorBoost` over :func:`make_hamiltonian`.

        Its per-target stage is BaseBoostCV, boosting from the physics model's prediction
        (columns ``prior_<target>``). Both report their progress where the ``workbench``
        logger shows INFO lines, except in a sweep's trials
        (:func:`~.base.showing_progress`).
        """
        h = cast(HamiltonianSettings, cfg.family_settings)  # validated by `settings`
        priors = [f"{PRIOR_PREFIX}{t}" for t in ds.target_names]
        boost = per_target_boost(cfg, ds, priors, boost_from_prior=False)
        physics = make_hamiltonian(h, ds, random_state=cfg.random_state, n_jobs=cfg.n_jobs,
                                   verbose=showing_progress())
        return FittedPriorBoost(physics, boost, prior_prefix=PRIOR_PREFIX,
                                cv=KFold(h.prior_cv, shuffle=True,
                                         random_state=cfg.random_state or 0),
                                boost_stage=h.boost_stage,
                                fallback=list(ds.prior_names) if h.fallback else None,
                                cv_predictions=self._needs_oof(cfg), n_jobs=cfg.jobs,
                                verbose=showing_progress())

    @staticmethod
    def _needs_oof(cfg: ExperimentConfig) -> bool:
        """Tell whether the model without a stage must keep its out-of-fold predictions.

        Only out-of-fold prediction intervals need them. Its CV MAE comes from them, so
        without a stage or such intervals the model's CV MAE is NaN rather than paid for
        with ``prior_cv`` refits; ``[evaluation] cv_repeats`` estimates it when asked.
        """
        return cfg.intervals.enabled and cfg.intervals.method == "oof"

    def fixed_choices(self, model: Any) -> Any:
        """Keep the selected covariates (refitting the selection would remake it); no
        progress lines."""
        selection = getattr(model.physics_, "selection_", None)
        if selection is not None:
            return clone(model).set_params(physics=selection.estimator(), verbose=False)
        return clone(model).set_params(verbose=False)

    def selected(self, model: Any, targets: list[str]) -> list[str]:
        """Label per target "hamiltonian", or "hamiltonian+boosted" where the stage was kept.

        "hamiltonian+<basis>" when the stage chose its basis among several by CV; "control"
        where the control model's prediction was kept (``fallback``).
        """
        stages = model.boost_.estimators_ if model.boost_stage else [None] * len(targets)
        base = ["hamiltonian" if p else "control" for p in model.physics_selected_]
        return [f"{b}+{getattr(e, 'selected_candidate_', None) or 'boosted'}"
                if s == "boosted" else b for b, s, e in zip(base, model.selected_, stages)]

    def scores(self, ds: Dataset, model: Any, Y_train: pd.DataFrame, prior_test: Any,
               y_test: Any, pred: Any) -> tuple[Scores, ModelScores, dict[str, Any]]:
        """Score prior and model, with the parameter-space model's details.

        ``model.cv_mae``: the boosting stage's CV (NaN without a stage; the repeated CV of
        ``[evaluation]`` replaces it when asked); ``cv_mae_hamiltonian``: the parameter-space
        model's out-of-fold CV MAE.
        """
        prior_train = ds.prior.loc[Y_train.index].to_numpy()
        nan = [float("nan")] * len(ds.target_names)
        Y = Y_train.to_numpy(dtype=float)
        staged = model.boost_stage
        s: dict[str, list[Any]] = stage_scores(model.boost_.estimators_, Y) if staged else {}
        prior = Scores(test_mae=mae(y_test, prior_test), test_mse=mse(y_test, prior_test),
                       cv_mae=mae(Y_train, prior_train),  # no fit: CV MAE = training MAE
                       cv_mse=mse(Y_train, prior_train))
        stage_cv = s["prior_cv_mae"] if staged else nan
        scores = ModelScores(test_mae=mae(y_test, pred), test_mse=mse(y_test, pred),
                             cv_mae=s["cv_mae"] if staged else stage_cv,
                             cv_mse=s["cv_mse"] if staged else nan,
                             selected=self.selected(model, ds.target_names),
                             coefs=s["coefs"] if staged else [[] for _ in nan],
                             extra={"cv_mae_hamiltonian": stage_cv})
        regressor = physics_regressor(model)
        ham: dict[str, Any] = {"covariates": regressor.covariate_names_,
                               "coefficients": _records(regressor.coefficient_table()),
                               "n_iter": regressor.n_iter_}
        physics = model.physics_
        selection = getattr(physics, "selection_", None)
        if selection is not None:
            ham["selection"] = {"cv_mae": selection.cv_mae, "steps": len(selection.path) - 1,
                                "folds": physics.cv, "repeats": physics.n_repeats,
                                "path": _records(selection.path),
                                "seconds": selection.seconds}
        return prior, scores, {"hamiltonian": ham}

    def design_problem(self, model: Any, X: pd.DataFrame, Y: pd.DataFrame,
                       candidates: pd.DataFrame, random_state: int | None = None
                       ) -> DesignProblem:
        """Give the Fisher information of the parameter-space model's correction coefficients.

        Gauss-Newton: the Hellmann-Feynman Jacobian of the eigenvalues times the covariates,
        :meth:`~workbench.param_regressor.HamiltonianParameterRegressor.coef_jacobian`, plus the
        ridge penalty as the coefficients' prior; one noise sd for every eigenvalue: the
        robust sd of the model's training residuals.

        The coefficients are those of every covariate the selection could choose, not only
        the chosen ones (at the fitted model, the others at 0; DuMouchel and Jones's
        "potential terms"): a design for the chosen covariates alone piles its points where
        they have leverage and starves the terms the selection has not taken yet. The
        boosting stage on top is not part of it.
        """
        regressor = physics_regressor(model)
        pool = getattr(model.physics_, "candidates", None) or {}
        return drift_problem(regressor, pool, X, Y, candidates,
                             "the Hamiltonian the selection could use", features=None)

    def outputs(self, model: Any, ds: Dataset, setting: str | None = None) -> Artifacts:
        """Make the tables and figures of a fitted model.

        They come from one computation of the corrected parameters of every experiment.
        Every table is written without its index (the corrected parameters carry the
        experiment label in the column ``experiment``).
        """
        regressor = physics_regressor(model)
        X = ds.X_physics
        names = regressor.parameter_names_
        control = regressor.control_parameters(X)  # parasitic couplings: 0 in the control
        corrected = regressor.corrected_parameters(X)
        split = pd.Series("test", index=X.index, name="split")
        split.loc[ds.train_index] = "train"
        columns = {"experiment": pd.Series(X.index, index=X.index), "split": split}
        for p in names:
            columns[f"{p}_control"] = control[p]
            columns[f"{p}_corrected"] = corrected[p]
            columns[f"{p}_correction"] = corrected[p] - control[p]
        out = Artifacts(tables={"coefficients": regressor.coefficient_table(),
                                "corrected_parameters": pd.DataFrame(columns)})
        out.figures["parameter_corrections"] = parameter_corrections(
            control, corrected, groups={"training rows": ds.train_index,
                                        "test rows": ds.test_index}, unit=ds.unit,
            setting=setting)
        selection = getattr(model.physics_, "selection_", None)
        if selection is not None:
            out.tables["selection_path"] = selection.path
            out.figures["selection_path"] = selection_path_figure(
                selection.path, title=f"Forward covariate selection ({selection.n_rows} "
                                      "training rows, CV MAE over all targets)", unit=ds.unit,
                setting=setting)
        return out
