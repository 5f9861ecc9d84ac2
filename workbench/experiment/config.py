"""Experiment configs (TOML files under ``experiments/``): a typed schema, read and checked.

Each section of a config is a pydantic model below: the schema *is* the documentation of
the config (see ``experiments/paper_main_body.toml`` for an annotated file)::

    name, description, random_state, n_jobs     # top level (ExperimentConfig)
    [data]         DataConfig       the benchmark, or a CSV of your own
    [data.hamiltonian]  HamiltonianData  the Hamiltonian's columns (physics-aware families)
    [model]        ModelConfig      family + the eigenvalue-space boosting settings
    [model.targets.<target>]  BoostSettings  per-target overrides
    [model.<family>]  the family's own settings (``ModelFamily.settings``)
    [selection]    SelectionConfig  BaseBoostCV's folds and scoring
    [evaluation]   EvaluationConfig extra estimates of ``evaluate``
    [intervals]    IntervalsConfig  conformal prediction intervals of the fitted model
    [search]       the space a sweep searches (:class:`~workbench.experiment.space.SearchSpace`;
                   ``[search.<family>]`` varies the family's settings)
    [cv]           CVConfig         nested CV of a sweep
    [study]        StudyConfig      the Optuna studies
    [tracking]     TrackingConfig   MLflow

Loading validates every value before anything is fitted: a bad one raises
:class:`ConfigError` with one line naming the file, ``section.key``, the value (shortened)
and what is allowed. A section checks structure and the config's own values; a key that is
an estimator's parameter (``ParameterOf``: the boosting settings are
:class:`~workbench.BaseBoostRegressor`'s, ``[intervals]``
:class:`~workbench.conformal.ConformalRegressor`'s) and the basis hyperparameters are
checked against that estimator's own ``_parameter_constraints`` (scikit-learn's machinery).
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from numbers import Integral, Real
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field, ValidationError, model_validator
from sklearn.base import BaseEstimator
from sklearn.metrics import get_scorer_names
from sklearn.utils._param_validation import Interval, StrOptions, validate_parameter_constraints

from ..bases import BASES, TRANSFORMS, make_basis, make_transform
from ..boosting import BaseBoostRegressor
from ..conformal import ConformalRegressor, min_calibration_rows
from ..datasets import DatasetError, load_csv_dataset, load_google_5q, load_ibm_gates
from ..hamiltonian import make_graph
from .errors import ConfigError, listing, shorten
from .families import FAMILIES, get_family
from .schema import MAX_INT, MAX_MESSAGE, ParameterOf, Section, Seed
from .space import SearchSpace, SpaceError, check_ranges, has_ranges

__all__ = ["BoostSettings", "CVConfig", "ConfigError", "DataConfig", "EvaluationConfig",
           "ExperimentConfig", "HamiltonianData", "IntervalsConfig", "ModelConfig",
           "SelectionConfig",
           "StudyConfig", "TrackingConfig", "load_config", "load_dataset", "parse_config"]

# --------------------------------------------------------------------------- [data]

class HamiltonianData(Section):
    """``[data.hamiltonian]``: the Hamiltonian's columns. ``sign``: the prior is the sorted
    eigenvalues of ``sign * H``. The coupling graph: ``topology`` "chain" (N - 1 couplings
    ``(i, i+1)``), "ring", "grid" with ``shape = [rows, cols]``, or an explicit ``edges``
    list of 0-based site pairs, one per coupling column.
    ``qubit_features``/``coupler_features``: the features acting on each site and on each
    coupling, in site and edge order."""

    onsite: list[str]
    couplings: list[str]
    sign: Literal[-1, 1] = -1
    topology: Literal["chain", "ring", "grid"] = "chain"
    shape: list[int] | None = None
    edges: list[list[int]] | None = None
    qubit_features: list[str] | None = None
    coupler_features: list[str] | None = None

    @model_validator(mode="after")
    def _graph(self) -> HamiltonianData:
        if self.shape is not None and self.topology != "grid":
            raise ValueError(f"shape applies to topology = \"grid\" only (topology is "
                             f"{self.topology!r})")
        if self.edges is not None and self.topology != "chain":
            raise ValueError("give either topology (with shape) or edges, not both")
        try:
            graph = make_graph(len(self.onsite), self.topology,
                               None if self.shape is None else tuple(self.shape), self.edges)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"coupling graph: {exc}") from None
        if len(self.couplings) != graph.n_edges:
            raise ValueError(f"couplings: the {graph.topology} graph of {len(self.onsite)} "
                             f"sites has {graph.n_edges} edges, got {len(self.couplings)} "
                             f"column(s)")
        return self


class DataConfig(Section):
    """``[data]``: ``source = "google_5q"`` (optional ``data_dir``), ``source = "ibm_gates"``
    (optional ``data_dir``, ``split = "time"`` or ``"devices"`` with ``split_seed``), or a CSV
    of your own (``csv``, one ``prior`` column per ``targets`` column, ``features``, either
    ``test_fraction`` or ``split_column``, and optionally the targets' ``unit``)."""

    source: Literal["google_5q", "ibm_gates", "csv"] = "google_5q"
    split: Literal["time", "devices"] | None = None
    data_dir: str | None = None
    csv: str | None = None
    prior: list[str] | None = None
    targets: list[str] | None = None
    features: list[str] = []
    test_fraction: float | None = Field(default=None, gt=0, lt=1)
    split_column: str | None = None
    split_seed: int = Seed()
    group_column: str | None = None
    unit: str | None = None
    hamiltonian: HamiltonianData | None = None

    @model_validator(mode="before")
    @classmethod
    def _csv_source(cls, data: Any) -> Any:
        if isinstance(data, dict) and "csv" in data and "source" not in data:
            data = {**data, "source": "csv"}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> DataConfig:
        csv_keys = sorted(k for k in ("csv", "prior", "targets", "test_fraction",
                                      "split_column", "group_column", "hamiltonian", "unit")
                          if getattr(self, k) is not None) + (["features"] if self.features
                                                              else [])
        if self.source != "csv":
            if csv_keys:
                raise ValueError(f"{csv_keys} apply to source = \"csv\" only")
            if self.split is not None and self.source != "ibm_gates":
                raise ValueError("'split' applies to source = \"ibm_gates\" only")
            return self
        if self.split is not None:
            raise ValueError("'split' applies to source = \"ibm_gates\" only (a CSV's split "
                             "is test_fraction or split_column)")
        for key in ("csv", "prior", "targets"):
            if getattr(self, key) is None:
                raise ValueError(f"source = \"csv\" needs {key!r}")
        assert self.prior is not None and self.targets is not None  # checked just above
        if len(self.prior) != len(self.targets):
            raise ValueError(f"{len(self.prior)} prior column(s) for {len(self.targets)} "
                             f"target(s): give one prior column per target")
        if (self.test_fraction is None) == (self.split_column is None):
            raise ValueError("give exactly one of test_fraction or split_column")
        return self


# --------------------------------------------------------------------------- [model]

#: A key whose value :class:`~workbench.BaseBoostRegressor`'s constraints check.
_Boost = ParameterOf(BaseBoostRegressor)


class BoostSettings(Section):
    """The eigenvalue-space boosting settings of one target (``[model]``, or a
    ``[model.targets.<target>]`` override, where every key is optional). ``n_stages``,
    ``loss``, ``line_search_loss``, ``line_search_penalty``, ``alpha`` and ``link`` are
    BaseBoostRegressor's parameters, checked against its ``_parameter_constraints``; a list
    of losses or of links makes candidates that CV chooses among per target."""

    basis: str | list[str] | None = None
    basis_params: dict[str, Any] | None = None
    # le: a cap no estimator declares (each stage fits the basis once more): a typo such as
    # 1e6 stages is refused at load instead of running for days
    n_stages: Annotated[int, _Boost] | None = Field(default=None, le=10_000)
    loss: Annotated[str, _Boost] | list[Annotated[str, _Boost]] | None = None
    line_search_loss: Annotated[str, _Boost] | None = None
    line_search_penalty: Annotated[float, _Boost] | None = None
    alpha: Annotated[float, _Boost] | None = None
    # "identity": the stages add to the prior; "log": they multiply it (positive quantities)
    link: Annotated[str, _Boost] | list[Annotated[str, _Boost]] | None = None
    basis_inputs: Literal["prior", "prior+features"] | None = None
    input_transform: str | None = None
    input_transform_params: dict[str, Any] | None = None
    # how many settings are drawn for a basis whose basis_params hold ranges
    draws: int | None = Field(default=None, ge=1, le=10_000)


#: ``[model]`` defaults (the paper's settings).
MODEL_DEFAULTS: dict[str, Any] = dict(
    basis="paper_stacking", basis_params={}, n_stages=1, loss="squared_error", draws=20,
    line_search_loss="absolute_error", line_search_penalty=0.1, alpha=0.9, link="identity",
    basis_inputs="prior", input_transform="quantile_normal", input_transform_params={},
)


class ModelConfig(BoostSettings):
    """``[model]``: the family (a name in :data:`~workbench.experiment.families.FAMILIES`),
    the boosting settings shared by every target, and per-target overrides."""

    family: str = "eigenvalue"
    targets: dict[str, BoostSettings] = {}


def check_boost_settings(settings: dict[str, Any]) -> None:
    """Resolve a target's merged settings the way a fit will (basis and transform names,
    their parameters against the estimators' own constraints, losses): ``ValueError`` with
    the offending key first."""
    for key in ("loss", "link"):
        if isinstance(settings.get(key), list):  # candidates chosen by CV per target
            values = settings[key]
            if not values or len(set(values)) != len(values):
                raise ValueError(f"{key} = {shorten(values)}: give distinct {key} names")
            for value in values:
                check_boost_settings({**settings, key: value})
            return
    if isinstance(settings["basis"], list):  # candidates chosen by CV per target
        names = settings["basis"]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"basis = {shorten(names)}: give distinct basis names")
        params = settings["basis_params"]
        extra = sorted(set(params) - set(names))
        if extra or not all(isinstance(v, dict) for v in params.values()):
            raise ValueError(f"basis_params = {shorten(params)}: with a list of bases, give "
                             f"one table per basis of the list ({names})")
        for name in names:
            check_boost_settings({**settings, "basis": name,
                                  "basis_params": params.get(name, {})})
        return
    if settings["basis"] not in BASES:
        raise ValueError(f"basis = {shorten(settings['basis'])}: unknown basis; valid: "
                         f"{sorted(BASES)}")
    if settings["input_transform"] not in ("none", *TRANSFORMS):
        raise ValueError(f"input_transform = {shorten(settings['input_transform'])}: unknown "
                         f"transform; valid: {['none', *sorted(TRANSFORMS)]}")
    params = settings["basis_params"]
    try:  # tables to draw from: each range's ends and each choice must be valid
        ends = check_ranges(settings["basis"], params) if has_ranges(params) else [params]
    except SpaceError as exc:
        raise ValueError(str(exc)) from None
    try:
        for values in ends:
            _validate_estimator(make_basis(settings["basis"], **values))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"basis_params ({settings['basis']}): {exc}") from None
    try:
        transform = make_transform(settings["input_transform"],
                                   **settings["input_transform_params"])
        if transform is not None:
            _validate_estimator(transform)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"input_transform_params ({settings['input_transform']}): {exc}"
                         ) from None


#: LightGBM's scikit-learn estimator declares no constraints; these are its documented ranges.
def _lightgbm_constraints() -> dict[str, list]:
    positive = [Interval(Real, 0, None, closed="neither")]
    nonneg = [Interval(Real, 0, None, closed="left")]
    fraction = [Interval(Real, 0, 1, closed="right")]
    return {
        "boosting_type": [StrOptions({"gbdt", "dart", "rf"})],
        "num_leaves": [Interval(Integral, 2, 131072, closed="both")],
        "max_depth": [Interval(Integral, -1, None, closed="left")],
        "learning_rate": positive, "n_estimators": [Interval(Integral, 1, None, closed="left")],
        "subsample_for_bin": [Interval(Integral, 1, None, closed="left")],
        "objective": [str, None], "min_split_gain": nonneg, "min_child_weight": nonneg,
        "min_child_samples": [Interval(Integral, 0, None, closed="left")],
        "subsample": fraction, "subsample_freq": [Interval(Integral, 0, None, closed="left")],
        "colsample_bytree": fraction, "reg_alpha": nonneg, "reg_lambda": nonneg,
        "random_state": ["random_state"], "n_jobs": [Integral, None],
        "importance_type": [StrOptions({"split", "gain"})], "verbose": [Integral],
        "max_bin": [Interval(Integral, 2, None, closed="left")],
        "data_sample_strategy": [StrOptions({"bagging", "goss"})],
    }


def _validate_estimator(estimator) -> None:
    """Check an estimator's (and its nested estimators') parameters against their declared
    constraints, without fitting."""
    nested = [estimator] + [v for v in estimator.get_params(deep=True).values()
                            if isinstance(v, BaseEstimator)]
    constraints: dict[str, list[Any]] | None
    for est in nested:
        params = est.get_params(deep=False)
        if any(c.__module__.startswith("lightgbm") for c in type(est).__mro__[:-1]):
            constraints = _lightgbm_constraints()
            unknown = sorted(set(params) - set(constraints) - {"class_weight"})
            extra = sorted(k for k in unknown if params[k] is not None)
            if extra:
                raise ValueError(f"unknown LightGBM parameter(s) [{listing(extra, 60)}]; "
                                 f"valid: {listing(sorted(constraints))}")
            params = {k: v for k, v in params.items() if k in constraints}
        else:
            constraints = getattr(est, "_parameter_constraints", None)
            if constraints is None:
                continue
        validate_parameter_constraints(constraints, params, caller_name=type(est).__name__)


# --------------------------------------------------------------------------- other sections

class SelectionConfig(Section):
    """``[selection]``: BaseBoostCV's folds (contiguous unless ``shuffle``; whole groups of rows
    when the dataset has groups, unless ``groups = false``) and scoring; with candidates,
    ``ensemble``: the mean of that many best candidates is a candidate too
    (:class:`~workbench.selection.BasisChoiceCV`; 1: none)."""

    cv: int = Field(default=5, ge=2, le=10_000)
    shuffle: bool = False
    scoring: str = "neg_mean_absolute_error"
    groups: bool = True  # whole groups per fold when the dataset has groups (e.g. devices)
    ensemble: int = Field(default=1, ge=1, le=1_000)

    @model_validator(mode="after")
    def _scorer(self) -> SelectionConfig:
        if self.scoring not in get_scorer_names():
            raise ValueError(f"scoring = {shorten(self.scoring)}: unknown scorer; see "
                             "sklearn.metrics.get_scorer_names(), e.g. "
                             "'neg_mean_absolute_error'")
        return self


class EvaluationConfig(Section):
    """``[evaluation]``: ``cv_repeats`` > 0 adds a repeated ``cv_folds``-fold CV of the chosen
    model on the training rows (``RepeatedKFold`` seeded by ``cv_seed``); ``nested_folds`` > 0
    adds a nested CV over all rows, every choice remade inside each outer fold."""

    cv_folds: int = Field(default=5, ge=2, le=10_000)
    cv_repeats: int = Field(default=0, ge=0, le=10_000)
    cv_seed: int = Field(default=1000, ge=0, le=MAX_INT)
    nested_folds: int = Field(default=0, ge=0, le=10_000)
    nested_seed: int = Seed()

    @model_validator(mode="after")
    def _nested(self) -> EvaluationConfig:
        if self.nested_folds == 1:
            raise ValueError("nested_folds = 1: give 0 (off) or >= 2 folds")
        return self


#: A key whose value :class:`~workbench.conformal.ConformalRegressor`'s constraints check.
_Conformal = ParameterOf(ConformalRegressor)


class IntervalsConfig(Section):
    """``[intervals]``: conformal prediction intervals around the fitted model
    (:class:`~workbench.conformal.ConformalRegressor`), ``1 - alpha`` per target. ``method``
    "oof" takes the out-of-fold residuals of the CV the model already ran to make its
    choices and centres ``+- q`` on the model fitted on all rows: no extra fit (``cv`` is
    then unused: the model's own folds count); absent, the family's default
    (:attr:`~workbench.experiment.families.base.ModelFamily.interval_method`: "oof" for a
    family whose model cross-validates itself, else "cv_plus"); "cv_plus" refits the whole model
    (every choice remade) once per ``cv`` fold; "cv" uses the same refits but centres
    ``+- q`` on the model fitted on all rows (not widened by the fold models'
    disagreement); "split" holds out ``calibration_fraction`` of the training rows.
    On unless ``enabled = false``. ``alpha``, ``method``, ``cv`` and ``calibration_fraction``
    are ConformalRegressor's parameters, checked against its ``_parameter_constraints``."""

    enabled: bool = True
    alpha: Annotated[float, _Conformal] = 0.1
    method: Annotated[str, _Conformal] | None = None
    # le: a cap ConformalRegressor does not declare (each fold refits the whole model)
    cv: Annotated[int, _Conformal] = Field(default=5, le=10_000)
    calibration_fraction: Annotated[float, _Conformal] = 0.25


class CVConfig(Section):
    """``[cv]``: the nested cross-validation of a sweep (``repeats``: ``RepeatedKFold``)."""

    outer_folds: int = Field(default=5, ge=2, le=10_000)
    inner_folds: int = Field(default=5, ge=2, le=10_000)
    repeats: int = Field(default=1, ge=1, le=1000)
    seed: int = Seed()


class StudyConfig(Section):
    """``[study]``: the Optuna studies of a sweep. ``storage``: a journal file path (one
    machine, several processes) or an RDB URL such as ``postgresql://...`` (machines)."""

    trials: int = Field(default=20, ge=1, le=1_000_000)
    timeout: float | None = Field(default=None, gt=0)
    sampler: Literal["tpe", "random"] = "tpe"
    pruner: Literal["none", "median", "wilcoxon"] = "median"
    storage: str = "mlruns/optuna.journal"
    study_name: str | None = None
    workers: int = Field(default=1, ge=1, le=1024)
    stale_after_s: float = Field(default=600, gt=0)


class TrackingConfig(Section):
    """``[tracking]``: MLflow; ``tracking_uri`` None means $MLFLOW_TRACKING_URI or
    ``sqlite:///mlruns/mlflow.db``; ``experiment`` None means the config's name."""

    tracking_uri: str | None = None
    experiment: str | None = None


class _Top(Section):
    """The top level of a config file (sections validated on their own)."""

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
    def _jobs(self) -> _Top:
        if self.n_jobs == 0:
            raise ValueError("n_jobs = 0: give a number of processes >= 1, or -1 for all cores")
        return self


# --------------------------------------------------------------------------- the config

@dataclass(frozen=True)
class ExperimentConfig:
    """A checked config. Sections are typed (frozen pydantic models); ``family_settings``
    is the family's ``[model.<family>]`` (its own schema), ``search`` the ``[search]`` space."""

    path: Path | None
    name: str
    random_state: int | None
    n_jobs: int | None
    data: DataConfig
    model: ModelConfig
    selection: SelectionConfig = SelectionConfig()
    evaluation: EvaluationConfig = EvaluationConfig()
    intervals: IntervalsConfig = IntervalsConfig()
    search: SearchSpace = field(default_factory=SearchSpace)
    cv: CVConfig = CVConfig()
    study: StudyConfig = StudyConfig()
    tracking: TrackingConfig = TrackingConfig()
    family_settings: BaseModel | None = None
    description: str = ""
    #: Per-target settings chosen by a search (target -> full settings), over ``[model]``.
    chosen: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def family(self):
        """The :class:`~workbench.experiment.families.ModelFamily` of ``[model] family``."""
        return get_family(self.model.family)

    @property
    def label(self) -> str:
        return str(self.path) if self.path else "config"

    @property
    def jobs(self) -> int:
        """Processes for independent work (``n_jobs``; unset: every core). Results do not
        depend on it (:mod:`workbench.parallel`)."""
        return -1 if self.n_jobs is None else self.n_jobs

    def model_for(self, target: str | None) -> dict[str, Any]:
        """The boosting settings of one target: defaults < ``[model]`` < its
        ``[model.targets.<target>]`` table (< a search's choice for it).

        ``basis_params`` (``input_transform_params``) merge over the parent's while the target
        keeps the parent's basis (transform), and start afresh when it names another one."""
        if target in self.chosen:
            return dict(self.chosen[target])
        merged = {**MODEL_DEFAULTS, **_set(self.model)}
        override = _set(self.model.targets[target]) if target in self.model.targets else {}
        for key, params in (("basis", "basis_params"),
                            ("input_transform", "input_transform_params")):
            if key in override and override[key] != merged[key]:
                merged[params] = {}
            merged[params] = {**merged[params], **override.get(params, {})}
        merged.update({k: v for k, v in override.items() if not k.endswith("_params")})
        return merged

    def with_study(self, **updates) -> ExperimentConfig:
        """This config with ``[study]`` values replaced (``None`` values ignored)."""
        updates = {k: v for k, v in updates.items() if v is not None}
        return dataclasses.replace(self, study=self.study.model_copy(update=updates))


def _set(section: BaseModel) -> dict[str, Any]:
    """The boosting keys a section sets (``None``: not given)."""
    return {k: v for k, v in section.model_dump(exclude={"family", "targets"}).items()
            if v is not None}


def _one_line(where: str, exc: ValidationError, prefix: tuple = ()) -> str:
    """One line for the first error: ``file: section.key = value: what is allowed``."""
    err = exc.errors(include_url=False)[0]
    # drop the union-branch labels pydantic adds to a location ("literal['a','b']", ...)
    loc = ".".join(str(p) for p in (*prefix, *err["loc"]) if not any(c in str(p) for c in "[("))
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] in ("value_error", "assertion_error") or not err["loc"]:
        text = f"{where}: [{loc}]: {msg}" if loc else f"{where}: {msg}"
    else:
        text = f"{where}: {loc} = {shorten(err.get('input'))}: {msg}"
    return text if len(text) <= MAX_MESSAGE else text[:MAX_MESSAGE - 3] + "..."


def _error(where: str, text: str) -> ConfigError:
    line = f"{where}: {text}"
    return ConfigError(line if len(line) <= MAX_MESSAGE else line[:MAX_MESSAGE - 3] + "...")


def parse_config(raw: dict[str, Any], path: Path | None = None) -> ExperimentConfig:
    """Validate a config's tables (every value, name and basis parameter) and return an
    :class:`ExperimentConfig`; :class:`ConfigError` (one line) for the first bad value."""
    where = str(path) if path else "config"
    try:
        top = _Top.model_validate(raw)
    except ValidationError as exc:
        raise ConfigError(_one_line(where, exc)) from None
    try:
        data = DataConfig.model_validate(top.data)
    except ValidationError as exc:
        raise ConfigError(_one_line(where, exc, ("data",))) from None
    model_table = dict(top.model)
    family_name = model_table.get("family", "eigenvalue")
    if family_name not in FAMILIES:
        raise _error(where, f"model.family = {shorten(family_name)}: unknown family; valid: "
                            f"{sorted(FAMILIES)}")
    family = FAMILIES[family_name]
    family_tables = {name: model_table.pop(name) for name in list(model_table)
                     if name in FAMILIES and name != "family"}
    for name in family_tables:
        if name != family_name:
            raise _error(where, f"[model.{name}]: applies to family = \"{name}\" only "
                                f"(family is {family_name!r})")
    try:
        model = ModelConfig.model_validate(model_table)
    except ValidationError as exc:
        raise ConfigError(_one_line(where, exc, ("model",))) from None
    try:
        settings = family.parse_settings(family_tables.get(family_name))
    except ValidationError as exc:
        raise ConfigError(_one_line(where, exc, ("model", family_name))) from None
    except ValueError as exc:
        raise _error(where, f"[model.{family_name}]: {exc}") from None
    try:
        search = family.parse_search(top.search)
    except (SpaceError, ValueError) as exc:
        raise _error(where, f"[search]: {exc}") from None
    try:
        family.check_data(data)
    except ValueError as exc:
        raise _error(where, str(exc)) from None
    intervals = top.intervals
    if intervals.method is None:
        intervals = intervals.model_copy(update={"method": family.interval_method})
    elif intervals.method == "oof" and family.interval_method != "oof":
        raise _error(where, f"intervals.method = 'oof': family {family_name!r} keeps no "
                            f"out-of-fold predictions of its own; use 'cv_plus', 'cv' or "
                            f"'split'")
    name = top.name if top.name is not None else (path.stem if path else "config")
    cfg = ExperimentConfig(path=path, name=name, description=top.description,
                           random_state=top.random_state, n_jobs=top.n_jobs, data=data,
                           model=model, selection=top.selection, evaluation=top.evaluation,
                           intervals=intervals, search=search, cv=top.cv, study=top.study,
                           tracking=top.tracking, family_settings=settings)
    for target in [None, *model.targets]:
        label = "model" if target is None else f"model.targets.{target}"
        try:
            check_boost_settings(cfg.model_for(target))
        except ValueError as exc:
            raise _error(where, f"{label}.{exc}") from None
    return cfg


def load_config(path: str | Path) -> ExperimentConfig:
    """Read and check a TOML config file."""
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except IsADirectoryError:
        raise ConfigError(f"config file {path} is a directory") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise _error(str(path), f"cannot read the file: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise _error(str(path), f"not valid TOML: {exc}") from None
    except ValueError as exc:  # e.g. an integer beyond Python's str-conversion limit
        raise _error(str(path), f"a value cannot be read: {exc}") from None
    return parse_config(raw, path)


def load_dataset(cfg: ExperimentConfig):
    """The dataset named by the config's ``[data]`` section (paths relative to the config).

    Raises :class:`~workbench.datasets.DatasetError` for unusable data, including a training
    split too small for the configured CV folds.
    """
    data = cfg.data
    base = cfg.path.parent if cfg.path is not None else Path.cwd()
    data_dir = (base / data.data_dir).resolve() if data.data_dir else None
    if data.source == "google_5q":
        ds = load_google_5q(data_dir)
    elif data.source == "ibm_gates":
        ds = load_ibm_gates(data_dir, split=data.split or "time", split_seed=data.split_seed)
    else:
        ham = data.hamiltonian
        # source = "csv" has them (DataConfig's check)
        assert data.csv is not None and data.prior is not None and data.targets is not None
        ds = load_csv_dataset(
            (base / data.csv).resolve(), prior=data.prior, targets=data.targets,
            features=data.features, test_fraction=data.test_fraction,
            split_column=data.split_column, split_seed=data.split_seed,
            onsite=ham.onsite if ham else None, couplings=ham.couplings if ham else None,
            sign=ham.sign if ham else -1, topology=ham.topology if ham else "chain",
            shape=ham.shape if ham else None, edges=ham.edges if ham else None,
            qubit_features=ham.qubit_features if ham else None,
            coupler_features=ham.coupler_features if ham else None,
            group_column=data.group_column, name=cfg.name, unit=data.unit)
    folds = cfg.selection.cv
    if len(ds.train_index) < 2 * folds:
        raise DatasetError(f"the training split has {len(ds.train_index)} rows, too few for "
                           f"[selection] cv = {folds} (each fold needs at least 2 rows: "
                           f"at least {2 * folds} training rows)")
    iv = cfg.intervals
    if iv.enabled:
        # CV+ calibrates on every training row (each fold needs 2); split on its held-out
        # share (rounded up, as train_test_split does)
        need = min_calibration_rows(iv.alpha)
        if iv.method == "oof":  # every training row is held out once by the model's CV
            least, how = need, "the model's own folds"
        elif iv.method != "split":
            least, how = max(2 * iv.cv, need), f"cv = {iv.cv}"
        else:
            least = int((need - 1) / iv.calibration_fraction) + 1  # ceil(frac n) >= need
            how = f"calibration_fraction = {iv.calibration_fraction}"
        if len(ds.train_index) < least:
            raise DatasetError(f"the training split has {len(ds.train_index)} rows, too few "
                               f"for [intervals] method = {iv.method!r} with {how} and alpha "
                               f"= {iv.alpha} (at least {least}); set a larger alpha or "
                               f"[intervals] enabled = false")
    return ds
