"""Data sources: the names ``[data] source`` takes, one loader each, in one registry.

A source turns the options of a config's ``[data]`` table into a :class:`Dataset`, with
relative paths resolved against a base folder (the config's). The benchmarks
(``google_5q``, ``ibm_gates``) and a CSV of one's own (``csv``) are registered here; another
source is a function added with :func:`register_source` or, from another package, through an
entry point of the group :data:`SOURCE_ENTRY_POINT_GROUP` (``workbench.sources``), loaded when a
name is not found (:func:`discover_sources`). An unknown name is an error listing the valid
ones, as for the bases and losses of the core.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._plugins import load_entry_points
from .base import Dataset
from .csv import DatasetError, load_csv_dataset
from .google_5q import load_google_5q
from .ibm_gates import load_ibm_gates

__all__ = ["SOURCES", "SOURCE_ENTRY_POINT_GROUP", "DataSource", "discover_sources", "get_source",
           "load_source", "register_source", "source_names"]

#: ``load(options, base, name)``: the dataset that a ``[data]`` table's ``options`` describe,
#: relative paths taken from ``base``, ``name`` the dataset's name where it has none of its own.
Loader = Callable[[Mapping[str, Any], Path, str], Dataset]


@dataclass(frozen=True)
class DataSource:
    """One ``[data] source``.

    Parameters
    ----------
    name : str
        The value of ``[data] source``.
    load : callable
        ``load(options, base, name) -> Dataset`` (:data:`Loader`).
    """

    name: str
    load: Loader


#: Data sources by name, in the order they were registered.
SOURCES: dict[str, DataSource] = {}


def register_source(name: str, load: Loader) -> DataSource:
    """Add a data source under ``name``.

    Parameters
    ----------
    name : str
        The value of ``[data] source`` that selects it.
    load : callable
        ``load(options, base, name) -> Dataset``.

    Returns
    -------
    DataSource
        The registered source.

    Raises
    ------
    ValueError
        For an empty name.
    TypeError
        For a loader that cannot be called.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"a data source needs a name, got {name!r}")
    if not callable(load):
        raise TypeError(f"data source {name!r}: the loader must be callable, got {load!r}")
    source = DataSource(name, load)
    SOURCES[name] = source
    return source


#: The entry-point group other packages add data sources through: each entry point names a
#: loader ``load(options, base, name) -> Dataset``, registered under its own name.
SOURCE_ENTRY_POINT_GROUP = "workbench.sources"

_discovered: set[str] = set()


def discover_sources() -> list[str]:
    """Register the data sources other packages declare as entry points, each once.

    The group is :data:`SOURCE_ENTRY_POINT_GROUP`. One that cannot be loaded is reported in
    one warning line naming it and left out.

    Returns
    -------
    list of str
        The names registered by this call.
    """
    def register(name: str, load: Any) -> str:
        return register_source(name, load).name

    return load_entry_points(SOURCE_ENTRY_POINT_GROUP, register, _discovered)


def source_names() -> list[str]:
    """The registered source names, plug-ins included, in registration order.

    Returns
    -------
    list of str
        The valid values of ``[data] source`` (after :func:`discover_sources`).
    """
    discover_sources()
    return list(SOURCES)


def get_source(name: str) -> DataSource:
    """The source called ``name``.

    A name not registered yet is looked up among the entry points first
    (:func:`discover_sources`).

    Parameters
    ----------
    name : str
        A registered source name.

    Returns
    -------
    DataSource
        The source.

    Raises
    ------
    DatasetError
        For an unknown name (the message lists the valid ones).
    """
    if name not in SOURCES and name not in source_names():
        raise DatasetError(f"unknown data source {name!r}; valid: {list(SOURCES)}")
    return SOURCES[name]


def load_source(name: str, options: Mapping[str, Any], base: Path,
                dataset_name: str) -> Dataset:
    """Load the dataset that source ``name`` makes of ``options``.

    Parameters
    ----------
    name : str
        A registered source name.
    options : mapping
        The ``[data]`` table's values.
    base : Path
        The folder relative paths are resolved against.
    dataset_name : str
        The dataset's name where the source gives none of its own.

    Returns
    -------
    Dataset
        The loaded dataset.
    """
    return get_source(name).load(options, base, dataset_name)


def _data_dir(options: Mapping[str, Any], base: Path) -> Path | None:
    data_dir = options.get("data_dir")
    return (base / data_dir).resolve() if data_dir else None


def _google_5q(options: Mapping[str, Any], base: Path, name: str) -> Dataset:
    return load_google_5q(_data_dir(options, base))


def _ibm_gates(options: Mapping[str, Any], base: Path, name: str) -> Dataset:
    return load_ibm_gates(_data_dir(options, base), split=options.get("split") or "time",
                          split_seed=options.get("split_seed", 0))


def _csv(options: Mapping[str, Any], base: Path, name: str) -> Dataset:
    ham = options.get("hamiltonian") or {}
    return load_csv_dataset(
        (base / options["csv"]).resolve(), prior=options.get("prior") or (),
        targets=options["targets"],
        features=options.get("features", []), test_fraction=options.get("test_fraction"),
        split_column=options.get("split_column"), split_seed=options.get("split_seed", 0),
        onsite=ham.get("onsite"), couplings=ham.get("couplings"), sign=ham.get("sign", -1),
        topology=ham.get("topology", "chain"), shape=ham.get("shape"), edges=ham.get("edges"),
        qubit_features=ham.get("qubit_features"),
        coupler_features=ham.get("coupler_features"),
        group_column=options.get("group_column"), name=name, unit=options.get("unit"),
        order_column=options.get("order_column"), split=options.get("split"),
        prior_label=options.get("prior_label") or "prior")


register_source("google_5q", _google_5q)
register_source("ibm_gates", _ibm_gates)
register_source("csv", _csv)
