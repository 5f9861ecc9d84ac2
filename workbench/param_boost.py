"""The device for the parameter-space model: its coupling graph, spectrum and covariates.

:func:`device_model` is a device's spectrum as a parametric model (the Hamiltonian
``sign * H(theta)`` of a :class:`~workbench.hamiltonian.CouplingGraph`, ``edges``; default the
nearest-neighbour chain), optionally with *parasitic* couplings the control model lacks
(``parasitic``, :func:`resolve_graph`): extra edges whose control value is 0, optional
parameters that enter a fit only where its covariates name them. :func:`default_library`
names each parameter's default covariates from the graph (the parameter and its square, the
couplings touching a site, the detuning across a coupling, the geometric means
``sqrt|g_a g_b|`` of the couplings bridging a parasitic pair). The Hamiltonian family's
regressor, :class:`~workbench.param_regressor.HamiltonianParameterRegressor`, fits this model
with these covariates.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ._covariates import float_block
from .hamiltonian import PARASITIC_KINDS, CouplingGraph, HamiltonianModel

__all__ = ["default_library", "device_model",
           "parasitic_names", "resolve_graph"]


def _names(value: Any, what: str) -> list[str]:
    if value is None:
        return []
    if isinstance(value, str):
        raise ValueError(f"{what} must be a list of column names, got the string {value!r}")
    names = list(value)
    if not all(isinstance(v, str) for v in names):
        raise ValueError(f"{what} must be a list of column names (str), got {names!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"{what} contains duplicate names: {names}")
    return names


def _columns(X: pd.DataFrame, names: list[str], what: str) -> np.ndarray:
    present = [str(c) for c in X.columns]
    missing = [c for c in names if c not in present]
    if missing:
        raise ValueError(f"{what} column(s) {missing} are not columns of X; columns are: "
                         f"{present}")
    try:
        values = float_block(X, names)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} columns {names} must be numeric: {exc}") from None
    if not np.all(np.isfinite(values)):
        rows = np.flatnonzero(~np.isfinite(values).all(axis=1))[:10].tolist()
        raise ValueError(f"{what} columns contain NaN or infinite values (rows {rows})")
    return values


def resolve_graph(n_sites: int, edges: Iterable[Sequence[int]] | None = None,
                  parasitic: str | Iterable[Sequence[int]] | None = None
                  ) -> tuple[CouplingGraph, list[tuple[int, int]]]:
    """The control model's graph and the parasitic site pairs.

    Parameters
    ----------
    n_sites : int
        The number of sites.
    edges : iterable of (int, int), default=None
        The coupling graph's site pairs (``None``: the chain).
    parasitic : str or iterable of (int, int), default=None
        ``None`` or ``"none"``, ``"next_nearest"``, ``"diagonal"`` or a list of site pairs.

    Returns
    -------
    graph : CouplingGraph
        The control model's graph.
    pairs : list of (int, int)
        The parasitic site pairs.
    """
    graph = CouplingGraph.chain(n_sites) if edges is None else \
        CouplingGraph.from_edges(n_sites, edges)
    if parasitic is None:
        return graph, []
    if isinstance(parasitic, str):
        if parasitic not in PARASITIC_KINDS:
            raise ValueError(f"unknown parasitic {parasitic!r}; valid: a list of site pairs "
                             f"or one of {', '.join(PARASITIC_KINDS)}")
        pairs = graph.parasitic_edges(parasitic)
    else:
        pairs = [(int(i), int(j)) for i, j in graph.with_edges(parasitic).edges[
            graph.n_edges:]]
    return graph, pairs


def parasitic_names(onsite: Iterable[str], pairs: Iterable[tuple[int, int]]) -> list[str]:
    """Names of parasitic couplings between sites ``(i, j)``: ``"<onsite_i>~<onsite_j>"``.

    Parameters
    ----------
    onsite : iterable of str
        The onsite parameters' names, in site order.
    pairs : iterable of (int, int)
        The parasitic site pairs.

    Returns
    -------
    list of str
        One name per pair.
    """
    on = list(onsite)
    return [f"{on[i]}~{on[j]}" for i, j in pairs]


def device_model(onsite: Sequence[str], couplings: Sequence[str],
                 edges: Iterable[Sequence[int]] | None = None,
                 parasitic: str | Iterable[Sequence[int]] | None = None,
                 sign: int = -1) -> HamiltonianModel:
    """The device's spectrum as a parametric model with every parasitic coupling optional.

    Each parasitic coupling (named by :func:`parasitic_names`) starts at 0 and is in the
    model only where a fit's covariates name it (:meth:`HamiltonianModel.restricted`), as
    :class:`~workbench.param_regressor.HamiltonianParameterRegressor` (a
    :class:`~workbench.param_regressor.ParametricRegressor` with this model) fits it.

    Parameters
    ----------
    onsite, couplings : sequence of str
        The onsite and control coupling columns, in site and edge order.
    edges : iterable of (int, int), default=None
        The control graph (None: the chain).
    parasitic : str or iterable of (int, int), default=None
        The parasitic couplings, as :func:`resolve_graph` reads them.
    sign : {-1, 1}, default=-1
        The spectrum is that of ``sign * H``.

    Returns
    -------
    HamiltonianModel
        The model, its parasitic couplings last.
    """
    graph, pairs = resolve_graph(len(onsite), edges, parasitic)
    return HamiltonianModel(tuple(onsite), tuple(couplings), graph.with_edges(pairs),
                            tuple(parasitic_names(onsite, pairs)), sign)


def _detuning(on: Sequence[str], i: int, j: int) -> str:
    return f"{on[min(i, j)]}-{on[max(i, j)]}"


def _geomean(a: str, b: str) -> str:
    return f"sqrt|{a}*{b}|"


def _bridges(graph: CouplingGraph, couplings: Iterable[str], i: int, j: int) -> list[str]:
    """``sqrt|g_a*g_b|`` of each two-edge path ``i - m - j`` of the control graph."""
    co = list(couplings)
    return [_geomean(co[a], co[b]) for a, b in graph.paths2(i, j)]


def default_library(onsite: Iterable[str], couplings: Iterable[str],
                    edges: Iterable[Sequence[int]] | None = None,
                    parasitic: str | Iterable[Sequence[int]] | None = None
                    ) -> dict[str, list[str]]:
    """The default covariates of each parameter (besides the intercept).

    Onsite ``f_i``: ``f_i``, ``f_i^2`` and each coupling touching site ``i`` with its square.
    Coupling ``g_e`` (``e = (i, j)``): ``g_e``, ``g_e^2`` and the detuning ``f_i-f_j``.
    Parasitic coupling ``(i, j)``: the geometric mean ``sqrt|g_a*g_b|`` of each pair of
    couplings bridging it.

    Parameters
    ----------
    onsite : iterable of str
        The onsite parameters' names, in site order.
    couplings : iterable of str
        The couplings' names, in edge order.
    edges : iterable of (int, int), default=None
        The coupling graph's site pairs (``None``: the chain).
    parasitic : str or iterable of (int, int), default=None
        The parasitic couplings, as :func:`resolve_graph` reads them.

    Returns
    -------
    dict of str to list of str
        Parameter name -> its covariates' names.
    """
    on, co = list(onsite), list(couplings)
    graph, pairs = resolve_graph(len(on), edges, parasitic)
    if len(co) != graph.n_edges:
        raise ValueError(f"couplings must name {graph.n_edges} columns, one per edge, got "
                         f"{len(co)}")
    lib = {}
    for i, p in enumerate(on):
        nb = [co[e] for e in graph.site_edges(i)]
        lib[p] = [p, f"{p}^2"] + [n for g in nb for n in (g, f"{g}^2")]
    for e, p in enumerate(co):
        i, j = graph.edges[e]
        lib[p] = [p, f"{p}^2", _detuning(on, i, j)]
    for (i, j), p in zip(pairs, parasitic_names(on, pairs)):
        lib[p] = _bridges(graph, co, i, j)
    return lib
