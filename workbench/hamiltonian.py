"""Single-excitation Hamiltonians on a coupling graph: batched construction, spectrum, Jacobian.

A device of N sites with a :class:`CouplingGraph` of E edges ``(i, j)`` has parameters
``theta = (f_1..f_N, g_1..g_E)``: onsite energies on the diagonal of ``H`` and couplings
``g_e = H[i, j] = H[j, i]`` for edge ``e = (i, j)``. The nearest-neighbour chain
(:meth:`CouplingGraph.chain`, edges ``(i, i+1)``) is the default; rings, 2-D grids and
explicit edge lists work the same way. The spectrum of interest is the ascending eigenvalues
of ``sign * H`` (``sign = -1`` for the project's data).

Derivatives follow from Hellmann-Feynman. With ``M = sign * H`` and unit eigenvector ``u_k``
(the same for ``M`` and ``H``), ``d lambda_k / d theta = u_k^T (dM / d theta) u_k``, so::

    d lambda_k / d f_i = sign * u_ik^2
    d lambda_k / d g_e = sign * 2 u_ik u_jk       (e = (i, j))

At an exact degeneracy the eigenvalues are not differentiable; the values returned are the
derivatives of the sorted eigenvalue branch whose eigenvectors ``numpy.linalg.eigh`` chose.
They are always finite (eigh never returns NaN for finite input).
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._covariates import float_block
from .parametric import ModelError, _restricted

__all__ = ["TOPOLOGIES", "CouplingGraph", "HamiltonianModel", "chain_hamiltonian", "chain_spectrum",
           "graph_hamiltonian", "graph_spectrum", "make_graph"]

#: Named topologies of :func:`make_graph`.
TOPOLOGIES = ("chain", "ring", "grid")
#: Kinds of parasitic (model-less) edges of :meth:`CouplingGraph.parasitic_edges`.
PARASITIC_KINDS = ("none", "next_nearest", "diagonal")


def _int(value: Any, what: str, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        raise ValueError(f"{what} must be an integer >= {low}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class CouplingGraph:
    """Sites ``0..n_sites-1`` and the couplings between them (edges, in parameter order).

    Build one with :meth:`chain`, :meth:`ring`, :meth:`grid` or :meth:`from_edges` (which
    check it).

    Parameters
    ----------
    n_sites : int
        The number of sites.
    edges : tuple of (int, int)
        The coupled site pairs, in parameter order.
    topology : str, default="edges"
        ``"chain"``, ``"ring"``, ``"grid"`` or ``"edges"`` (an explicit list).
    shape : (int, int), default=None
        ``(rows, cols)`` for a grid (site ``r * cols + c``), else ``None``.
    """

    n_sites: int
    edges: tuple[tuple[int, int], ...]
    topology: str = "edges"
    shape: tuple[int, int] | None = None

    # ------------------------------------------------------------------ constructors
    @classmethod
    def chain(cls, n: int) -> CouplingGraph:
        """Nearest-neighbour chain: edges ``(0, 1), (1, 2), ..., (n-2, n-1)``.

        Parameters
        ----------
        n : int
            The number of sites, 2 or more.

        Returns
        -------
        CouplingGraph
            The graph.
        """
        n = _int(n, "a chain's number of sites", 2)
        return cls(n, tuple((i, i + 1) for i in range(n - 1)), "chain")

    @classmethod
    def ring(cls, n: int) -> CouplingGraph:
        """Ring: the chain's edges and ``(n-1, 0)``.

        Parameters
        ----------
        n : int
            The number of sites, 3 or more.

        Returns
        -------
        CouplingGraph
            The graph.
        """
        n = _int(n, "a ring's number of sites", 3)
        return cls(n, tuple((i, (i + 1) % n) for i in range(n)), "ring")

    @classmethod
    def grid(cls, rows: int, cols: int) -> CouplingGraph:
        """``rows x cols`` square lattice, site ``r * cols + c``; the horizontal edges row by
        row, then the vertical edges row by row.

        Parameters
        ----------
        rows, cols : int
            The lattice's shape, 2 sites or more.

        Returns
        -------
        CouplingGraph
            The graph.
        """
        rows, cols = _int(rows, "grid rows", 1), _int(cols, "grid cols", 1)
        if rows * cols < 2:
            raise ValueError(f"a grid needs at least 2 sites, got shape {rows}x{cols}")
        horizontal = [(r * cols + c, r * cols + c + 1)
                      for r in range(rows) for c in range(cols - 1)]
        vertical = [(r * cols + c, (r + 1) * cols + c)
                    for r in range(rows - 1) for c in range(cols)]
        return cls(rows * cols, tuple(horizontal + vertical), "grid", (rows, cols))

    @classmethod
    def from_edges(cls, n_sites: int, edges: Iterable[Sequence[int]]) -> CouplingGraph:
        """Any graph: ``edges`` a list of site pairs ``[i, j]`` (0-based).

        Parameters
        ----------
        n_sites : int
            The number of sites, 2 or more.
        edges : iterable of (int, int)
            The coupled site pairs, none twice and no self-loop.

        Returns
        -------
        CouplingGraph
            The graph.
        """
        n = _int(n_sites, "n_sites", 2)
        graph = cls(n, _check_edges(n, edges), "edges")
        return graph

    # ------------------------------------------------------------------ structure
    @property
    def n_edges(self) -> int:
        """The number of edges."""
        return len(self.edges)

    def site_edges(self, i: int) -> list[int]:
        """Indices of the edges touching site ``i``.

        Parameters
        ----------
        i : int
            The site.

        Returns
        -------
        list of int
            The edges' indices, ascending.
        """
        return [e for e, (a, b) in enumerate(self.edges) if i in (a, b)]

    def neighbours(self, i: int) -> list[int]:
        """Sites coupled to site ``i``, ascending.

        Parameters
        ----------
        i : int
            The site.

        Returns
        -------
        list of int
            The neighbouring sites.
        """
        return sorted({b if a == i else a for a, b in self.edges if i in (a, b)})

    def edge_neighbours(self, e: int) -> list[int]:
        """Indices of the other edges sharing a site with edge ``e``.

        Parameters
        ----------
        e : int
            The edge's index.

        Returns
        -------
        list of int
            The other edges' indices, ascending.
        """
        a, b = self.edges[e]
        return [k for k, (c, d) in enumerate(self.edges) if k != e and {a, b} & {c, d}]

    def edge_index(self, i: int, j: int) -> int | None:
        """Index of the edge between ``i`` and ``j`` (either order), or None.

        Parameters
        ----------
        i, j : int
            The sites.

        Returns
        -------
        int or None
            The edge's index; ``None``: the sites are not coupled.
        """
        for e, pair in enumerate(self.edges):
            if set(pair) == {i, j}:
                return e
        return None

    def paths2(self, i: int, j: int) -> list[tuple[int, int]]:
        """Pairs of edge indices ``(e1, e2)`` forming a path ``i - m - j`` of two edges.

        Parameters
        ----------
        i, j : int
            The path's ends.

        Returns
        -------
        list of (int, int)
            One pair per middle site ``m``, by ascending ``m``.
        """
        out = []
        for m in self.neighbours(i):
            if m != j and j in self.neighbours(m):
                e1, e2 = self.edge_index(i, m), self.edge_index(m, j)
                assert e1 is not None and e2 is not None  # m neighbours both i and j
                out.append((e1, e2))
        return out

    def parasitic_edges(self, kind: str) -> list[tuple[int, int]]:
        """Site pairs the graph lacks, coupled only through a shared neighbour.

        ``"next_nearest"``: every pair at graph distance 2 (chain: ``(i, i+2)``; grid:
        diagonals and straight two-steps). ``"diagonal"``: pairs joined by two different
        two-edge paths (the grid's diagonals). ``"none"``: no pair.

        Parameters
        ----------
        kind : {"next_nearest", "diagonal", "none"}
            Which pairs.

        Returns
        -------
        list of (int, int)
            The pairs ``(i, j)``, ``i < j``, in ascending order.

        Raises
        ------
        ValueError
            An unknown ``kind``, listing the valid ones.
        """
        if kind not in PARASITIC_KINDS:
            raise ValueError(f"unknown parasitic coupling kind {kind!r}; valid: "
                             f"{', '.join(PARASITIC_KINDS)}")
        if kind == "none":
            return []
        out = []
        for i in range(self.n_sites):
            for j in range(i + 1, self.n_sites):
                if self.edge_index(i, j) is not None:
                    continue
                paths = self.paths2(i, j)
                if (kind == "next_nearest" and paths) or (kind == "diagonal" and len(paths) >= 2):
                    out.append((i, j))
        return out

    def with_edges(self, extra: Iterable[Sequence[int]]) -> CouplingGraph:
        """Return the graph with the ``extra`` edges appended, in order.

        Parameters
        ----------
        extra : iterable of (int, int)
            The edges to add (none already in the graph).

        Returns
        -------
        CouplingGraph
            A new graph of topology ``"edges"``.
        """
        return CouplingGraph(self.n_sites, _check_edges(self.n_sites, [*self.edges, *extra]),
                             "edges")

    def to_dict(self) -> dict:
        """Write the graph as JSON-ready data.

        Returns
        -------
        dict
            ``topology``, ``n_sites``, ``shape`` (or ``None``) and ``edges`` (pairs as lists).
        """
        return {"topology": self.topology, "n_sites": self.n_sites,
                "shape": list(self.shape) if self.shape else None,
                "edges": [list(e) for e in self.edges]}


def _check_edges(n: int, edges: Any) -> tuple[tuple[int, int], ...]:
    if isinstance(edges, (str, bytes)) or not hasattr(edges, "__iter__"):
        raise ValueError(f"edges must be a list of site pairs [i, j], got {edges!r}")
    out, seen = [], set()
    for k, pair in enumerate(edges):
        pair = list(pair) if hasattr(pair, "__iter__") and not isinstance(pair, str) else pair
        if (not isinstance(pair, list) or len(pair) != 2
                or not all(isinstance(v, numbers.Integral) and not isinstance(v, bool)
                           for v in pair)):
            raise ValueError(f"edge {k} must be a pair of site indices [i, j], got {pair!r}")
        i, j = int(pair[0]), int(pair[1])
        if not (0 <= i < n and 0 <= j < n):
            raise ValueError(f"edge {k} [{i}, {j}] is out of range: sites are 0..{n - 1}")
        if i == j:
            raise ValueError(f"edge {k} [{i}, {j}] is a self-loop (onsite terms are not edges)")
        key = frozenset((i, j))
        if key in seen:
            raise ValueError(f"edge {k} [{i}, {j}] is a duplicate")
        seen.add(key)
        out.append((i, j))
    return tuple(out)


def make_graph(n_sites: int | None = None, topology: str = "chain",
               shape: Any = None,
               edges: Iterable[Sequence[int]] | None = None) -> CouplingGraph:
    """A graph from config-style settings: a topology or an explicit list of edges.

    Parameters
    ----------
    n_sites : int, default=None
        The number of sites; with ``edges`` or a grid, it must match them if given.
    topology : {"chain", "ring", "grid"}, default="chain"
        The graph's shape (with ``edges``: ignored).
    shape : (int, int), default=None
        ``(rows, cols)`` of a grid.
    edges : iterable of (int, int), default=None
        An explicit list of coupled site pairs.

    Returns
    -------
    CouplingGraph
        The graph.

    Raises
    ------
    ValueError
        An unknown topology, a shape without a grid or a grid without one, or a number of
        sites that does not match.
    """
    if edges is not None:
        if n_sites is None:
            flat = [v for e in edges for v in e]
            n_sites = max(flat) + 1 if flat else 0
        return CouplingGraph.from_edges(n_sites, edges)
    if topology not in TOPOLOGIES:
        raise ValueError(f"unknown topology {topology!r}; valid: {', '.join(TOPOLOGIES)}")
    if topology == "grid":
        if shape is None or len(shape) != 2:
            raise ValueError(f"topology grid needs shape = [rows, cols], got {shape!r}")
        graph = CouplingGraph.grid(*shape)
    else:
        if shape is not None:
            raise ValueError(f"shape is only for topology grid, got shape {shape!r} with "
                             f"topology {topology}")
        if n_sites is None:
            raise ValueError(f"topology {topology} needs the number of sites")
        graph = getattr(CouplingGraph, topology)(n_sites)
    if n_sites is not None and graph.n_sites != n_sites:
        raise ValueError(f"grid shape {shape[0]}x{shape[1]} has {graph.n_sites} sites, but "
                         f"there are {n_sites} onsite columns")
    return graph


def _check(onsite: ArrayLike, couplings: ArrayLike, graph: CouplingGraph | None
           ) -> tuple[np.ndarray, np.ndarray, CouplingGraph]:
    f = np.asarray(onsite, dtype=float)
    g = np.asarray(couplings, dtype=float)
    if f.ndim != 2:
        raise ValueError(f"onsite must be 2-D (n_examples, n_sites), got shape {f.shape}")
    if g.ndim != 2:
        raise ValueError("couplings must be 2-D (n_examples, n_edges), got shape "
                         f"{g.shape}")
    n, N = f.shape
    if graph is None:
        if N < 2:
            raise ValueError(f"a chain needs at least 2 sites; onsite has {N} column(s)")
        graph = CouplingGraph.chain(N)
        if g.shape != (n, N - 1):
            raise ValueError(f"couplings must have shape (n_examples, n_sites - 1) = "
                             f"({n}, {N - 1}) to match onsite {f.shape}, got {g.shape}")
    elif not isinstance(graph, CouplingGraph):
        raise ValueError(f"graph must be a CouplingGraph, got {type(graph).__name__}")
    elif graph.n_sites != N:
        raise ValueError(f"the graph has {graph.n_sites} sites but onsite has {N} columns")
    elif g.shape != (n, graph.n_edges):
        raise ValueError(f"couplings must have shape (n_examples, n_edges) = "
                         f"({n}, {graph.n_edges}) to match onsite {f.shape} and the graph, "
                         f"got {g.shape}")
    for name, a in (("onsite", f), ("couplings", g)):
        if not np.all(np.isfinite(a)):
            rows = np.flatnonzero(~np.isfinite(a).all(axis=1))[:10].tolist()
            raise ValueError(f"{name} contains NaN or infinite values (rows {rows})")
    return f, g, graph


def _check_sign(sign: Any) -> int:
    if isinstance(sign, bool) or not isinstance(sign, numbers.Real) or sign not in (-1, 1):
        raise ValueError(f"sign must be -1 or 1, got {sign!r}")
    return 1 if sign == 1 else -1


def _build(f: np.ndarray, g: np.ndarray, graph: CouplingGraph,
           out: np.ndarray | None = None) -> np.ndarray:
    n, N = f.shape
    h = np.zeros((n, N, N)) if out is None else out
    d = np.arange(N)
    h[:, d, d] = f
    if graph.n_edges:
        a = np.fromiter((e[0] for e in graph.edges), int, graph.n_edges)
        b = np.fromiter((e[1] for e in graph.edges), int, graph.n_edges)
        h[:, a, b] = g
        h[:, b, a] = g
    return h


def graph_hamiltonian(onsite: ArrayLike, couplings: ArrayLike,
                      graph: CouplingGraph | None = None) -> np.ndarray:
    """Hamiltonians, shape ``(n, N, N)``, on a coupling graph.

    Parameters
    ----------
    onsite : array-like of shape (n, N)
        The diagonal entries.
    couplings : array-like of shape (n, E)
        One coupling per edge of ``graph``.
    graph : CouplingGraph, default=None
        The graph (``None``: the chain).

    Returns
    -------
    ndarray of shape (n, N, N)
        The symmetric Hamiltonians.
    """
    f, g, graph = _check(onsite, couplings, graph)
    return _build(f, g, graph)


def graph_spectrum(onsite: ArrayLike, couplings: ArrayLike, graph: CouplingGraph | None = None,
                   sign: int = -1, *, jacobian: bool = True, chunk_elements: int = 8_000_000,
                   out: np.ndarray | None = None) -> Any:  # a pair when jacobian, else one
    """Ascending eigenvalues of ``sign * H`` and (``jacobian=True``) their Jacobian.

    Parameters
    ----------
    onsite : array-like of shape (n, N)
        The diagonal entries.
    couplings : array-like of shape (n, E)
        One coupling per edge of ``graph``.
    graph : CouplingGraph, default=None
        The graph (``None``: the chain).
    sign : int, default=-1
        The sign of ``H``.
    jacobian : bool, default=True
        Whether to compute the Jacobian.
    chunk_elements : int, default=8_000_000
        The examples are diagonalised in chunks of about this many matrix entries.
    out : ndarray, default=None
        An array of the Jacobian's shape to write it into (reused memory).

    Returns
    -------
    eigenvalues : ndarray of shape (n, N)
        Each example's eigenvalues, ascending.
    jacobian : ndarray of shape (n, N, N + E)
        ``jacobian[j, k, p] = d lambda_k / d theta_p`` for example ``j``, with
        ``theta = (onsite_1..onsite_N, coupling_1..coupling_E)``. Only when ``jacobian``.
    """
    sign = _check_sign(sign)
    f, g, graph = _check(onsite, couplings, graph)
    n, N = f.shape
    E = graph.n_edges
    a = np.fromiter((e[0] for e in graph.edges), int, E)
    b = np.fromiter((e[1] for e in graph.edges), int, E)
    lam = np.empty((n, N))
    jac = None
    if jacobian:
        shape = (n, N, N + E)
        jac = out if isinstance(out, np.ndarray) and out.shape == shape else np.empty(shape)
    step = max(1, chunk_elements // (N * N))
    for s in range(0, n, step):
        sl = slice(s, min(n, s + step))
        h = _build(f[sl], g[sl], graph)
        if sign == -1:
            np.negative(h, out=h)
        if not jacobian:
            lam[sl] = np.linalg.eigvalsh(h)
            continue
        lam[sl], vec = np.linalg.eigh(h)  # vec[j, i, k] = u_ik, ascending lam
        assert jac is not None  # made above when jacobian
        _hellmann_feynman(vec, sign, a, b, jac[sl])
    return (lam, jac) if jacobian else lam


def _hellmann_feynman(vec: np.ndarray, sign: int, a: np.ndarray, b: np.ndarray, out: np.ndarray,
                      block_elements: int = 1_000_000) -> np.ndarray:
    """``out[j, k, :] = d lambda_k / d theta`` from eigenvectors ``vec[j, i, k] = u_ik``:
    ``sign * u_ik^2`` for the onsite terms, ``2 sign u_ak u_bk`` for the couplings (a, b).
    Written through the transposed eigenvectors ``u[j, k, i]`` (contiguous in the site), so
    both products are contiguous in ``out``, over blocks of rows whose temporaries hold
    about ``block_elements`` numbers (large fresh arrays cost page faults)."""
    n, N = vec.shape[:2]
    rows = max(1, block_elements // (N * max(N, len(a), 1)))
    for s in range(0, n, rows):
        sl = slice(s, min(n, s + rows))
        vt = np.ascontiguousarray(np.swapaxes(vec[sl], 1, 2))
        np.multiply(vt, sign * vt, out=out[sl, :, :N])
        if len(a):
            np.multiply(np.take(vt, a, axis=2), (2.0 * sign) * np.take(vt, b, axis=2),
                        out=out[sl, :, N:])
    return out


def chain_hamiltonian(onsite: ArrayLike, couplings: ArrayLike) -> np.ndarray:
    """Tridiagonal Hamiltonians, shape ``(n, N, N)``, of chains.

    Parameters
    ----------
    onsite : array-like of shape (n, N)
        The diagonal entries (an array or a DataFrame).
    couplings : array-like of shape (n, N - 1)
        The nearest-neighbour couplings.

    Returns
    -------
    ndarray of shape (n, N, N)
        The tridiagonal Hamiltonians.
    """
    return graph_hamiltonian(onsite, couplings, None)


def chain_spectrum(onsite: ArrayLike, couplings: ArrayLike,
                   sign: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Ascending eigenvalues of ``sign * H`` of a chain and their Jacobian, shape
    ``(n, N, 2N - 1)`` (see :func:`graph_spectrum`).

    Parameters
    ----------
    onsite : array-like of shape (n, N)
        The diagonal entries.
    couplings : array-like of shape (n, N - 1)
        The nearest-neighbour couplings.
    sign : int, default=-1
        The sign of ``H``.

    Returns
    -------
    eigenvalues : ndarray of shape (n, N)
        Ascending.
    jacobian : ndarray of shape (n, N, 2N - 1)
        Their derivatives by the onsite terms, then the couplings.
    """
    return graph_spectrum(onsite, couplings, None, sign)


@dataclass(frozen=True, eq=False)
class HamiltonianModel:
    """A device's spectrum as a physics model in the parametric contract.

    The parameters are the onsite energies and the couplings of ``graph``'s edges, in that
    order (:mod:`workbench.parametric`'s model object: ``names``, ``parameters``,
    ``start``, ``predict``, ``jacobian``); ``predict`` is the ascending eigenvalues of
    ``sign * H(theta)`` and ``jacobian`` their analytic Hellmann-Feynman derivatives (no
    finite differences), ``predict_and_jacobian`` both from one eigendecomposition.
    Each onsite and control coupling starts at the data column of its name (the control
    program's value); a parasitic coupling (an edge the control model lacks) starts at 0.
    :class:`~workbench.param_regressor.ParametricRegressor` (the Hamiltonian family's
    :class:`~workbench.param_regressor.HamiltonianParameterRegressor` among its uses) fits
    its drifts.

    Parameters
    ----------
    onsite : tuple of str
        The onsite parameters (data columns), in site order.
    couplings : tuple of str
        The control couplings (data columns), one per edge of ``graph`` after the sites',
        in edge order.
    graph : CouplingGraph
        The device: the control edges, then the parasitic ones.
    parasitic : tuple of str, default=()
        The parasitic couplings' names, one per edge of ``graph`` beyond ``couplings``.
    sign : {-1, 1}, default=-1
        The spectrum is that of ``sign * H``.
    """

    onsite: tuple[str, ...]
    couplings: tuple[str, ...]
    graph: CouplingGraph
    parasitic: tuple[str, ...] = ()
    sign: int = -1

    def __post_init__(self) -> None:
        """Check that the names match the graph's sites and edges."""
        if not isinstance(self.graph, CouplingGraph):
            raise ValueError(f"graph must be a CouplingGraph, got {type(self.graph).__name__}")
        if len(self.onsite) != self.graph.n_sites:
            raise ValueError(f"the graph has {self.graph.n_sites} sites but {len(self.onsite)} "
                             "onsite names")
        if len(self.couplings) + len(self.parasitic) != self.graph.n_edges:
            raise ValueError(f"the graph has {self.graph.n_edges} edges but "
                             f"{len(self.couplings)} couplings and {len(self.parasitic)} "
                             "parasitic couplings")
        _check_sign(self.sign)

    @classmethod
    def chain(cls, onsite: Sequence[str], couplings: Sequence[str],
              sign: int = -1) -> HamiltonianModel:
        """The nearest-neighbour chain of ``onsite`` sites.

        Parameters
        ----------
        onsite : sequence of str
            The sites' onsite parameter columns (N names).
        couplings : sequence of str
            The couplings' columns (N - 1 names).
        sign : int, default=-1
            The spectrum's sign convention.

        Returns
        -------
        HamiltonianModel
            The chain's model.
        """
        return cls(tuple(onsite), tuple(couplings), CouplingGraph.chain(len(onsite)), (), sign)

    @property
    def source(self) -> str:
        """How messages name the model."""
        return f"hamiltonian ({self.graph.topology}, {self.graph.n_sites} sites)"

    @property
    def names(self) -> list[str]:
        """The parameters' names: onsite, couplings, parasitic couplings."""
        return [*self.onsite, *self.couplings, *self.parasitic]

    @property
    def parameters(self) -> dict[str, float | str]:
        """Each parameter's start: its data column, or 0.0 for a parasitic coupling."""
        return {**{p: p for p in (*self.onsite, *self.couplings)},
                **{p: 0.0 for p in self.parasitic}}

    @property
    def optional(self) -> tuple[str, ...]:
        """The parasitic couplings: terms the control model lacks (the contract's
        ``OPTIONAL``), each in the model only where a fit's covariates name it."""
        return self.parasitic

    def restricted(self, keep: Sequence[str]) -> HamiltonianModel:
        """The model with only the parasitic couplings ``keep`` names (the others left out
        of the graph: held at 0).

        Parameters
        ----------
        keep : sequence of str
            The parameters to fit: every onsite and control coupling, and the parasitic
            couplings to include.

        Returns
        -------
        HamiltonianModel
            The same device with fewer parasitic edges (the same object for the same
            ``keep``).
        """
        def build(held: tuple[str, ...]) -> HamiltonianModel:
            control = len(self.couplings)
            kept = [(name, edge) for name, edge in zip(self.parasitic,
                                                       self.graph.edges[control:], strict=True)
                    if name not in held]
            graph = CouplingGraph(self.graph.n_sites, self.graph.edges[:control],
                                  self.graph.topology, self.graph.shape).with_edges(
                [edge for _, edge in kept]) if held else self.graph
            return HamiltonianModel(self.onsite, self.couplings, graph,
                                    tuple(name for name, _ in kept), self.sign)

        return _restricted(self, keep, build)

    def __repr__(self) -> str:
        """The model's source and parameters."""
        return f"HamiltonianModel({self.source!r}, parameters={self.names})"

    def start(self, data: Any) -> np.ndarray:
        """The control values of every row (0 for the parasitic couplings).

        Parameters
        ----------
        data : DataFrame
            The rows, with the onsite and coupling columns.

        Returns
        -------
        ndarray of shape (rows, parameters)
            The start values.
        """
        control = [*self.onsite, *self.couplings]
        missing = [c for c in control if c not in data.columns]
        if missing:
            raise ModelError(f"model {self.source}: the data lack the parameter column(s) "
                               f"{missing}")
        out = np.zeros((len(data), len(self.names)))
        try:
            out[:, :len(control)] = float_block(data, control)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"model {self.source}: the parameter columns must be numeric: "
                               f"{exc}") from None
        if not np.all(np.isfinite(out)):
            raise ModelError(f"model {self.source}: the parameter columns have missing "
                               "values")
        return out

    def _targets(self, n_targets: int | None) -> None:
        if n_targets is not None and n_targets != self.graph.n_sites:
            raise ModelError(f"model {self.source}: its spectrum has {self.graph.n_sites} "
                               f"eigenvalues, not {n_targets} targets")

    def predict(self, theta: np.ndarray, data: Any = None,
                n_targets: int | None = None) -> np.ndarray:
        """Ascending eigenvalues of ``sign * H(theta)``.

        Parameters
        ----------
        theta : ndarray of shape (rows, parameters)
            The parameters per row, in :attr:`names`' order.
        data : DataFrame, optional
            The rows' data (unused: the spectrum depends on ``theta`` alone).
        n_targets : int, optional
            The number of targets the caller expects (checked against the sites).

        Returns
        -------
        ndarray of shape (rows, sites)
            The eigenvalues.
        """
        self._targets(n_targets)
        N = self.graph.n_sites
        return graph_spectrum(theta[:, :N], theta[:, N:], self.graph, self.sign,
                              jacobian=False)

    def predict_and_jacobian(self, theta: np.ndarray, data: Any = None,
                             n_targets: int | None = None,
                             out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The eigenvalues and their Hellmann-Feynman Jacobian from one eigendecomposition.

        Parameters
        ----------
        theta : ndarray of shape (rows, parameters)
            The parameters per row, in :attr:`names`' order.
        data : DataFrame, optional
            The rows' data (unused: the spectrum depends on ``theta`` alone).
        n_targets : int, optional
            The number of targets the caller expects (checked against the sites).
        out : ndarray of shape (rows, sites, parameters), optional
            An array to write the Jacobian into.

        Returns
        -------
        eigenvalues : ndarray of shape (rows, sites)
            As :meth:`predict`'s.
        jacobian : ndarray of shape (rows, sites, parameters)
            As :meth:`jacobian`'s.
        """
        self._targets(n_targets)
        N = self.graph.n_sites
        return graph_spectrum(theta[:, :N], theta[:, N:], self.graph, self.sign,
                              jacobian=True, out=out)

    def jacobian(self, theta: np.ndarray, data: Any = None,
                 n_targets: int | None = None) -> np.ndarray:
        """``d eigenvalues / d theta`` (Hellmann-Feynman).

        Parameters
        ----------
        theta : ndarray of shape (rows, parameters)
            The parameters per row, in :attr:`names`' order.
        data : DataFrame, optional
            The rows' data (unused: the spectrum depends on ``theta`` alone).
        n_targets : int, optional
            The number of targets the caller expects (checked against the sites).

        Returns
        -------
        ndarray of shape (rows, sites, parameters)
            The Jacobian.
        """
        return self.predict_and_jacobian(theta, data, n_targets)[1]

    def file_functions(self) -> tuple[dict[str, float | str], Any, Any]:
        """``(PARAMETERS, predict, jacobian)`` of a model file (the contract's functions of
        ``params``, a dict of per-row arrays, and ``data``), e.g. for
        :meth:`workbench.parametric.ParametricModel.from_functions`.

        Returns
        -------
        parameters : dict
            Each parameter's start (:attr:`parameters`).
        predict : callable
            ``predict(params, data)``.
        jacobian : callable
            ``jacobian(params, data)``.
        """
        names = self.names

        def stack(params: dict[str, Any]) -> np.ndarray:
            return np.column_stack([np.asarray(params[p], dtype=float) for p in names])

        def predict(params: dict[str, Any], data: Any) -> np.ndarray:
            return self.predict(stack(params), data)

        def jacobian(params: dict[str, Any], data: Any) -> np.ndarray:
            return self.jacobian(stack(params), data)

        return self.parameters, predict, jacobian
