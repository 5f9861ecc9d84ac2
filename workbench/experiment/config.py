"""Experiment configs (TOML files under ``experiments/``): read, check, and turn into models.

A config has these sections (see ``experiments/paper_main_body.toml`` for an annotated one)::

    name, description, random_state, n_jobs     # top level
    [data]        source = "google_5q" (data_dir optional), or a CSV of your own:
                  csv, prior, targets, features, test_fraction | split_column, split_seed
    [data.hamiltonian]  onsite, couplings, sign (optional, for physics-aware models)
    [model]       basis, basis_params, n_stages, loss, line_search_loss, line_search_penalty,
                  alpha, basis_inputs ("prior" | "prior+features"), input_transform
    [model.targets.<target>]  the same keys, overriding [model] for one target
    [selection]   cv (folds, contiguous unless shuffle = true), shuffle, scoring
    [search]      the space a sweep searches (see workbench.experiment.space)
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

from sklearn.metrics import get_scorer
from sklearn.model_selection import KFold

from ..bases import make_basis, make_transform
from ..boosting import BaseBoostRegressor
from ..datasets import Dataset, DatasetError, load_csv_dataset, load_google_5q
from ..multitarget import MultiTargetBaseBoost
from ..selection import BaseBoostCV
from .space import SearchSpace, SpaceError

__all__ = ["ConfigError", "ExperimentConfig", "build_model", "load_config", "load_dataset",
           "make_booster", "parse_config", "target_inputs"]

TOP_KEYS = {"name", "description", "random_state", "n_jobs", "data", "model", "selection",
            "search", "cv", "study", "tracking"}
DATA_KEYS = {"source", "data_dir", "csv", "prior", "targets", "features", "test_fraction",
             "split_column", "split_seed", "hamiltonian"}
HAMILTONIAN_KEYS = {"onsite", "couplings", "sign"}
MODEL_KEYS = {"basis", "basis_params", "n_stages", "loss", "line_search_loss",
              "line_search_penalty", "alpha", "basis_inputs", "input_transform",
              "input_transform_params"}
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


def _positive_int(where: str, key: str, value: Any, minimum: int) -> None:
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise ConfigError(f"{where}: {key} must be an integer >= {minimum}, got {value!r}")


def _check_sweep_sections(where: str, raw: dict[str, Any]):
    try:
        search = SearchSpace.from_table(_table(f"{where} [search]", raw.get("search", {})))
    except SpaceError as exc:
        raise ConfigError(f"{where} [search]: {exc}") from None
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
    search, cv, study, tracking = _check_sweep_sections(where, raw)
    cfg = ExperimentConfig(path=path, name=str(raw.get("name", path.stem if path else "config")),
                           random_state=raw.get("random_state"), n_jobs=raw.get("n_jobs"),
                           data=data, model=model, targets=targets, selection=selection,
                           search=search, cv=cv, study=study, tracking=tracking)
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
            name=cfg.name)
    folds = cfg.selection["cv"]
    if len(ds.train_index) < 2 * folds:
        raise DatasetError(f"the training split has {len(ds.train_index)} rows, too few for "
                           f"[selection] cv = {folds} (each fold needs at least 2 rows: "
                           f"at least {2 * folds} training rows)")
    return ds


def target_inputs(settings: dict[str, Any], dataset: Dataset) -> list[str]:
    """The basis input columns that ``settings["basis_inputs"]`` names."""
    extra = dataset.feature_names if settings["basis_inputs"] == "prior+features" else []
    return dataset.prior_names + extra


def build_model(cfg: ExperimentConfig, dataset: Dataset) -> MultiTargetBaseBoost:
    """One :class:`BaseBoostCV` per target, target ``j`` boosting from prior column ``j``."""
    names = dataset.target_names
    unknown = sorted(set(cfg.targets) - set(names))
    if unknown:
        raise ConfigError(f"[model.targets]: unknown target(s) {unknown}; the dataset's "
                          f"targets are {names}")
    selection = cfg.selection
    cv = KFold(selection["cv"], shuffle=selection["shuffle"],
               random_state=cfg.random_state if selection["shuffle"] else None)
    per_target = {}
    for target, prior in zip(names, dataset.prior_names):
        s = cfg.model_for(target)
        booster = make_booster(s, prior=prior, inputs=target_inputs(s, dataset))
        per_target[target] = BaseBoostCV(booster, cv=cv, scoring=selection["scoring"])
    return MultiTargetBaseBoost(target_estimators=per_target, n_jobs=cfg.n_jobs,
                                random_state=cfg.random_state)
