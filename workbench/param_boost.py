"""Boosting in the control model's parameter space: correct the Hamiltonian, not the eigenvalues.

:class:`HamiltonianParameterRegressor` predicts all N eigenvalues of a chain at once as the
ascending eigenvalues of ``sign * H(theta(x) + delta(x))``, where ``theta(x)`` are the control
model's onsite frequencies and couplings (columns of ``X``) and the correction of each
parameter ``p`` is linear in a small covariate library, ``delta_p(x) = phi_p(x) . c_p``.
The coefficients are fitted by (robust, regularised) Gauss-Newton with an exact
re-diagonalisation at every iteration; the Jacobian comes from Hellmann-Feynman
(:func:`workbench.hamiltonian.graph_spectrum`). It is the parametric family's regressor
(:class:`workbench.param_regressor.ParametricRegressor`: its covariates, its fit) with the
device's spectrum as the model (:func:`device_model`), its covariates named from the coupling
graph (:func:`default_library`), no calibration step and IRLS weights by default.

The device is any :class:`~workbench.hamiltonian.CouplingGraph` (``edges``; default the
nearest-neighbour chain), optionally with *parasitic* couplings the control model lacks
(``parasitic``): extra edges whose control value is 0 and whose coupling is, like every other
parameter's correction, linear in covariates (by default the geometric means
``sqrt|g_a g_b|`` of the pairs of couplings that bridge them).
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Sequence
from typing import Any, Self, cast

import numpy as np
import pandas as pd
from sklearn.utils._param_validation import Options, StrOptions
from sklearn.utils.validation import check_is_fitted

from ._covariates import variable
from .hamiltonian import PARASITIC_KINDS, CouplingGraph, HamiltonianModel
from .param_regressor import ParametricRegressor
from .parametric import restrict

__all__ = ["HamiltonianParameterRegressor", "default_library", "device_model",
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
    position = {str(c): i for i, c in enumerate(X.columns)}
    missing = [c for c in names if c not in position]
    if missing:
        raise ValueError(f"{what} column(s) {missing} are not columns of X; columns are: "
                         f"{list(position)}")
    index = [position[c] for c in names]
    try:  # fast path: an all-numeric frame converts as one block
        values = X.to_numpy(dtype=float)[:, index]
    except (TypeError, ValueError):
        try:
            values = X.iloc[:, index].to_numpy(dtype=float)
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
    :class:`HamiltonianParameterRegressor` and a
    :class:`~workbench.parametric_boost.ParametricRegressor` with this model fit it alike.

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


class HamiltonianParameterRegressor(ParametricRegressor):
    """Multi-output regressor of a device's N eigenvalues via corrections of its Hamiltonian.

    ``predict(X)`` = ascending eigenvalues of ``sign * H(theta(X) + delta(X))`` with
    ``theta = X[onsite + couplings]`` (and 0 for each active parasitic coupling) and
    ``delta_p(x) = phi_p(x) . c_p`` for each parameter ``p``.

    The covariates ``phi_p`` of parameter ``p`` are an intercept (never penalised) and the
    covariates that ``covariates`` names for ``p``, in the parametric regressor's language
    (:mod:`workbench._covariates`). A covariate is a *variable* optionally raised to a power
    (``"f1^2"``); a variable is a column of ``X`` (the control parameters are columns; e.g.
    voltages), or of two columns the difference ``"a-b"`` (a detuning ``"f_i-f_j"``), the
    geometric mean ``"sqrt|a*b|"`` (of two couplings sharing a site) or the product
    ``"a*b"`` (each factor centred by its training mean first; e.g. a qubit's bias times a
    neighbouring bias line, the first-order frequency change from flux crosstalk). Every
    variable is centred by its training mean
    before the power is taken; every covariate is then standardised with its training mean and
    sd (sd 0 -> 1), so a coefficient is in the targets' units (MHz) per standard deviation of
    its covariate.

    Fitting minimises ``sum rho(y - lambda) + alpha / 2 * ||c||^2 + alpha_l1 * ||c||_1``
    (intercepts excluded from both penalties), ``rho`` one of
    :data:`~workbench.param_engine.PARAM_LOSSES` (``r^2 / 2``, ``|r|`` or Huber), by
    Gauss-Newton with IRLS weights:
    ``(A^T W A + alpha D) dc = A^T W r - alpha D c`` with ``A`` the stacked
    ``J[:, k, p] * phi_p(x)``; with ``alpha_l1 > 0`` the step minimises the same quadratic
    model plus the L1 term (FISTA). The step is halved (up to 30 times) until
    the objective does not increase; iteration stops when the relative improvement is below
    ``tol``, no step improves it, or after ``max_iter`` iterations. ``solver="newton"``
    weights the normal matrix by the loss's curvature ``rho''(r)`` instead of the IRLS
    weights ``psi(r) / r`` (the same for squared error; Huber: 1 inside ``huber_delta``, 0
    beyond) once an iteration improves the objective by less than 10 %: near the optimum it
    converges in fewer iterations (IRLS converges linearly there); if a Newton step finds
    no decrease, the fit goes on with IRLS steps.

    Parameters
    ----------
    onsite : list of str
        Columns of ``X`` with the N control-model onsite frequencies (MHz), in site order.
    couplings : list of str
        Columns of ``X`` with the control model's couplings, one per edge, in edge order.
    edges : list of [i, j], default=None
        The coupling graph (0-based site pairs, one per coupling column); None: the
        nearest-neighbour chain ``[[0, 1], [1, 2], ...]``.
    parasitic : None, "none", "next_nearest", "diagonal" or list of [i, j], default=None
        Site pairs with a parasitic coupling the control model lacks (control value 0); see
        :meth:`~workbench.hamiltonian.CouplingGraph.parasitic_edges`. A parasitic coupling
        named ``"<onsite_i>~<onsite_j>"`` is in the model only if ``covariates`` gives it at
        least one covariate (``"default"``: the geometric means of the couplings bridging it).
    sign : {-1, 1}, default=-1
        The targets are eigenvalues of ``sign * H``.
    covariates : "default" or dict of str -> list of str, default="default"
        ``"default"``: :func:`default_library`. A dict maps parameter names to their
        covariate names; control parameters it does not list get only an intercept,
        parasitic ones are left out.
    features : list of str, default=None
        Columns of ``X`` added, with their squares, to every control parameter's covariates.
    alpha : float, default=1.0
        Ridge penalty on the non-intercept coefficients.
    alpha_l1 : float, default=0.0
        L1 penalty on the non-intercept coefficients.
    loss : {"squared_error", "absolute_error", "huber"}, default="squared_error"
    huber_delta : float, default=1.0
        Huber threshold (targets' units).
    max_iter : int, default=20
        Maximum Gauss-Newton iterations.
    tol : float, default=1e-6
        Stop when the relative decrease of the objective is below this.
    solver : {"irls", "newton"}, default="irls"
        Weights of the Gauss-Newton normal equations: IRLS ``psi(r) / r`` or the loss's
        curvature (``"newton"``; ``absolute_error`` has none and keeps IRLS).

    Attributes
    ----------
    parameter_names_ : list of str
        ``onsite + couplings`` and the active parasitic couplings.
    graph_ : CouplingGraph
        The model's graph: the control edges, then the active parasitic ones.
    covariate_names_ : dict of str -> list of str
        Covariates of each parameter (starting with ``"intercept"``).
    coef_ : pandas.DataFrame
        One row per (parameter, covariate), column ``"coef"`` (MHz per covariate sd);
        ``coef_dict()`` gives the same as a dict.
    products_ : dict of str -> (str, str)
        The product covariates' variables and their two factors.
    factor_mean_ : dict of str -> float
        Training means of the product factors (empty without products).
    model_ : HamiltonianModel
        The spectrum fitted (:func:`device_model` with the active parasitic couplings).
    n_iter_ : int
        Gauss-Newton iterations taken.
    train_loss_ : ndarray
        Objective at the start and after each accepted iteration.
    n_features_in_, feature_names_in_
    """

    _parameter_constraints: dict = {
        "onsite": [None, list, tuple],
        "couplings": [None, list, tuple],
        "edges": [None, "array-like"],
        "parasitic": [None, StrOptions(set(PARASITIC_KINDS)), "array-like"],
        "sign": [Options(numbers.Integral, {-1, 1})],
        "covariates": [StrOptions({"default"}), dict],
        "features": [None, list, tuple],
        # the fit's settings, as the parametric regressor declares them
        **{k: v for k, v in ParametricRegressor._parameter_constraints.items()
           if k in ("alpha", "alpha_l1", "loss", "huber_delta", "max_iter", "tol", "solver")},
    }

    def __init__(self, *, onsite: Sequence[str] | None = None,
                 couplings: Sequence[str] | None = None,
                 edges: Iterable[Sequence[int]] | None = None,
                 parasitic: str | Iterable[Sequence[int]] | None = None, sign: int = -1,
                 covariates: str | dict[str, list[str]] = "default",
                 features: Sequence[str] | None = None, alpha: float = 1.0,
                 alpha_l1: float = 0.0, loss: str = "squared_error", huber_delta: float = 1.0,
                 max_iter: int = 20, tol: float = 1e-6, solver: str = "irls") -> None:
        self.onsite = onsite
        self.couplings = couplings
        self.edges = edges
        self.parasitic = parasitic
        self.sign = sign
        self.covariates = covariates  # type: ignore[assignment]  # also "default"
        self.features = features
        self.alpha = alpha
        self.alpha_l1 = alpha_l1
        self.loss = loss
        self.huber_delta = huber_delta
        self.max_iter = max_iter
        self.tol = tol
        self.solver = solver

    # ------------------------------------------------------------------ validation
    def _check_params(self) -> tuple[list[str], list[str], list[str], dict[str, list[str]],
                                     CouplingGraph, list[str]]:
        self._validate_params()  # each value against _parameter_constraints
        onsite = _names(self.onsite, "onsite")
        couplings = _names(self.couplings, "couplings")
        if len(onsite) < 2:
            raise ValueError(f"onsite must name at least 2 columns, got {onsite!r}")
        graph, pairs = resolve_graph(len(onsite), self.edges, self.parasitic)
        if len(couplings) != graph.n_edges:
            what = "len(onsite) - 1" if self.edges is None else "len(edges)"
            raise ValueError(f"couplings must name {what} = {graph.n_edges} "
                             f"columns, got {len(couplings)}: {couplings!r}")
        features = _names(self.features, "features")
        if set(onsite) & set(couplings) or set(features) & set(onsite + couplings):
            raise ValueError("onsite, couplings and features must name distinct columns")
        extra = parasitic_names(onsite, pairs)
        params = onsite + couplings
        covariates: Any = self.covariates
        if isinstance(covariates, str):  # "default"
            library = default_library(onsite, couplings, self.edges, pairs)
        else:
            unknown = [p for p in covariates if p not in params + extra]
            if unknown:
                raise ValueError(f"covariates names unknown parameter(s) {unknown}; "
                                 f"parameters are {params + extra}")
            library = {p: _names(covariates.get(p, []), f"covariates[{p!r}]")
                       for p in params + extra}
        active = [(pair, p) for pair, p in zip(pairs, extra) if library.get(p)]
        graph = graph.with_edges([pair for pair, _ in active])
        return onsite, couplings, features, library, graph, [p for _, p in active]

    #: The parametric regressor's settings this one fixes: no calibration (the control
    #: values are the start, every intercept starts at 0), no guard beyond the training box.
    calibrate = False
    out_of_bounds = "extrapolate"
    _IRLS_FALLBACK = True
    _CHECK_MODEL = False  # the model is the device's spectrum; fit checks its columns

    # ------------------------------------------------------------------ the model
    def _whole_model(self) -> HamiltonianModel:
        """The device's spectrum with every parasitic coupling (:func:`device_model`)."""
        device = getattr(self, "_device", None)
        if device is None:  # before fit
            device = device_model(_names(self.onsite, "onsite"),
                                  _names(self.couplings, "couplings"), self.edges,
                                  self.parasitic, self.sign)
        return device

    def _named_covariates(self) -> dict[str, list[str]]:
        return self._library

    def fit(self, X: pd.DataFrame, y: Any, coef_init: Any = None) -> Self:
        """Fit the coefficients on ``X`` (DataFrame) and ``y`` (n, N ascending eigenvalues).

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The onsite, coupling and covariate columns, by name.
        y : array-like of shape (n_samples, N)
            The measured eigenvalues, ascending.
        coef_init : pandas.DataFrame or dict, default=None
            Starting coefficients, e.g. another fit's ``coef_`` (or ``coef_dict()``); entries
            are matched by (parameter, covariate), missing ones start at 0 and ones this
            model's covariates lack are ignored (a warm start when covariates are added or
            removed).

        Returns
        -------
        self
            The fitted model.
        """
        onsite, couplings, features, library, graph, extra = self._check_params()
        if not isinstance(X, pd.DataFrame):
            raise ValueError("X must be a pandas DataFrame holding the onsite, coupling and "
                             f"covariate columns by name, got {type(X).__name__}")
        if len(X) == 0:
            raise ValueError("X has no rows")
        n, N = len(X), len(onsite)
        _columns(X, onsite + couplings, "parameter")  # present, numeric and finite
        if features:
            _columns(X, features, "feature")
        y = np.asarray(y, dtype=float)
        if y.shape != (n, N):
            raise ValueError(f"y must have shape (n_samples, n_sites) = ({n}, {N}), "
                             f"got {y.shape}")
        if not np.all(np.isfinite(y)):
            raise ValueError("y contains NaN or infinite values")
        self.onsite_, self.couplings_, self.features_ = onsite, couplings, features
        self.parasitic_, self.graph_ = extra, graph
        self._device = device_model(onsite, couplings, self.edges, self.parasitic, self.sign)
        every = [f"{v}^{k}" if k > 1 else v for v in features for k in (1, 2)]
        self._library = {p: list(library.get(p, [])) + (every if p in onsite + couplings
                                                         else [])
                         for p in onsite + couplings + extra}
        self._fit(X, y, coef_init)  # the parameters were validated above
        self.model_ = restrict(self._device, self.parameter_names_)
        self.products_ = {v: cast(tuple[str, str], tuple(var[1:]))
                          for ts in self.terms_.values() for v, _ in ts
                          if (var := variable(v, self._columns)) and var[0] == "*"}
        return self

    def _physics(self) -> Any:
        check_is_fitted(self)
        return self.model_

    def _check_X(self, X: Any) -> None:
        check_is_fitted(self)
        if not isinstance(X, pd.DataFrame):
            raise ValueError("X must be a pandas DataFrame holding the onsite, coupling and "
                             f"covariate columns by name, got {type(X).__name__}")

    def _rows(self, X: Any) -> tuple[pd.DataFrame, np.ndarray, list[np.ndarray]]:
        self._check_X(X)
        return super()._rows(X)

    def control_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """The control model's parameters ``theta(X)`` in :attr:`parameter_names_` order
        (0 for the parasitic couplings it lacks): :meth:`start_parameters`.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The onsite, coupling and covariate columns, by name.

        Returns
        -------
        pandas.DataFrame
            The control parameters, indexed as ``X``.
        """
        self._check_X(X)
        return self.start_parameters(X)
