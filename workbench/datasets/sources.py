"""Data sources: the names ``[data] source`` takes, one loader each, in one registry.

A source turns the options of a config's ``[data]`` table into a :class:`Dataset`, with
relative paths resolved against a base folder (the config's). The benchmarks
(``google_5q``, ``ibm_gates``) and a CSV of one's own (``csv``) are registered here; another
source is a function added with :func:`register_source`. An unknown name is an error listing
the valid ones, as for the bases and losses of the core.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .base import Dataset
from .csv import DatasetError, load_csv_dataset
from .google_5q import load_google_5q
from .ibm_gates import load_ibm_gates

__all__ = ["SOURCES", "DataSource", "get_source", "load_source", "register_source",
           "source_names"]

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
    """
    source = DataSource(name, load)
    SOURCES[name] = source
    return source


def source_names() -> list[str]:
    """The registered source names, in registration order.

    Returns
    -------
    list of str
        The valid values of ``[data] source``.
    """
    return list(SOURCES)


def get_source(name: str) -> DataSource:
    """The source called ``name``.

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
    try:
        return SOURCES[name]
    except KeyError:
        raise DatasetError(f"unknown data source {name!r}; valid: {source_names()}") from None


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
        (base / options["csv"]).resolve(), prior=options["prior"], targets=options["targets"],
        features=options.get("features", []), test_fraction=options.get("test_fraction"),
        split_column=options.get("split_column"), split_seed=options.get("split_seed", 0),
        onsite=ham.get("onsite"), couplings=ham.get("couplings"), sign=ham.get("sign", -1),
        topology=ham.get("topology", "chain"), shape=ham.get("shape"), edges=ham.get("edges"),
        qubit_features=ham.get("qubit_features"),
        coupler_features=ham.get("coupler_features"),
        group_column=options.get("group_column"), name=name, unit=options.get("unit"),
        prior_label=options.get("prior_label") or "prior")


register_source("google_5q", _google_5q)
register_source("ibm_gates", _ibm_gates)
register_source("csv", _csv)
