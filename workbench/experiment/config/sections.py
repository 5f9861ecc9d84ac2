"""The sections of a config besides ``[data]``.

The boosting settings (``[model]``, ``[model.targets.<target>]``), ``[selection]``,
``[evaluation]``, ``[intervals]``, ``[cv]``, ``[study]``, ``[tracking]``, and the top level
that holds them (:class:`TopLevel`).
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, model_validator
from sklearn.metrics import get_scorer_names

from ...boosting import BaseBoostRegressor
from ...conformal import ConformalRegressor
from ...selection import BasisChoiceCV
from ..process.errors import shorten
from .schema import MAX_INT, ParameterOf, Section, Seed

__all__ = ["MODEL_DEFAULTS", "BoostSettings", "CVConfig", "EvaluationConfig", "IntervalsConfig",
           "ModelConfig", "SelectionConfig", "StudyConfig", "TopLevel", "TrackingConfig"]

#: A key whose value :class:`~workbench.BaseBoostRegressor`'s constraints check.
_Boost = ParameterOf(BaseBoostRegressor)


class BoostSettings(Section):
    """The eigenvalue-space boosting settings of one target.

    ``[model]``, or a ``[model.targets.<target>]`` override, where every key is optional: a
    key not given takes ``[model]``'s value, else the default of :data:`MODEL_DEFAULTS`
    (:meth:`~workbench.experiment.config.ExperimentConfig.model_for` merges them).
    ``n_stages``, ``loss``, ``line_search_loss``, ``line_search_penalty``, ``alpha``,
    ``link`` and ``out_of_bounds`` are BaseBoostRegressor's parameters, checked against its
    ``_parameter_constraints``; a list of bases, losses, line-search losses, links or input
    transforms makes candidates that CV chooses among per target (``[selection]``).

    Parameters
    ----------
    basis : str or list of str, default=None
        The regressor each boosting stage fits to the residuals, a name in
        :data:`workbench.bases.BASES` (e.g. ``"paper_stacking"``, ``"ridge"``,
        ``"lightgbm"``); a list: candidates.
    basis_params : dict, default=None
        The basis's parameters (with a list of bases, one table per basis of the list). A
        value given as a range ``{ low, high, log }`` or a choice ``{ choices = [...] }``
        makes ``draws`` settings drawn at random, each a candidate.
    n_stages : int, default=None
        The boosting stages ``K``.
    loss : str or list of str, default=None
        The loss whose negative gradient each stage fits, a name in
        :data:`workbench.losses.LOSSES` (e.g. ``"squared_error"``, ``"huber"``); a list:
        candidates.
    line_search_loss : str or list of str, default=None
        The loss of the line search that sets each stage's coefficient (a name in
        :data:`workbench.losses.LOSSES`); a list: candidates.
    line_search_penalty : float, default=None
        The L1 penalty on each stage's coefficient in the line search (0: none).
    alpha : float, default=None
        Huber's quantile for its ``delta``, and the quantile loss's level.
    link : str or list of str, default=None
        How the stages combine with the prior: ``"identity"`` adds them to it, ``"log"``
        multiplies it by them (targets and prior positive); a list: candidates.
    out_of_bounds : str, default=None
        ``"extrapolate"``: a new row gets the correction the stages predict; ``"clip"``: it
        stays within the range the correction took on the training rows.
    basis_inputs : {"prior", "prior+features"}, default=None
        What the basis sees: the prior alone, or the prior and the dataset's features.
    input_transform : str or list of str, default=None
        The transform of the basis's inputs (never of the prior term), a name in
        :data:`workbench.bases.TRANSFORMS` or ``"none"``; a list: candidates.
    input_transform_params : dict, default=None
        The transform's parameters.
    draws : int, default=None
        How many settings are drawn for a basis whose ``basis_params`` hold ranges.
    tune : {"draws", "halving"}, default=None
        What those drawn settings become: ``"draws"``, each a candidate of CV; ``"halving"``,
        one candidate per basis (and link, loss, transform) that chooses among them by
        successive halving on 3 folds of the rows each of its fits sees
        (:class:`~workbench.halving.HalvingChoiceCV`): fewer, tuned candidates.
    """

    basis: str | list[str] | None = None
    basis_params: dict[str, Any] | None = None
    # le: a cap no estimator declares (each stage fits the basis once more): a typo such as
    # 1e6 stages is refused at load instead of running for days
    n_stages: Annotated[int, _Boost] | None = Field(default=None, le=10_000)
    loss: Annotated[str, _Boost] | list[Annotated[str, _Boost]] | None = None
    line_search_loss: Annotated[str, _Boost] | list[Annotated[str, _Boost]] | None = None
    line_search_penalty: Annotated[float, _Boost] | None = None
    alpha: Annotated[float, _Boost] | None = None
    # "identity": the stages add to the prior; "log": they multiply it (positive quantities)
    link: Annotated[str, _Boost] | list[Annotated[str, _Boost]] | None = None
    # "clip": a new row's correction stays within the range it took on the training rows
    out_of_bounds: Annotated[str, _Boost] | None = None
    basis_inputs: Literal["prior", "prior+features"] | None = None
    # a list: candidates that CV chooses among per target
    input_transform: str | list[str] | None = None
    input_transform_params: dict[str, Any] | None = None
    # how many settings are drawn for a basis whose basis_params hold ranges
    draws: int | None = Field(default=None, ge=1, le=10_000)
    # "halving": the draws race inside each fit, and the winner is one candidate
    tune: Literal["draws", "halving"] | None = None


#: ``[model]`` defaults (the paper's settings).
MODEL_DEFAULTS: dict[str, Any] = dict(
    basis="paper_stacking", basis_params={}, n_stages=1, loss="squared_error", draws=20,
    line_search_loss="absolute_error", line_search_penalty=0.1, alpha=0.9, link="identity",
    out_of_bounds="extrapolate", basis_inputs="prior", input_transform="quantile_normal",
    input_transform_params={}, tune="draws",
)


class ModelConfig(BoostSettings):
    """``[model]``: the family, the boosting settings shared by every target, and overrides.

    A boosting key left out takes its default from :data:`MODEL_DEFAULTS` (the paper's
    settings).

    Parameters
    ----------
    family : str, default="eigenvalue"
        The model family, a name in :data:`~workbench.experiment.families.FAMILIES` (its own
        settings: ``[model.<family>]``).
    targets : dict of str to BoostSettings, default={}
        Per target, the boosting settings that override these (``[model.targets.<target>]``).
    basis, basis_params, n_stages, loss, line_search_loss, line_search_penalty, alpha, link
        As in :class:`BoostSettings`, for every target.
    out_of_bounds, basis_inputs, input_transform, input_transform_params, draws, tune
        As in :class:`BoostSettings`, for every target.
    """

    family: str = "eigenvalue"
    targets: dict[str, BoostSettings] = {}


class SelectionConfig(Section):
    """``[selection]``: BaseBoostCV's folds and scoring.

    The CV on the training rows that makes every choice of the model: the prior or the
    boosted model per target, and among candidates. The folds follow the data: with
    ``[data] order_column`` (dates, times, run numbers) they chain forward, each training on
    the rows before the ones it holds out (scikit-learn's ``TimeSeriesSplit``, rows of one
    value on one side); with groups, each group is held out whole; else K-fold.

    Parameters
    ----------
    cv : int, default=5
        The folds.
    shuffle : bool, default=False
        Shuffle the rows (or groups) before making the folds (seeded by ``random_state``;
        else the folds are contiguous). Forward-chaining folds are never shuffled.
    scoring : str, default="neg_mean_absolute_error"
        What the choices maximise, a scikit-learn scorer's name
        (``sklearn.metrics.get_scorer_names()``).
    groups : bool, default=True
        When the dataset has groups (e.g. each row's device), keep each group's rows in one
        fold; ``false``: split them like any rows.
    ensemble : int, default=1
        With candidates: the mean of this many best candidates is a candidate too
        (:class:`~workbench.selection.BasisChoiceCV`; 1: none).
    rule : str, default="best"
        How CV chooses among the prior, the candidates (simplest first: the bases as listed,
        the identity link before the others, smaller tree ensembles first) and their mean.
        ``"best"``: the best mean CV score. ``"one_se"``: the one-standard-error rule, the
        simplest within one standard error of the paired fold differences from the best
        (the prior first), so the prior, the identity link or a simpler basis is kept unless
        CV tells the gain from noise. ``"prior_se"``: the prior unless the best beats it by
        more than one standard error of their paired fold differences, else the best.
    """

    cv: int = Field(default=5, ge=2, le=10_000)
    shuffle: bool = False
    scoring: str = "neg_mean_absolute_error"
    groups: bool = True  # whole groups per fold when the dataset has groups (e.g. devices)
    ensemble: int = Field(default=1, ge=1, le=1_000)
    # "one_se": the simplest model within one standard error of the best (BasisChoiceCV)
    rule: Annotated[str, ParameterOf(BasisChoiceCV)] = "best"

    @model_validator(mode="after")
    def _scorer(self) -> SelectionConfig:
        if self.scoring not in get_scorer_names():
            raise ValueError(f"scoring = {shorten(self.scoring)}: unknown scorer; see "
                             "sklearn.metrics.get_scorer_names(), e.g. "
                             "'neg_mean_absolute_error'")
        return self


class EvaluationConfig(Section):
    """``[evaluation]``: the extra estimates of the chosen model's error.

    Each beside the test error that ``evaluate`` always reports; all off by default.

    Parameters
    ----------
    cv_folds : int, default=5
        The folds of the repeated CV.
    cv_repeats : int, default=0
        Repeats of a ``cv_folds``-fold CV of the chosen model on the training rows
        (``RepeatedKFold``; 0: none).
    cv_seed : int, default=1000
        Seeds the repeated CV's folds (a fixed draw: not the model's ``random_state``).
    nested_folds : int, default=0
        The outer folds of a nested CV over all rows, training and test, every choice of the
        model remade inside each (0: none; else 2 or more).
    nested_seed : int, default=0
        Seeds the nested CV's outer folds (a fixed draw).
    random_states : list of int, default=[]
        Two or more distinct values of the top-level ``random_state``: ``evaluate`` fits the
        config once with each (the data, their split and the CV folds stay), and reports the
        mean and sd of the test MAE over them (:mod:`workbench.experiment.runs.seeds`;
        ``--random-states`` overrides it; empty: one fit with ``random_state``). Formerly
        ``seeds``.
    """

    cv_folds: int = Field(default=5, ge=2, le=10_000)
    cv_repeats: int = Field(default=0, ge=0, le=10_000)
    cv_seed: int = Field(default=1000, ge=0, le=MAX_INT)
    nested_folds: int = Field(default=0, ge=0, le=10_000)
    nested_seed: int = Seed()
    # max_length: a cap of its own (each seed is one more fit of the whole model)
    random_states: list[Annotated[int, Field(ge=0, le=MAX_INT)]] = Field(default=[],
                                                                         max_length=1000)
    renamed: ClassVar[dict[str, str]] = {"seeds": "random_states"}

    @model_validator(mode="after")
    def _nested(self) -> EvaluationConfig:
        if self.nested_folds == 1:
            raise ValueError("nested_folds = 1: give 0 (off) or >= 2 folds")
        return self

    @model_validator(mode="after")
    def _random_states(self) -> EvaluationConfig:
        states = self.random_states
        if len(states) == 1:
            raise ValueError(f"random_states = {states}: give two or more to compare (one: "
                             "random_state), or none")
        if len(set(states)) != len(states):
            raise ValueError(f"random_states = {shorten(states)}: a value given twice")
        return self


#: A key whose value :class:`~workbench.conformal.ConformalRegressor`'s constraints check.
_Conformal = ParameterOf(ConformalRegressor)


class IntervalsConfig(Section):
    """``[intervals]``: conformal prediction intervals around the fitted model.

    A :class:`~workbench.conformal.ConformalRegressor` of level ``1 - alpha`` per target.
    ``alpha``, ``method``, ``cv`` and ``calibration_fraction`` are ConformalRegressor's
    parameters, checked against its ``_parameter_constraints``.

    Parameters
    ----------
    enabled : bool, default=True
        Make the intervals (``false``: none, as ``--no-intervals``).
    alpha : float, default=0.1
        The miscoverage: the intervals aim to hold a share ``1 - alpha`` of new rows.
    method : str, default=None
        How the intervals are calibrated. ``"oof"`` takes the out-of-fold residuals of the
        CV the model already ran to make its choices and centres ``+- q`` on the model
        fitted on all rows: no extra fit (``cv`` unused: the model's own folds count).
        ``"cv_plus"`` refits the whole model (every choice remade) once per ``cv`` fold;
        ``"cv"`` uses the same refits but centres ``+- q`` on the model fitted on all rows
        (not widened by the fold models' disagreement); ``"split"`` holds out
        ``calibration_fraction`` of the training rows. Not given: the family's default
        (:attr:`~workbench.experiment.families.base.ModelFamily.interval_method`: ``"oof"``
        for a family whose model cross-validates itself, else ``"cv_plus"``).
    cv : int, default=5
        The folds of ``"cv_plus"`` and ``"cv"``.
    calibration_fraction : float, default=0.25
        The share of the training rows ``"split"`` holds out to calibrate on.
    """

    enabled: bool = True
    alpha: Annotated[float, _Conformal] = 0.1
    method: Annotated[str, _Conformal] | None = None
    # le: a cap ConformalRegressor does not declare (each fold refits the whole model)
    cv: Annotated[int, _Conformal] = Field(default=5, le=10_000)
    calibration_fraction: Annotated[float, _Conformal] = 0.25


class CVConfig(Section):
    """``[cv]``: the nested cross-validation of a sweep.

    With ``[data] order_column`` the outer and the inner folds chain forward in time (as
    ``[selection]``'s do; one repeat).

    Parameters
    ----------
    outer_folds, inner_folds : int, default=5
        The folds of the outer (scoring) and the inner (searching) CV.
    repeats : int, default=1
        Repeats of the outer folds (``RepeatedKFold``).
    sweep_seed : int, default=0
        Seeds the sweep's fixed draws: its outer and inner folds and each trial's sampler
        (not the model's ``random_state``). Formerly ``seed``.
    """

    outer_folds: int = Field(default=5, ge=2, le=10_000)
    inner_folds: int = Field(default=5, ge=2, le=10_000)
    repeats: int = Field(default=1, ge=1, le=1000)
    sweep_seed: int = Seed()
    renamed: ClassVar[dict[str, str]] = {"seed": "sweep_seed"}


class StudyConfig(Section):
    """``[study]``: the Optuna studies of a sweep.

    Parameters
    ----------
    trials : int, default=20
        Trials per study.
    timeout : float, default=None
        Seconds a study may search (``None``: no limit).
    sampler : {"tpe", "random"}, default="tpe"
        Optuna's sampler.
    pruner : {"none", "median", "wilcoxon"}, default="median"
        Optuna's pruner.
    storage : str, default="mlruns/optuna.journal"
        A journal file path (one machine, several processes) or an RDB URL such as
        ``postgresql://...`` (machines).
    study_name : str, default=None
        The studies' name prefix (``None``: from the config's name).
    workers : int, default=1
        Processes searching at once.
    stale_after_s : float, default=600
        A running trial without a heartbeat for this long is failed and re-queued.
    """

    trials: int = Field(default=20, ge=1, le=1_000_000)
    timeout: float | None = Field(default=None, gt=0)
    sampler: Literal["tpe", "random"] = "tpe"
    pruner: Literal["none", "median", "wilcoxon"] = "median"
    storage: str = "mlruns/optuna.journal"
    study_name: str | None = None
    workers: int = Field(default=1, ge=1, le=1024)
    stale_after_s: float = Field(default=600, gt=0)


class TrackingConfig(Section):
    """``[tracking]``: where MLflow records.

    Parameters
    ----------
    tracking_uri : str, default=None
        The tracking store (``None``: $MLFLOW_TRACKING_URI or ``sqlite:///mlruns/mlflow.db``).
    experiment : str, default=None
        The MLflow experiment (``None``: the config's name).
    """

    tracking_uri: str | None = None
    experiment: str | None = None


class TopLevel(Section):
    """The top level of a config file (sections validated on their own).

    Parameters
    ----------
    name : str, default=None
        The config's name: its runs', studies' and outputs' (``None``: the file's stem).
    description : str, default=""
        A note on what the config is for (free text).
    random_state : int, default=None
        Seeds every random component of the model: the bases, the transforms, the
        ``basis_params`` draws and shuffled folds (``None``: they are not seeded).
    n_jobs : int, default=None
        Processes for independent work (targets, folds, refits; ``-1`` or ``None``: every
        core); the results do not depend on it (``--jobs`` overrides it).
    data : dict, default={}
        ``[data]`` (:class:`~workbench.experiment.config.DataConfig`).
    model : dict, default={}
        ``[model]`` (:class:`ModelConfig`, and the family's ``[model.<family>]``).
    selection : SelectionConfig, default=SelectionConfig()
        ``[selection]``.
    evaluation : EvaluationConfig, default=EvaluationConfig()
        ``[evaluation]``.
    intervals : IntervalsConfig, default=IntervalsConfig()
        ``[intervals]``.
    search : dict, default={}
        ``[search]``: the space a sweep searches
        (:class:`~workbench.experiment.config.space.SearchSpace`).
    cv : CVConfig, default=CVConfig()
        ``[cv]``.
    study : StudyConfig, default=StudyConfig()
        ``[study]``.
    tracking : TrackingConfig, default=TrackingConfig()
        ``[tracking]``.
    """

    name: str | None = None
    description: str = ""
    random_state: int | None = Field(default=None, ge=0, le=MAX_INT)
    n_jobs: int | None = Field(default=None, ge=-1, le=1024)
    data: dict[str, Any] = {}
    model: dict[str, Any] = {}
    selection: SelectionConfig = SelectionConfig()
    evaluation: EvaluationConfig = EvaluationConfig()
    intervals: IntervalsConfig = IntervalsConfig()
    search: dict[str, Any] = {}
    cv: CVConfig = CVConfig()
    study: StudyConfig = StudyConfig()
    tracking: TrackingConfig = TrackingConfig()

    @model_validator(mode="after")
    def _jobs(self) -> TopLevel:
        if self.n_jobs == 0:
            raise ValueError("n_jobs = 0: give a number of processes >= 1, or -1 for all cores")
        return self

