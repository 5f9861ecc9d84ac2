"""Loading a config file and preparing the run a command works on.

:func:`load_config` reads the TOML, validates every section, resolves the model family
(:mod:`workbench.experiment.families`, built-in or found through the ``workbench.families``
entry points) and checks its settings and search space; :func:`prepare` loads the config's
dataset once and checks it against the config (:class:`PreparedRun`), and each command
hands that run down instead of loading the data again.

This module sits above the families: the config's types (:mod:`workbench.experiment.config`)
sit below them, so no import runs from the config to the families.
"""

from __future__ import annotations

import dataclasses
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from ..._text import clip
from ...datasets import Dataset
from ..config import (
    DataConfig,
    ExperimentConfig,
    IntervalsConfig,
    ModelConfig,
    TopLevel,
    check_boost_settings,
    load_dataset,
)
from ..config.overrides import apply_overrides, format_overrides
from ..config.schema import MAX_MESSAGE
from ..config.space import SearchSpace, SpaceError
from ..families import FAMILIES, ModelFamily, discover_families
from ..process.errors import ConfigError, shorten
from ..splits.folds import check_fold_settings

__all__ = ["PreparedRun", "load_config", "parse_config", "prepare"]


@dataclass(frozen=True)
class PreparedRun:
    """What a command works on: the checked config, its family and its dataset, loaded once.

    Parameters
    ----------
    config : ExperimentConfig
        The checked config.
    dataset : Dataset
        The config's data, checked against its folds and intervals.
    """

    config: ExperimentConfig
    dataset: Dataset

    @property
    def family(self) -> ModelFamily:
        """The model family of ``[model] family``."""
        family: ModelFamily = self.config.family
        return family

    def with_config(self, config: ExperimentConfig) -> PreparedRun:
        """Return the same data with another config.

        E.g. a search's choices, or ``--no-intervals``.

        Parameters
        ----------
        config : ExperimentConfig
            A config with the same ``[data]``.

        Returns
        -------
        PreparedRun
            The run on the same dataset.
        """
        return dataclasses.replace(self, config=config)


def prepare(cfg: ExperimentConfig) -> PreparedRun:
    """Load the config's dataset once and check it (:func:`~.config.load_dataset`).

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.

    Returns
    -------
    PreparedRun
        The config with its dataset.

    Raises
    ------
    DatasetError
        For unusable data (the data source's message), or too few training rows.
    """
    return PreparedRun(cfg, load_dataset(cfg))


def _one_line(where: str, exc: ValidationError, prefix: tuple[str, ...] = ()) -> str:
    """Write one line for the first error: ``file: section.key = value: what is allowed``."""
    err = exc.errors(include_url=False)[0]
    # drop the union-branch labels pydantic adds to a location ("literal['a','b']", ...)
    loc = ".".join(str(p) for p in (*prefix, *err["loc"]) if not any(c in str(p) for c in "[("))
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] in ("value_error", "assertion_error") or not err["loc"]:
        text = f"{where}: [{loc}]: {msg}" if loc else f"{where}: {msg}"
    else:
        text = f"{where}: {loc} = {shorten(err.get('input'))}: {msg}"
    return clip(text, MAX_MESSAGE)


def _error(where: str, text: str) -> ConfigError:
    return ConfigError(clip(f"{where}: {text}", MAX_MESSAGE))


def _family(where: str, model_table: dict[str, Any]) -> tuple[ModelFamily, Any]:
    """Find the family ``[model] family`` names, and its ``[model.<family>]`` table.

    The table is taken out of ``model_table``; a table of another family is an error.
    """
    family_name = model_table.get("family", "eigenvalue")
    if family_name not in FAMILIES:
        discover_families()  # a plug-in's name: entry points are read on a miss
    if family_name not in FAMILIES:
        raise _error(where, f"model.family = {shorten(family_name)}: unknown family; valid: "
                            f"{sorted(FAMILIES)}")
    family_tables = {name: model_table.pop(name) for name in list(model_table)
                     if name in FAMILIES and name != "family"}
    for name in family_tables:
        if name != family_name:
            raise _error(where, f"[model.{name}]: applies to family = \"{name}\" only "
                                f"(family is {family_name!r})")
    return FAMILIES[family_name], family_tables.get(family_name)


def _family_parts(where: str, family: ModelFamily, table: Any, search: dict[str, Any],
                  data: DataConfig) -> tuple[BaseModel | None, SearchSpace]:
    """Check the family's settings, search space and ``[data]``; return the first two."""
    try:
        settings = family.parse_settings(table)
    except ValidationError as exc:
        raise ConfigError(_one_line(where, exc, ("model", family.name))) from None
    except ValueError as exc:
        raise _error(where, f"[model.{family.name}]: {exc}") from None
    try:
        space = family.parse_search(search)
    except (SpaceError, ValueError) as exc:
        raise _error(where, f"[search]: {exc}") from None
    try:
        family.check_data(data)
    except ValueError as exc:
        raise _error(where, str(exc)) from None
    return settings, space


def _intervals(where: str, family: ModelFamily, intervals: IntervalsConfig) -> IntervalsConfig:
    """Fill in ``[intervals]``' method with the family's default.

    ``"oof"`` is accepted only where the family keeps out-of-fold predictions.
    """
    if intervals.method is None:
        return intervals.model_copy(update={"method": family.interval_method})
    if intervals.method == "oof" and family.interval_method != "oof":
        raise _error(where, f"intervals.method = 'oof': family {family.name!r} keeps no "
                            f"out-of-fold predictions of its own; use 'cv_plus', 'cv' or "
                            f"'split'")
    return intervals


def _validated(where: str, model: type[BaseModel], table: Any,
               prefix: tuple[str, ...] = ()) -> Any:
    try:
        return model.model_validate(table)
    except ValidationError as exc:
        raise ConfigError(_one_line(where, exc, prefix)) from None


def parse_config(raw: dict[str, Any], path: Path | None = None) -> ExperimentConfig:
    """Validate a config's tables (every value, name and basis parameter).

    Parameters
    ----------
    raw : dict
        The config's tables, as read from TOML.
    path : Path, optional
        The config file (messages name it; relative data paths start from its folder).

    Returns
    -------
    ExperimentConfig
        The checked config, its family resolved.

    Raises
    ------
    ConfigError
        One line for the first bad value: file, ``section.key``, value, what is allowed.
    """
    where = str(path) if path else "config"
    top: TopLevel = _validated(where, TopLevel, raw)
    data: DataConfig = _validated(where, DataConfig, top.data, ("data",))
    model_table = dict(top.model)
    family, family_table = _family(where, model_table)
    model: ModelConfig = _validated(where, ModelConfig, model_table, ("model",))
    settings, search = _family_parts(where, family, family_table, top.search, data)
    name = top.name if top.name is not None else (path.stem if path else "config")
    cfg = ExperimentConfig(path=path, name=name, description=top.description,
                           random_state=top.random_state, n_jobs=top.n_jobs, data=data,
                           model=model, selection=top.selection, evaluation=top.evaluation,
                           intervals=_intervals(where, family, top.intervals), search=search,
                           cv=top.cv, study=top.study, tracking=top.tracking,
                           family_settings=settings, family=family)
    for target in [None, *model.targets]:
        label = "model" if target is None else f"model.targets.{target}"
        try:
            check_boost_settings(cfg.model_for(target))
        except ValueError as exc:
            raise _error(where, f"{label}.{exc}") from None
    try:
        check_fold_settings(cfg)
    except ValueError as exc:
        raise _error(where, str(exc)) from None
    return cfg


def load_config(path: str | Path,
                overrides: Mapping[str, Any] | None = None) -> ExperimentConfig:
    """Read and check a TOML config file.

    Parameters
    ----------
    path : str or Path
        The config file.
    overrides : mapping, optional
        ``SECTION.KEY`` -> value, set over the file's values before they are checked
        (``--set``; :mod:`workbench.experiment.config.overrides`): checked like the file's own.

    Returns
    -------
    ExperimentConfig
        The checked config (:func:`parse_config`).

    Raises
    ------
    ConfigError
        One line: a file that cannot be read, is not TOML, or holds a bad value (an
        override's too: the line then starts with the ``--set`` overrides).
    """
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
    if not overrides:
        return parse_config(raw, path)
    try:
        cfg = parse_config(apply_overrides(raw, overrides), path)
    except ConfigError as exc:
        raise ConfigError(f"with --set {format_overrides(overrides)}: {exc}") from None
    return dataclasses.replace(cfg, overrides=dict(overrides))
