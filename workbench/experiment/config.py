"""Experiment configs (TOML files under ``experiments/``): read, check, and turn into models.

A config has these sections (see ``experiments/paper_main_body.toml`` for an annotated one)::

    name, description, random_state, n_jobs     # top level
    [data]        source = "google_5q" (data_dir optional), or a CSV of your own:
                  csv, prior, targets, features, test_fraction | split_column, split_seed
    [data.hamiltonian]  onsite, couplings, sign (optional, for physics-aware models)
    [model]       family ("eigenvalue" | "hamiltonian"), basis, basis_params, n_stages, loss,
                  line_search_loss, line_search_penalty, alpha,
                  basis_inputs ("prior" | "prior+features"), input_transform
    [model.targets.<target>]  the same keys but family, overriding [model] for one target
    [model.hamiltonian]  the parameter-space model of family = "hamiltonian" (its eigenvalue-
                  space boosting stage on top uses the [model] keys above)
    [evaluation]  extra estimates of evaluate: repeated CV on the training rows, nested CV
                  over all rows
    [selection]   cv (folds, contiguous unless shuffle = true), shuffle, scoring
    [search]      the space a sweep searches (see workbench.experiment.space)
    [search.hamiltonian]  family hamiltonian: the [model.hamiltonian] settings a sweep varies
    [cv]          outer_folds, inner_folds, repeats, seed (nested CV of a sweep)
    [study]       trials, timeout, sampler, pruner, storage, study_name, workers
    [tracking]    tracking_uri, experiment (MLflow)

Unknown sections, keys, names and targets are errors that list what is valid.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
from sklearn.metrics import get_scorer
from sklearn.model_selection import KFold

from ..bases import make_basis, make_transform
from ..boosting import BaseBoostRegressor
from ..datasets import Dataset, DatasetError, load_csv_dataset, load_google_5q
from ..fitted_prior import FittedPriorBoost
from ..multitarget import MultiTargetBaseBoost
from ..hamiltonian import PARASITIC_KINDS, make_graph
from ..param_boost import PARAM_LOSSES, HamiltonianParameterRegressor, default_library
from ..param_select import HamiltonianSelectionCV, candidate_pool
from ..selection import BaseBoostCV
from .space import SearchSpace, SpaceError

__all__ = ["ConfigError", "ExperimentConfig", "build_model", "load_config", "load_dataset",
           "make_booster", "make_hamiltonian", "model_inputs", "parse_config", "target_inputs"]

TOP_KEYS = {"name", "description", "random_state", "n_jobs", "data", "model", "selection",
            "search", "cv", "study", "tracking", "evaluation"}
DATA_KEYS = {"source", "data_dir", "csv", "prior", "targets", "features", "test_fraction",
             "split_column", "split_seed", "hamiltonian"}
HAMILTONIAN_KEYS = {"onsite", "couplings", "sign", "qubit_features", "coupler_features",
                    "topology", "shape", "edges"}
MODEL_KEYS = {"basis", "basis_params", "n_stages", "loss", "line_search_loss",
              "line_search_penalty", "alpha", "basis_inputs", "input_transform",
              "input_transform_params"}
FAMILIES = ("eigenvalue", "hamiltonian")
#: ``[model.hamiltonian]``: the parameter-space model (``family = "hamiltonian"``).
#: ``start``: covariates every model has ("default": the default library, "none": intercepts);
#: ``candidates``: the pool ("physical": candidate_pool with neighbours, "local": without,
#: "none"); ``selection``: "forward" (forward selection by CV from start over the pool) or
#: "none" (start and pool together, regularised by alpha / alpha_l1).
HAMILTONIAN_DEFAULTS: dict[str, Any] = dict(
    loss="huber", huber_delta=0.5, alpha=1.0, alpha_l1=0.0, max_iter=20, start="default",
    candidates="physical", selection="forward", selection_cv=5, selection_repeats=1,
    max_steps=20, min_improvement=1e-3, boost_stage=True, prior_cv=5, parasitic="none")
HAMILTONIAN_CHOICES: dict[str, tuple[str, ...]] = {
    "loss": tuple(PARAM_LOSSES), "start": ("default", "none"),
    "candidates": ("physical", "local", "none"),
    "selection": ("forward", "linearised", "none"),
    "parasitic": PARASITIC_KINDS}
#: ``[search.hamiltonian]``: the keys a sweep may vary, with the valid values of the
#: categorical ones (every value a search can take is also checked like ``[model.hamiltonian]``).
HAMILTONIAN_SEARCH: dict[str, tuple[Any, ...] | None] = {
    key: HAMILTONIAN_CHOICES.get(key, (True, False) if key == "boost_stage" else None)
    for key in HAMILTONIAN_DEFAULTS}
#: ``[evaluation]``: ``cv_repeats`` > 0 adds a repeated ``cv_folds``-fold CV of the chosen
#: model on the training rows (seeds ``cv_seed``...); ``nested_folds`` > 0 adds a nested CV
#: over all rows (training and test), every choice remade inside each outer fold.
EVALUATION_DEFAULTS: dict[str, Any] = dict(cv_folds=5, cv_repeats=0, cv_seed=1000,
                                           nested_folds=0, nested_seed=0)
SELECTION_KEYS = {"cv", "shuffle", "scoring"}
BASIS_INPUTS = ("prior", "prior+features")
SOURCES = ("google_5q", "csv")

MODEL_DEFAULTS: dict[str, Any] = dict(
    basis="paper_stacking", basis_params={}, n_stages=1, loss="squared_error",
    line_search_loss="absolute_error", line_search_penalty=0.1, alpha=0.9,
    basis_inputs="prior", input_transform="quantile_normal", input_transform_params={},
)
SELECTION_DEFAULTS: dict[str, Any] = dict(cv=5, shuffle=False, scoring="neg_mean_absolute_error")
#: Nested cross-validation of a sweep (``workbench sweep``).
CV_DEFAULTS: dict[str, Any] = dict(outer_folds=5, inner_folds=5, repeats=1, seed=0)
#: The Optuna studies of a sweep. ``storage``: a journal file path (one machine, several
#: processes) or an RDB URL such as ``postgresql://...`` (several machines).
STUDY_DEFAULTS: dict[str, Any] = dict(trials=20, timeout=None, sampler="tpe", pruner="median",
                                      storage="mlruns/optuna.journal", study_name=None,
                                      workers=1, stale_after_s=600)
SAMPLERS = ("tpe", "random")
PRUNERS = ("none", "median", "wilcoxon")
#: MLflow tracking; ``tracking_uri`` None means $MLFLOW_TRACKING_URI or mlruns/mlflow.db.
TRACKING_DEFAULTS: dict[str, Any] = dict(tracking_uri=None, experiment=None)


class ConfigError(ValueError):
    """A config file that cannot be used; the message names the file and the problem."""


def _check_keys(where: str, table: dict, valid: set[str]) -> None:
    unknown = sorted(set(table) - valid)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; valid keys are {sorted(valid)}")


@dataclass(frozen=True)
class ExperimentConfig:
    """A checked config: the raw tables plus where the file lives (for relative paths)."""

    path: Path | None
    name: str
    random_state: int | None
    n_jobs: int | None
    data: dict[str, Any]
    model: dict[str, Any]
    targets: dict[str, dict[str, Any]]
    selection: dict[str, Any]
    search: SearchSpace = field(default_factory=SearchSpace)
    cv: dict[str, Any] = field(default_factory=lambda: dict(CV_DEFAULTS))
    study: dict[str, Any] = field(default_factory=lambda: dict(STUDY_DEFAULTS))
    tracking: dict[str, Any] = field(default_factory=lambda: dict(TRACKING_DEFAULTS))
    family: str = "eigenvalue"
    hamiltonian: dict[str, Any] = field(default_factory=lambda: dict(HAMILTONIAN_DEFAULTS))
    evaluation: dict[str, Any] = field(default_factory=lambda: dict(EVALUATION_DEFAULTS))

    def model_for(self, target: str | None) -> dict[str, Any]:
        """The model settings of one target: ``[model]`` overridden by its target table.

        ``basis_params`` (``input_transform_params``) merge over the parent's while the target
        keeps the parent's basis (transform), and start afresh when it names another one.
        """
        merged = {**MODEL_DEFAULTS, **self.model}
        override = self.targets.get(target, {}) if target is not None else {}
        for key, params in (("basis", "basis_params"),
                            ("input_transform", "input_transform_params")):
            if key in override and override[key] != merged[key]:
                merged[params] = {}
            merged[params] = {**merged[params], **override.get(params, {})}
        merged.update({k: v for k, v in override.items() if not k.endswith("_params")})
        return merged


def _table(where: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a table, got {type(value).__name__} {value!r}")
    return dict(value)


def _check_data(where: str, data: dict[str, Any]) -> None:
    csv_keys = sorted((DATA_KEYS - {"source", "data_dir"}) & set(data))
    if data["source"] == "google_5q":
        if csv_keys:
            raise ConfigError(f"{where}: {csv_keys} apply to source = \"csv\" only")
        return
    for key in ("csv", "prior", "targets"):
        if key not in data:
            raise ConfigError(f"{where}: source = \"csv\" needs {key!r}")
    for key in ("prior", "targets", "features"):
        value = data.get(key, [])
        if not (isinstance(value, list) and all(isinstance(v, str) for v in value)):
            raise ConfigError(f"{where}: {key} must be a list of column names, got {value!r}")
    if len(data["prior"]) != len(data["targets"]):
        raise ConfigError(f"{where}: {len(data['prior'])} prior column(s) for "
                          f"{len(data['targets'])} target(s): give one prior column per target")
    if ("test_fraction" in data) == ("split_column" in data):
        raise ConfigError(f"{where}: give exactly one of test_fraction or split_column")
    ham = _table(f"{where}.hamiltonian", data.get("hamiltonian", {}))
    _check_keys(f"{where}.hamiltonian", ham, HAMILTONIAN_KEYS)
    if ham and not {"onsite", "couplings"} <= set(ham):
        raise ConfigError(f"{where}.hamiltonian: needs both onsite and couplings")
    if ham and {"topology", "shape", "edges"} & set(ham):
        try:
            make_graph(len(ham["onsite"]), ham.get("topology", "chain"), ham.get("shape"),
                       ham.get("edges"))
        except (ValueError, TypeError) as exc:
            raise ConfigError(f"{where}.hamiltonian: {exc}") from None


def _positive_int(where: str, key: str, value: Any, minimum: int) -> None:
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise ConfigError(f"{where}: {key} must be an integer >= {minimum}, got {value!r}")


def _check_sweep_sections(where: str, raw: dict[str, Any], family: str = "eigenvalue"):
    table = _table(f"{where} [search]", raw.get("search", {}))
    hamiltonian = family == "hamiltonian"
    if "hamiltonian" in table and not hamiltonian:
        raise ConfigError(f"{where} [search.hamiltonian]: applies to family = \"hamiltonian\" "
                          f"only (family is {family!r})")
    try:
        search = SearchSpace.from_table(table, HAMILTONIAN_SEARCH if hamiltonian else None)
    except SpaceError as exc:
        raise ConfigError(f"{where} [search]: {exc}") from None
    for key, values in search.hamiltonian_values().items():
        for value in values:
            _check_hamiltonian(where, {key: value}, family, section="search.hamiltonian")
    cv = {**CV_DEFAULTS, **_table(f"{where} [cv]", raw.get("cv", {}))}
    _check_keys(f"{where} [cv]", cv, set(CV_DEFAULTS))
    for key, minimum in (("outer_folds", 2), ("inner_folds", 2), ("repeats", 1), ("seed", 0)):
        _positive_int(f"{where} [cv]", key, cv[key], minimum)
    study = {**STUDY_DEFAULTS, **_table(f"{where} [study]", raw.get("study", {}))}
    _check_keys(f"{where} [study]", study, set(STUDY_DEFAULTS))
    _positive_int(f"{where} [study]", "trials", study["trials"], 1)
    _positive_int(f"{where} [study]", "workers", study["workers"], 1)
    if study["sampler"] not in SAMPLERS:
        raise ConfigError(f"{where} [study]: unknown sampler {study['sampler']!r}; valid: "
                          f"{list(SAMPLERS)}")
    if study["pruner"] not in PRUNERS:
        raise ConfigError(f"{where} [study]: unknown pruner {study['pruner']!r}; valid: "
                          f"{list(PRUNERS)}")
    if study["timeout"] is not None and not (isinstance(study["timeout"], (int, float))
                                             and study["timeout"] > 0):
        raise ConfigError(f"{where} [study]: timeout must be a number of seconds > 0, got "
                          f"{study['timeout']!r}")
    tracking = {**TRACKING_DEFAULTS, **_table(f"{where} [tracking]", raw.get("tracking", {}))}
    _check_keys(f"{where} [tracking]", tracking, set(TRACKING_DEFAULTS))
    return search, cv, study, tracking


def _check_hamiltonian(where: str, table, family: str,
                       section: str = "model.hamiltonian") -> dict[str, Any]:
    label = f"{where} [{section}]"
    if table is not None and family != "hamiltonian":
        raise ConfigError(f"{label}: applies to family = \"hamiltonian\" only (family is "
                          f"{family!r})")
    settings = {**HAMILTONIAN_DEFAULTS, **_table(label, table or {})}
    _check_keys(label, settings, set(HAMILTONIAN_DEFAULTS))
    for key, valid in HAMILTONIAN_CHOICES.items():
        if settings[key] not in valid:
            raise ConfigError(f"{label}: unknown {key} {settings[key]!r}; valid: {list(valid)}")
    for key, minimum in (("selection_cv", 2), ("selection_repeats", 1), ("max_steps", 0),
                         ("max_iter", 0), ("prior_cv", 2)):
        _positive_int(label, key, settings[key], minimum)
    if not isinstance(settings["boost_stage"], bool):
        raise ConfigError(f"{label}: boost_stage must be true or false, got "
                          f"{settings['boost_stage']!r}")
    for key in ("huber_delta", "alpha", "alpha_l1", "min_improvement"):
        value = settings[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0:
            raise ConfigError(f"{label}: {key} must be a number >= 0, got {value!r}")
    if settings["huber_delta"] <= 0:
        raise ConfigError(f"{label}: huber_delta must be > 0, got {settings['huber_delta']!r}")
    return settings


def make_hamiltonian(settings: dict[str, Any], dataset: Dataset, *, random_state=None,
                     n_jobs=None):
    """The parameter-space model that ``[model.hamiltonian]`` settings describe: a
    :class:`HamiltonianSelectionCV` (``selection = "forward"``) or a
    :class:`HamiltonianParameterRegressor` with the start and pool covariates together."""
    ham = dataset.hamiltonian
    if ham is None:
        raise ConfigError(f"family = \"hamiltonian\" needs a dataset with Hamiltonian "
                          f"parameters; {dataset.name!r} has none")
    on, co = list(ham.onsite.columns), list(ham.couplings.columns)
    edges = ham.edge_list
    parasitic = None if settings["parasitic"] == "none" else settings["parasitic"]
    common = dict(onsite=on, couplings=co, edges=edges, parasitic=parasitic,
                  sign=ham.sign, loss=settings["loss"],
                  huber_delta=float(settings["huber_delta"]), alpha=float(settings["alpha"]),
                  alpha_l1=float(settings["alpha_l1"]), max_iter=settings["max_iter"])
    start = default_library(on, co, edges) if settings["start"] == "default" else {}
    if settings["candidates"] == "none":
        pool = {}
    else:
        pool = candidate_pool(on, co, ham.qubit_features, ham.coupler_features, base=None,
                              neighbours=settings["candidates"] == "physical", edges=edges,
                              parasitic=parasitic)
    if settings["selection"] == "none":
        merged = {p: list(dict.fromkeys(start.get(p, []) + pool.get(p, [])))
                  for p in on + co}
        return HamiltonianParameterRegressor(covariates=merged, **common)
    return HamiltonianSelectionCV(candidates=pool, start=start or None,
                                  cv=settings["selection_cv"],
                                  n_repeats=settings["selection_repeats"],
                                  max_steps=settings["max_steps"],
                                  min_improvement=float(settings["min_improvement"]),
                                  random_state=random_state, n_jobs=n_jobs,
                                  method="linearised" if settings["selection"] == "linearised"
                                  else "refit", **common)


def make_booster(settings: dict[str, Any], prior, inputs: list[str]) -> BaseBoostRegressor:
    """The :class:`BaseBoostRegressor` that one target's settings describe."""
    return BaseBoostRegressor(
        prior=prior, basis=make_basis(settings["basis"], **settings["basis_params"]),
        n_stages=settings["n_stages"], loss=settings["loss"],
        line_search_loss=settings["line_search_loss"],
        line_search_penalty=settings["line_search_penalty"], alpha=settings["alpha"],
        basis_features=inputs,
        input_transform=make_transform(settings["input_transform"],
                                       **settings["input_transform_params"]))


def parse_config(raw: dict[str, Any], path: Path | None = None) -> ExperimentConfig:
    """Check a config's tables and return an :class:`ExperimentConfig`.

    Every name and value is resolved here (bases, losses, transforms, scoring, n_stages...),
    so a bad config fails at load time, never halfway through a run.
    """
    where = str(path) if path else "config"
    _check_keys(where, raw, TOP_KEYS)
    data = _table(f"{where} [data]", raw.get("data", {}))
    _check_keys(f"{where} [data]", data, DATA_KEYS)
    if "csv" in data:
        data.setdefault("source", "csv")
    if data.get("source") not in SOURCES:
        raise ConfigError(f"{where} [data]: source must be one of {list(SOURCES)}, got "
                          f"{data.get('source')!r}")
    _check_data(f"{where} [data]", data)
    model = _table(f"{where} [model]", raw.get("model", {}))
    targets = _table(f"{where} [model.targets]", model.pop("targets", {}))
    family = model.pop("family", "eigenvalue")
    if family not in FAMILIES:
        raise ConfigError(f"{where} [model]: unknown family {family!r}; valid: {list(FAMILIES)}")
    hamiltonian = _check_hamiltonian(where, model.pop("hamiltonian", None), family)
    _check_keys(f"{where} [model]", model, MODEL_KEYS)
    tables = {None: model}
    for name, table in targets.items():
        tables[name] = _table(f"{where} [model.targets.{name}]", table)
        _check_keys(f"{where} [model.targets.{name}]", table, MODEL_KEYS)
    for name, table in tables.items():
        label = f"{where} [model{'' if name is None else '.targets.' + name}]"
        for key in ("basis_params", "input_transform_params"):
            _table(f"{label} {key}", table.get(key, {}))
    selection = {**SELECTION_DEFAULTS, **_table(f"{where} [selection]", raw.get("selection", {}))}
    _check_keys(f"{where} [selection]", selection, SELECTION_KEYS)
    cv = selection["cv"]
    if not isinstance(cv, int) or isinstance(cv, bool) or cv < 2:
        raise ConfigError(f"{where} [selection]: cv must be an integer >= 2, got {cv!r}")
    if not isinstance(selection["shuffle"], bool):
        raise ConfigError(f"{where} [selection]: shuffle must be true or false, got "
                          f"{selection['shuffle']!r}")
    for key in ("random_state", "n_jobs"):
        value = raw.get(key)
        if value is not None and (not isinstance(value, int) or isinstance(value, bool)):
            raise ConfigError(f"{where}: {key} must be an integer, got {value!r}")
    try:
        get_scorer(selection["scoring"])
    except ValueError as exc:
        raise ConfigError(f"{where} [selection]: scoring: {exc}") from None
    search, cv, study, tracking = _check_sweep_sections(where, raw, family)
    evaluation = {**EVALUATION_DEFAULTS,
                  **_table(f"{where} [evaluation]", raw.get("evaluation", {}))}
    _check_keys(f"{where} [evaluation]", evaluation, set(EVALUATION_DEFAULTS))
    for key, minimum in (("cv_folds", 2), ("cv_repeats", 0), ("cv_seed", 0),
                         ("nested_folds", 0), ("nested_seed", 0)):
        _positive_int(f"{where} [evaluation]", key, evaluation[key], minimum)
    if evaluation["nested_folds"] == 1:
        raise ConfigError(f"{where} [evaluation]: nested_folds must be 0 (off) or >= 2, got 1")
    if family == "hamiltonian" and data["source"] == "csv" and not data.get("hamiltonian"):
        raise ConfigError(f"{where}: family = \"hamiltonian\" needs the Hamiltonian's columns "
                          "in [data.hamiltonian] (onsite, couplings)")
    cfg = ExperimentConfig(path=path, name=str(raw.get("name", path.stem if path else "config")),
                           random_state=raw.get("random_state"), n_jobs=raw.get("n_jobs"),
                           data=data, model=model, targets=targets, selection=selection,
                           search=search, cv=cv, study=study, tracking=tracking, family=family,
                           hamiltonian=hamiltonian, evaluation=evaluation)
    for target in tables:
        settings = cfg.model_for(target)
        label = f"{where} [model{'' if target is None else '.targets.' + target}]"
        if settings["basis_inputs"] not in BASIS_INPUTS:
            raise ConfigError(f"{label}: basis_inputs must be one of {list(BASIS_INPUTS)}, got "
                              f"{settings['basis_inputs']!r}")
        try:
            make_booster(settings, prior=None, inputs=None)._check_params()
        except (ValueError, TypeError) as exc:
            raise ConfigError(f"{label}: {exc}") from None
    return cfg


def load_config(path: str | Path) -> ExperimentConfig:
    """Read and check a TOML config file."""
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read config file {path}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    return parse_config(raw, path)


def load_dataset(cfg: ExperimentConfig) -> Dataset:
    """The dataset named by the config's ``[data]`` section (paths relative to the config).

    Raises :class:`~workbench.datasets.DatasetError` for unusable data, including a training
    split too small for the configured CV folds.
    """
    data = cfg.data
    base = cfg.path.parent if cfg.path is not None else Path.cwd()
    if data["source"] == "google_5q":
        data_dir = data.get("data_dir")
        ds = load_google_5q((base / data_dir).resolve() if data_dir is not None else None)
    else:
        ham = data.get("hamiltonian", {})
        ds = load_csv_dataset(
            (base / data["csv"]).resolve(), prior=data["prior"], targets=data["targets"],
            features=data.get("features", []), test_fraction=data.get("test_fraction"),
            split_column=data.get("split_column"), split_seed=data.get("split_seed", 0),
            onsite=ham.get("onsite"), couplings=ham.get("couplings"), sign=ham.get("sign", -1),
            qubit_features=ham.get("qubit_features"), coupler_features=ham.get("coupler_features"),
            topology=ham.get("topology", "chain"), shape=ham.get("shape"), edges=ham.get("edges"),
            name=cfg.name)
    folds = cfg.selection["cv"]
    if len(ds.train_index) < 2 * folds:
        raise DatasetError(f"the training split has {len(ds.train_index)} rows, too few for "
                           f"[selection] cv = {folds} (each fold needs at least 2 rows: "
                           f"at least {2 * folds} training rows)")
    return ds


#: Prefix of the columns holding the parameter-space model's prediction (family hamiltonian).
PRIOR_PREFIX = "prior_"


def target_inputs(settings: dict[str, Any], dataset: Dataset,
                  family: str = "eigenvalue") -> list[str]:
    """The basis input columns that ``settings["basis_inputs"]`` names: the prior columns
    (for family hamiltonian, the parameter-space model's predictions), optionally with the
    features."""
    extra = dataset.feature_names if settings["basis_inputs"] == "prior+features" else []
    if family == "hamiltonian":
        return [f"{PRIOR_PREFIX}{t}" for t in dataset.target_names] + extra
    return dataset.prior_names + extra


def model_inputs(cfg: ExperimentConfig, dataset: Dataset) -> pd.DataFrame:
    """The frame a config's model reads: :attr:`Dataset.X`, plus the Hamiltonian's
    parameter columns for family hamiltonian."""
    return dataset.X_physics if cfg.family == "hamiltonian" else dataset.X


def build_model(cfg: ExperimentConfig, dataset: Dataset):
    """The config's unfitted model.

    Family eigenvalue: one :class:`BaseBoostCV` per target, target ``j`` boosting from prior
    column ``j`` (a :class:`MultiTargetBaseBoost`). Family hamiltonian: a
    :class:`FittedPriorBoost` whose physics model is :func:`make_hamiltonian` and whose
    per-target stage is the same BaseBoostCV, boosting from the physics model's prediction.
    """
    names = dataset.target_names
    unknown = sorted(set(cfg.targets) - set(names))
    if unknown:
        raise ConfigError(f"[model.targets]: unknown target(s) {unknown}; the dataset's "
                          f"targets are {names}")
    selection = cfg.selection
    cv = KFold(selection["cv"], shuffle=selection["shuffle"],
               random_state=cfg.random_state if selection["shuffle"] else None)
    hamiltonian = cfg.family == "hamiltonian"
    per_target = {}
    for target, prior in zip(names, dataset.prior_names):
        s = cfg.model_for(target)
        booster = make_booster(s, prior=None if hamiltonian else prior,
                               inputs=target_inputs(s, dataset, cfg.family))
        per_target[target] = BaseBoostCV(booster, cv=cv, scoring=selection["scoring"])
    boost = MultiTargetBaseBoost(target_estimators=per_target, n_jobs=cfg.n_jobs,
                                 random_state=cfg.random_state)
    if not hamiltonian:
        return boost
    h = cfg.hamiltonian
    physics = make_hamiltonian(h, dataset, random_state=cfg.random_state, n_jobs=cfg.n_jobs)
    return FittedPriorBoost(physics, boost, prior_prefix=PRIOR_PREFIX,
                            cv=KFold(h["prior_cv"], shuffle=True,
                                     random_state=cfg.random_state or 0),
                            boost_stage=h["boost_stage"])
