"""Covariate selection for the parameter-space regressor by cross-validation.

:func:`forward_select` chooses the covariates of each Hamiltonian parameter by greedy forward
stepwise selection over (parameter, covariate) pairs from a candidate pool
(:func:`candidate_pool`), scoring each candidate by repeated K-fold CV MAE on the rows it is
given, and only those. :class:`HamiltonianSelectionCV` wraps the selection and the refit in
one estimator (as ``LassoCV`` wraps its path), so nested CV is ``cross_val_predict`` of it.
"""

from __future__ import annotations

import numbers
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field
from typing import Any, Self

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.model_selection import RepeatedKFold
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from ._progress import Progress
from .hamiltonian import CouplingGraph
from .parallel import Task, effective_n_jobs, map_tasks
from .param_boost import default_library, parasitic_names, resolve_graph
from .param_linear import linear_scores
from .param_regressor import HamiltonianParameterRegressor

__all__ = ["HamiltonianSelectionCV", "SelectionResult", "candidate_pool", "crosstalk_candidates",
           "cv_mae", "forward_select"]


# ---------------------------------------------------------------------- candidate pools

def _pool_features(on: list[str], co: list[str], qubit_features: Sequence[str] | None,
                   coupler_features: Sequence[str] | None, graph: CouplingGraph,
                   base: str | None) -> tuple[list[str], list[str]]:
    """:func:`candidate_pool`'s names checked against the graph: the qubit and coupler
    features as lists (empty when not given)."""
    if len(co) != graph.n_edges:
        raise ValueError(f"couplings needs {graph.n_edges} names (one per edge), got {len(co)}")
    qf = list(qubit_features) if qubit_features is not None else []
    cf = list(coupler_features) if coupler_features is not None else []
    if qf and len(qf) != len(on):
        raise ValueError(f"qubit_features needs {len(on)} names (one per site), got {len(qf)}")
    if cf and len(cf) != len(co):
        raise ValueError(f"coupler_features needs {len(co)} names (one per coupling), got "
                         f"{len(cf)}")
    if base not in ("default", None):
        raise ValueError(f'base must be "default" or None, got {base!r}')
    return qf, cf

def candidate_pool(onsite: Sequence[str], couplings: Sequence[str],
                   qubit_features: Sequence[str] | None = None,
                   coupler_features: Sequence[str] | None = None, *, squares: bool = True,
                   base: str | None = "default", neighbours: bool = True,
                   edges: Iterable[Sequence[int]] | None = None,
                   parasitic: str | Iterable[Sequence[int]] | None = None,
                   crosstalk: bool = False) -> dict[str, list[str]]:
    """Physically meaningful candidate covariates of each Hamiltonian parameter.

    "Adjacent" and "neighbouring" are read from the coupling graph. ``base="default"``
    starts from :func:`~workbench.param_boost.default_library` (the parameter and its square;
    for onsite ``f_i`` the couplings touching site ``i`` and their squares; for ``g_e`` the
    detuning across it; for a parasitic coupling the geometric means of the couplings
    bridging it); ``base=None`` from nothing. Then, each with its square when ``squares``:

    * onsite ``f_i``: its qubit's feature and the features of the couplers touching it;
      with ``neighbours``, also the neighbouring onsite frequencies ``f_j``, the detunings
      to them and the neighbouring qubits' features;
    * coupling ``g_e``, ``e = (i, j)``: its coupler's feature; with ``neighbours``, also the
      two coupled frequencies, the squared detuning and the two qubits' features;
    * parasitic coupling ``(i, j)``: the geometric means ``sqrt|g_a*g_b|`` of the bridging
      couplings (not squared); with ``neighbours``, also the bridging couplers' features and
      the two qubits' features. It enters the model once a covariate of it is selected.

    With ``crosstalk``, the bias products of :func:`crosstalk_candidates`. Duplicates are
    dropped.

    Parameters
    ----------
    onsite, couplings : sequence of str
        The onsite parameters' and the couplings' names, in site and edge order.
    qubit_features, coupler_features : sequence of str, default=None
        The features acting on each site (N names) and coupling (one per edge), in site and
        edge order (e.g. ``qvolt5..qvolt9`` and ``cvolt5..cvolt8`` on the benchmark).
    squares, neighbours, crosstalk : bool, default=True, True, False
        Whether to add each candidate's square, the neighbouring terms, the bias products.
    base : {"default", None}, default="default"
        Whether to start from :func:`~workbench.param_boost.default_library`.
    edges, parasitic : default=None
        The coupling graph's site pairs (``None``: the chain) and the parasitic couplings
        (:func:`~workbench.param_boost.resolve_graph`).

    Returns
    -------
    dict of str to list of str
        Parameter name -> its candidate covariates.
    """
    on, co = list(onsite), list(couplings)
    graph, pairs = resolve_graph(len(on), edges, parasitic)
    qf, cf = _pool_features(on, co, qubit_features, coupler_features, graph, base)
    extra_names = parasitic_names(on, pairs)
    pool = (default_library(on, co, edges, pairs) if base == "default"
            else {p: [] for p in on + co + extra_names})
    pw = (1, 2) if squares else (1,)

    def terms(*variables: str) -> list[str]:
        return [v if k == 1 else f"{v}^{k}" for v in variables for k in pw]

    for i, p in enumerate(on):
        adjacent = graph.site_edges(i)  # couplings touching site i
        extra = terms(*(qf[i:i + 1] if qf else []), *([cf[j] for j in adjacent] if cf else []))
        if neighbours:
            sites = graph.neighbours(i)
            extra += [on[j] for j in sites]
            extra += terms(*(f"{on[min(i, j)]}-{on[max(i, j)]}" for j in sites))
            extra += terms(*([qf[j] for j in sites] if qf else []))
        pool[p] = list(dict.fromkeys(pool[p] + extra))
    for e, p in enumerate(co):
        a, b = graph.edges[e]
        extra = terms(*(cf[e:e + 1] if cf else []))
        if neighbours:
            extra += [on[a], on[b], f"{on[min(a, b)]}-{on[max(a, b)]}^2"]
            extra += terms(*([qf[a], qf[b]] if qf else []))
        pool[p] = list(dict.fromkeys(pool[p] + extra))
    for (i, j), p in zip(pairs, extra_names):
        paths = graph.paths2(i, j)
        extra = [f"sqrt|{co[a]}*{co[b]}|" for a, b in paths]
        if neighbours:
            extra += terms(*([cf[e] for path in paths for e in path] if cf else []))
            extra += terms(*([qf[i], qf[j]] if qf else []))
        pool[p] = list(dict.fromkeys(pool[p] + extra))
    if crosstalk:
        for p, terms_ in crosstalk_candidates(on, co, qf, cf, graph, neighbours).items():
            pool[p] = list(dict.fromkeys(pool[p] + terms_))
    return pool


def crosstalk_candidates(onsite: Sequence[str], couplings: Sequence[str],
                         qubit_features: Sequence[str] | None,
                         coupler_features: Sequence[str] | None, graph: CouplingGraph,
                         neighbours: bool = True) -> dict[str, list[str]]:
    """The bias-product candidates of :func:`candidate_pool` (``crosstalk=True``).

    Bias crosstalk terms (products of centred biases, not squared): a parameter tuned by its
    own bias line that also feels a neighbouring line ``V'`` changes by about
    ``(df/dV) C V'``, and near a sweet spot ``df/dV`` is linear in the own bias ``V``, so the
    candidate is ``V*V'``. Onsite ``f_i``: its qubit's feature times the features of the
    couplers touching it and (with ``neighbours``) of the neighbouring qubits; coupling
    ``g_e``: its coupler's feature times its two qubits' features.

    Parameters
    ----------
    onsite, couplings, qubit_features, coupler_features, neighbours
        As in :func:`candidate_pool`.
    graph : CouplingGraph
        The coupling graph.

    Returns
    -------
    dict of str to list of str
        Parameter name -> its bias products.
    """
    qf, cf = list(qubit_features or []), list(coupler_features or [])
    out: dict[str, list[str]] = {}
    for i, p in enumerate(onsite):
        if not qf:
            break
        lines = [cf[e] for e in graph.site_edges(i)] if cf else []
        if neighbours:
            lines += [qf[j] for j in graph.neighbours(i)]
        out[p] = [f"{qf[i]}*{v}" for v in lines]
    for e, p in enumerate(couplings):
        if not (qf and cf):
            break
        out[p] = [f"{cf[e]}*{qf[k]}" for k in graph.edges[e]]
    return out


# ---------------------------------------------------------------------- CV scoring

def _splits(n: int, cv: int, n_repeats: int,
            random_state: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Repeated K-fold splits (``RepeatedKFold``: the first repeat is
    ``KFold(cv, shuffle=True, random_state=random_state)``)."""
    return list(RepeatedKFold(n_splits=cv, n_repeats=n_repeats,
                              random_state=random_state).split(np.arange(n)))


def _cv_splits(X: pd.DataFrame, cv: Any, n_repeats: int,
               random_state: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The folds of ``X``: an int ``cv`` as :func:`_splits` (repeated shuffled K-fold), or a
    CV splitter's own (e.g. the forward-chaining
    :class:`~workbench.selection.LabelTimeSeriesSplit`, which looks the rows up by ``X``'s
    index); a splitter makes its folds once, so ``n_repeats`` must be 1."""
    if isinstance(cv, numbers.Integral):
        return _splits(len(X), int(cv), n_repeats, random_state)
    if n_repeats != 1:
        raise ValueError(f"n_repeats = {n_repeats} repeats shuffled K-fold; the splitter "
                         f"{type(cv).__name__} makes its folds once: set n_repeats = 1")
    return [(np.asarray(f), np.asarray(v)) for f, v in cv.split(X)]


def _sliced(X: pd.DataFrame, y: np.ndarray,
            splits: list[tuple[np.ndarray, np.ndarray]]) -> list[tuple]:
    """``(X_fit, y_fit, X_val, y_val)`` of each split, sliced once."""
    return [(X.iloc[f], y[f], X.iloc[v], y[v]) for f, v in splits]


def cv_mae(estimator: Any, X: pd.DataFrame, y: ArrayLike, *, cv: int = 5, n_repeats: int = 1,
           random_state: int = 0) -> float:
    """Repeated K-fold CV MAE of ``estimator`` on ``(X, y)``, the mean over all held-out values.

    Parameters
    ----------
    estimator : HamiltonianParameterRegressor
        The model.
    X : DataFrame
        The rows.
    y : array-like of shape (n, N)
        Their ascending eigenvalues.
    cv : int, default=5
        Folds.
    n_repeats : int, default=1
        Repeats of the K-fold split.
    random_state : int, default=0
        Seeds the ``RepeatedKFold``.

    Returns
    -------
    float
        The MAE over every held-out value of every repeat.
    """
    y = np.asarray(y, dtype=float)
    abs_sum, count = 0.0, 0
    for fit_rows, val_rows in _splits(len(X), cv, n_repeats, random_state):
        fitted = clone(estimator).fit(X.iloc[fit_rows], y[fit_rows])
        abs_sum += np.abs(fitted.predict(X.iloc[val_rows]) - y[val_rows]).sum()
        count += y[val_rows].size
    return float(abs_sum / count)


def _fit_splits(base: Any, covariates: dict[str, list[str]], folds: list[tuple], warm: list,
                models: bool = False, done: Callable[[int], None] | None = None) -> tuple:
    """CV MAE of ``base`` with ``covariates`` over the sliced ``folds``, and each fold's
    coefficients (to warm-start the next fits); with ``models``, also the fitted models.
    ``done(k)`` is called after fold ``k`` (from 1), to report progress."""
    est = clone(base).set_params(covariates=covariates)
    abs_sum, count, coefs, fits = 0.0, 0, [], []
    for k, ((X_fit, y_fit, X_val, y_val), init) in enumerate(zip(folds, warm), 1):
        fitted = clone(est).fit(X_fit, y_fit, coef_init=init)
        abs_sum += np.abs(fitted.predict(X_val) - y_val).sum()
        count += y_val.size
        coefs.append(fitted.coef_dict())
        fits.append(fitted)
        if done is not None:
            done(k)
    return (abs_sum / count, coefs, fits) if models else (abs_sum / count, coefs)


def _linear_fold(est: Any, fold: tuple, pool: list[tuple[str, str]],
                 irls: bool = False) -> np.ndarray:
    X_fit, y_fit, X_val, y_val = fold
    return linear_scores(est, X_fit, y_fit, X_val, y_val, pool, irls=irls)


def _score_many(base: Any, libraries: list[dict[str, list[str]]], folds: list[tuple],
                warm: list) -> list[float]:
    return [_fit_splits(base, lib, folds, warm)[0] for lib in libraries]


# ---------------------------------------------------------------------- selection

@dataclass
class SelectionResult:
    """Outcome of :func:`forward_select`.

    Parameters
    ----------
    covariates : dict
        Parameter name -> the selected covariate names (refit with
        ``HamiltonianParameterRegressor(covariates=result.covariates, ...)`` or
        :meth:`estimator`).
    path : DataFrame
        One row per step, columns ``step``, ``parameter``, ``covariate``, ``cv_mae``
        (step 0 is the start).
    cv_mae : float
        CV MAE of the final selection (the last row of ``path``).
    n_rows : int
        Rows the selection saw.
    index : Index
        Their index labels.
    regressor_params : dict, default={}
        The other parameters of the regressor the selection fitted (:meth:`estimator`
        passes them on).
    seconds : float, default=0.0
        Wall time of the selection.
    """

    covariates: dict
    path: pd.DataFrame
    cv_mae: float
    n_rows: int
    index: pd.Index
    regressor_params: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def selected(self) -> list[tuple[str, str]]:
        """Pairs added by the selection, in order."""
        return [tuple(r) for r in self.path.iloc[1:][["parameter", "covariate"]].to_numpy()]

    def estimator(self, **params: Any) -> HamiltonianParameterRegressor:
        """An unfitted regressor with the selected covariates.

        Parameters
        ----------
        **params
            Parameters overriding the selection's regressor's.

        Returns
        -------
        HamiltonianParameterRegressor
            The regressor.
        """
        return HamiltonianParameterRegressor(covariates=self.covariates,
                                             **{**self.regressor_params, **params})


SELECTION_METHODS = ("refit", "linearised")


def forward_select(X: pd.DataFrame, y: ArrayLike, *, candidates: dict[str, list[str]],
                   cv: int = 5, n_repeats: int = 1, random_state: int = 0, max_steps: int = 30,
                   min_improvement: float = 1e-3, start: dict[str, list[str]] | None = None,
                   n_jobs: int | None = None, method: str = "refit", shortlist: int = 5,
                   batch: int | str = "auto", progress: Callable[[str], None] | None = None,
                   **regressor_params: Any) -> SelectionResult:
    """Greedy forward stepwise selection of (parameter, covariate) pairs by K-fold CV MAE.

    Starts from ``start`` (default: intercepts only); at each step tries adding every
    remaining candidate pair, keeps the one with the lowest repeated K-fold CV MAE (RepeatedKFold
    seeded by ``random_state``, the same splits for
    every candidate) and stops when it improves the current CV MAE by less than
    ``min_improvement`` (targets' units) or after ``max_steps`` additions. Each candidate's
    fit on a split starts from the current selection's coefficients on that split (a warm
    start). Only ``X`` and ``y`` are used: pass the training rows alone.

    ``method="linearised"`` scales to large devices: each step scores every candidate on
    every split by one Gauss-Newton step of the enlarged model from the current fit
    (:func:`~workbench.param_linear.linear_scores`, a bordered least-squares update instead
    of a refit), then refits exactly: either a *batch* of the best-scored candidates of up
    to ``batch`` different parameters at once (``"auto"``: one per ten parameters in the
    model), kept if the refit's CV MAE improves by more than ``min_improvement`` (else the
    batch is halved), or, once the batch is 1, the ``shortlist`` best-scored single
    candidates, keeping the best by exact CV MAE as ``"refit"`` does. ``max_steps`` counts
    steps (a batch step adds several pairs). Its fold refits use the Newton solver
    (:data:`SELECTION_SOLVER`) and stop at a relative objective change of
    :data:`SELECTION_TOL` (or the regressor's ``tol``, if looser).

    Parameters
    ----------
    X : DataFrame
        The onsite, coupling and candidate-feature columns.
    y : array-like of shape (n, N)
        The ascending eigenvalues.
    candidates : dict
        Parameter -> list of covariate names (see :func:`candidate_pool`).
    cv : int, default=5
        Folds.
    n_repeats : int, default=1
        Repeats of the K-fold split.
    random_state : int, default=0
        Seeds the ``RepeatedKFold``.
    max_steps : int, default=30
        The most steps.
    min_improvement : float, default=0.001
        The least CV MAE gain (targets' units) a step must bring.
    start : dict, default=None
        The starting covariates (``None``: intercepts only).
    n_jobs : int, default=None
        Scikit-learn's convention (``None``: 1, ``-1``: every core; 1 inside a worker
        process): for ``"refit"``, the candidates are scored on the workbench's worker
        processes (:mod:`workbench.parallel`, the command's pool when there is one); for
        ``"linearised"``, the folds' fits and linear scores run on threads of this process
        (the folds' data and fitted models stay in memory from step to step; numpy's
        linear algebra releases the GIL).
    method : {"refit", "linearised"}, default="refit"
        How candidates are scored (see above).
    shortlist : int, default=5
        ``"linearised"``: the best-scored single candidates refitted exactly.
    batch : int or "auto", default="auto"
        ``"linearised"``: the most parameters a batch step adds a covariate to.
    progress : callable, default=None
        Called with one line per step.
    **regressor_params
        Passed to :class:`~workbench.param_regressor.HamiltonianParameterRegressor`
        (``onsite``, ``couplings``, ``sign``, ``alpha``, ``loss``, ...; not ``covariates``).

    Returns
    -------
    SelectionResult
        The selected covariates, the path and its CV scores.
    """
    t0 = time.perf_counter()
    y, base, current, pool = _selection_setup(X, y, candidates, start, max_steps, method,
                                              shortlist, batch, regressor_params)
    folds = _sliced(X, y, _splits(len(X), cv, n_repeats, random_state))
    jobs = effective_n_jobs(n_jobs)  # scikit-learn's convention: None 1, -1 every core
    if method == "linearised":
        return _linearised_select(X, base, current, pool, folds, jobs, max_steps,
                                  min_improvement, shortlist, batch, progress, t0,
                                  regressor_params)
    return _refit_select(X, base, current, pool, folds, jobs, max_steps, min_improvement,
                         progress, t0, regressor_params)


def _selection_setup(X: pd.DataFrame, y: ArrayLike, candidates: dict[str, list[str]],
                     start: dict[str, list[str]] | None, max_steps: int, method: str,
                     shortlist: int, batch: int | str, regressor_params: dict[str, Any]
                     ) -> tuple[np.ndarray, HamiltonianParameterRegressor,
                                dict[str, list[str]], list[tuple[str, str]]]:
    """:func:`forward_select`'s arguments checked: ``y`` as floats, the base regressor, the
    starting covariates of every parameter and the pool of ``(parameter, covariate)`` pairs
    not in them."""
    if not isinstance(X, pd.DataFrame):
        raise ValueError("X must be a pandas DataFrame")
    if "covariates" in regressor_params:
        raise ValueError("pass the starting covariates as start=, not covariates=")
    if not (isinstance(max_steps, numbers.Integral) and int(max_steps) >= 0):
        raise ValueError(f"max_steps must be an integer >= 0, got {max_steps!r}")
    if not isinstance(candidates, dict):
        raise ValueError("candidates must be a dict parameter -> list of covariate names, got "
                         f"{type(candidates).__name__}")
    y = np.asarray(y, dtype=float)
    base = HamiltonianParameterRegressor(**regressor_params)
    base._check_params()
    _, pairs = resolve_graph(len(base.onsite), base.edges, base.parasitic)
    params = (list(base.onsite) + list(base.couplings)
              + parasitic_names(base.onsite, pairs))
    for what, table in (("candidates", candidates), ("start", start or {})):
        unknown = [p for p in table if p not in params]
        if unknown:
            raise ValueError(f"{what} name unknown parameter(s) {unknown}; parameters are "
                             f"{params}")
    current = {p: list((start or {}).get(p, [])) for p in params}
    pool = [(p, c) for p in params for c in dict.fromkeys(candidates.get(p, []))
            if c not in current[p]]
    if method not in SELECTION_METHODS:
        raise ValueError(f"unknown selection method {method!r}; valid: "
                         f"{', '.join(SELECTION_METHODS)}")
    if not (isinstance(shortlist, numbers.Integral) and int(shortlist) >= 1):
        raise ValueError(f"shortlist must be an integer >= 1, got {shortlist!r}")
    if batch != "auto" and not (isinstance(batch, numbers.Integral) and int(batch) >= 1):
        raise ValueError(f'batch must be "auto" or an integer >= 1, got {batch!r}')
    return y, base, current, pool


def _selection_result(X: pd.DataFrame, current: dict[str, list[str]], rows: list[dict],
                      best: float, regressor_params: dict[str, Any],
                      t0: float) -> SelectionResult:
    """The :class:`SelectionResult` of a finished selection (``t0``: its start time)."""
    path = pd.DataFrame(rows, columns=["step", "parameter", "covariate", "cv_mae"])
    return SelectionResult(covariates={p: v for p, v in current.items() if v}, path=path,
                           cv_mae=float(best), n_rows=len(X), index=X.index.copy(),
                           regressor_params=dict(regressor_params),
                           seconds=time.perf_counter() - t0)


def _refit_select(X: pd.DataFrame, base: HamiltonianParameterRegressor,
                  current: dict[str, list[str]], pool: list[tuple[str, str]], folds: list,
                  jobs: int, max_steps: int, min_improvement: float,
                  progress: Callable[[str], None] | None, t0: float,
                  regressor_params: dict[str, Any]) -> SelectionResult:
    """Forward selection refitting every candidate on every fold (``method="refit"`` of
    :func:`forward_select`)."""

    def score(libraries: list[dict[str, list[str]]], warm: list) -> list:
        if jobs > 1 and len(libraries) > 1:
            chunks = [libraries[i::jobs] for i in range(jobs)]
            # the workbench's worker processes (workbench.parallel), the command's own pool
            res = map_tasks([Task(_score_many, base, ch, folds, warm) for ch in chunks], jobs)
            out: list = [None] * len(libraries)
            for i, r in enumerate(res):
                out[i::jobs] = r
            return out
        return _score_many(base, libraries, folds, warm)

    best, warm = _fit_splits(base, current, folds, [None] * len(folds))
    rows = [dict(step=0, parameter=None, covariate=None, cv_mae=best)]
    if progress:
        progress(f"start: cv_mae={best:.4g} ({len(pool)} candidate terms)")
    for step in range(1, int(max_steps) + 1):
        if not pool:
            break
        trials = [{**current, p: current[p] + [c]} for p, c in pool]
        scores = np.asarray(score(trials, warm))
        k = int(np.argmin(scores))
        if not best - scores[k] > min_improvement:
            break
        p, c = pool.pop(k)
        current[p] = current[p] + [c]
        best, warm = _fit_splits(base, current, folds, warm)
        rows.append(dict(step=step, parameter=p, covariate=c, cv_mae=best))
        if progress:
            progress(f"step {step}: {p} <- {c}  cv_mae={best:.4g} "
                     f"({time.perf_counter() - t0:.0f} s)")
    return _selection_result(X, current, rows, best, regressor_params, t0)


#: Relative-objective tolerance of the fold refits inside the linearised selection (the
#: regressor's own ``tol`` when that is looser); the final refit on all rows uses ``tol``.
SELECTION_TOL = 1e-5
#: Solver of the linearised selection's fold refits and candidate steps (see
#: :class:`~workbench.param_regressor.HamiltonianParameterRegressor`): Newton steps converge
#: from a warm start in a few iterations where IRLS needs many, and its one-step candidate
#: scores are closer to a refit's.
SELECTION_SOLVER = "newton"


def _fit_fold(est: HamiltonianParameterRegressor, lib: dict[str, list[str]], fold: tuple,
              init: dict | None) -> tuple[float, int, dict, HamiltonianParameterRegressor]:
    """Fit ``est`` with covariates ``lib`` on one fold: held-out absolute-error sum, count,
    coefficients and the fitted model."""
    X_fit, y_fit, X_val, y_val = fold
    fitted = clone(est).set_params(covariates=lib).fit(X_fit, y_fit, coef_init=init)
    return (float(np.abs(fitted.predict(X_val) - y_val).sum()), y_val.size,
            fitted.coef_dict(), fitted)


def _linearised_select(X: pd.DataFrame, base: Any,
                       current: dict[str, list[str]], pool: list[tuple[str, str]],
                       folds: list[tuple], jobs: int, max_steps: int, min_improvement: float,
                       shortlist: int, batch: int | str, progress: Callable[[str], None] | None,
                       t0: float, regressor_params: dict[str, Any],
                       irls_scores: bool = False) -> SelectionResult:
    """Forward selection with linearised candidate scores (see :func:`forward_select`);
    ``base`` a drift regressor (:class:`~workbench.param_regressor.HamiltonianParameterRegressor`
    or :class:`~workbench.param_regressor.ParametricRegressor`), ``irls_scores`` the
    scores' weights (:func:`~workbench.param_linear.linear_scores`' ``irls``).

    Everything runs in this process: the folds' data and fitted models stay in memory from
    step to step (nothing is pickled), and with ``jobs > 1`` the (library, fold) fits and the
    folds' linear scores run in a pool of ``jobs`` threads (numpy's linear algebra and large
    array operations release the GIL)."""
    est = clone(base).set_params(tol=max(float(base.tol), SELECTION_TOL),
                                 solver=SELECTION_SOLVER)
    with ThreadPoolExecutor(max_workers=jobs) if jobs > 1 else nullcontext() as executor:
        def run(func: Callable, items: list[tuple]) -> list:
            if executor is None or len(items) < 2:
                return [func(*it) for it in items]
            return list(executor.map(lambda it: func(*it), items))

        def fit_libs(libs: list[dict[str, list[str]]], warm: list) -> list[tuple]:
            out = run(_fit_fold, [(est, lib, fold, init) for lib in libs
                                  for fold, init in zip(folds, warm)])
            k = len(folds)
            return [(sum(o[0] for o in out[i:i + k]) / sum(o[1] for o in out[i:i + k]),
                     [o[2] for o in out[i:i + k]], [o[3] for o in out[i:i + k]])
                    for i in range(0, len(out), k)]

        best, warm, models = fit_libs([current], [None] * len(folds))[0]
        rows = [dict(step=0, parameter=None, covariate=None, cv_mae=best)]
        if progress:
            progress(f"start: cv_mae={best:.4g} ({len(pool)} candidate terms, linearised)")
        n_params = sum(1 for v in current.values() if v) or 1
        size = max(1, n_params // 10) if batch == "auto" else int(batch)
        step = 0
        while step < max_steps and pool:
            step += 1
            count = sum(f[3].size for f in folds)
            lin = np.sum(run(_linear_fold, [(m, f, pool, irls_scores)
                                            for m, f in zip(models, folds)]), axis=0) / count
            hopeful = [int(k) for k in np.argsort(lin, kind="stable") if lin[k] < best]
            accepted = None
            while hopeful:
                if size > 1:
                    chosen, seen = [], set()
                    for k in hopeful:
                        if pool[k][0] not in seen:
                            chosen.append(k)
                            seen.add(pool[k][0])
                        if len(chosen) == size:
                            break
                    trials = [chosen]
                else:
                    trials = [[k] for k in hopeful[:shortlist]]
                libs = []
                for ks in trials:
                    lib = {p: list(v) for p, v in current.items()}
                    for k in ks:
                        lib[pool[k][0]].append(pool[k][1])
                    libs.append(lib)
                results = fit_libs(libs, warm)
                i = int(np.argmin([r[0] for r in results]))
                if best - results[i][0] > min_improvement:
                    accepted = (trials[i], libs[i], results[i])
                    break
                if size == 1 or len(trials[0]) == 1:
                    break
                size = max(1, size // 2)
            if accepted is None:
                break
            ks, lib, (best, warm, models) = accepted
            for k in ks:
                rows.append(dict(step=step, parameter=pool[k][0], covariate=pool[k][1],
                                 cv_mae=best))
            if progress:
                added = ", ".join(f"{pool[k][0]} <- {pool[k][1]}" for k in ks)
                progress(f"step {step}: {added}  cv_mae={best:.4g} "
                         f"({time.perf_counter() - t0:.0f} s)")
            current = lib
            pool = [pc for k, pc in enumerate(pool) if k not in set(ks)]
    return _selection_result(X, current, rows, best, regressor_params, t0)


class HamiltonianSelectionCV(RegressorMixin, BaseEstimator):
    """Forward covariate selection by CV (on the rows given to ``fit``), then a refit.

    ``fit`` runs :func:`forward_select` with these settings on ``regressor`` and refits it
    with the selected covariates on all the rows. Cloning it and cross-validating gives
    nested CV (the selection runs again inside each outer fold).

    Parameters
    ----------
    regressor : HamiltonianParameterRegressor, default=None
        The model whose covariates are selected (its ``covariates`` is replaced by the
        selection's; every other parameter is kept, e.g. the graph, penalties, loss and
        solver). ``None``: ``HamiltonianParameterRegressor()``, which needs ``onsite`` and
        ``couplings`` set (``regressor__onsite=...``).
    candidates : dict parameter -> list of covariate names, default=None
        The pool (:func:`candidate_pool`); ``None``: the regressor's default library.
    start : dict, default=None
        Covariates every candidate model has (``None``: intercepts only).
    cv, n_repeats : int, default=5, 1
        The selection's repeated K-fold CV.
    max_steps, min_improvement
        As in :func:`forward_select`.
    random_state : int, RandomState or None, default=None
        Seeds the selection's fold shuffling.
    n_jobs : int, default=None
        Candidates scored in parallel.
    method, shortlist, batch : default="refit", 5, "auto"
        As in :func:`forward_select` (``"linearised"`` for large devices).
    verbose : bool, default=False
        Report one line per selection step: INFO records of the
        ``workbench.param_select`` logger, or printed to standard error where no logging
        is set up (:mod:`workbench._progress`). No number depends on it.

    Attributes
    ----------
    selection_ : SelectionResult
    estimator_ : HamiltonianParameterRegressor (fitted on all rows)
    """

    _parameter_constraints: dict = {
        "regressor": [None, HasMethods(["fit", "predict", "coef_dict"])],
        "candidates": [None, dict],
        "start": [None, dict],
        "cv": [Interval(numbers.Integral, 2, None, closed="left")],
        "n_repeats": [Interval(numbers.Integral, 1, None, closed="left")],
        "max_steps": [Interval(numbers.Integral, 0, None, closed="left")],
        "min_improvement": [Interval(numbers.Real, 0, None, closed="left")],
        "random_state": ["random_state"],
        "n_jobs": [numbers.Integral, None],
        "method": [StrOptions(set(SELECTION_METHODS))],
        "shortlist": [Interval(numbers.Integral, 1, None, closed="left")],
        "batch": [StrOptions({"auto"}), Interval(numbers.Integral, 1, None, closed="left")],
        "verbose": ["boolean"],
    }

    def __init__(self, regressor: Any = None, *, candidates: dict[str, list[str]] | None = None,
                 start: dict[str, list[str]] | None = None, cv: int = 5, n_repeats: int = 1,
                 max_steps: int = 30, min_improvement: float = 1e-3,
                 random_state: int | np.random.RandomState | None = None,
                 n_jobs: int | None = None, method: str = "refit", shortlist: int = 5,
                 batch: int | str = "auto", verbose: bool = False) -> None:
        self.regressor = regressor
        self.candidates = candidates
        self.start = start
        self.cv = cv
        self.n_repeats = n_repeats
        self.max_steps = max_steps
        self.min_improvement = min_improvement
        self.random_state = random_state
        self.n_jobs = n_jobs
        self.method = method
        self.shortlist = shortlist
        self.batch = batch
        self.verbose = verbose

    def fit(self, X: pd.DataFrame, y: ArrayLike) -> Self:
        """Select the covariates forward by CV, then refit the regressor on all rows.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The onsite, coupling and covariate columns, by name.
        y : array-like of shape (n_samples, N)
            The measured eigenvalues, ascending.

        Returns
        -------
        self
            The fitted selection.
        """
        self._validate_params()
        regressor = HamiltonianParameterRegressor() if self.regressor is None else self.regressor
        params = {k: v for k, v in regressor.get_params(deep=False).items() if k != "covariates"}
        candidates = self.candidates
        if candidates is None:
            candidates = default_library(params["onsite"] or [], params["couplings"] or [],
                                         params["edges"], params["parasitic"])
        if isinstance(self.random_state, numbers.Integral):
            seed = int(self.random_state)
        else:
            seed = int(check_random_state(self.random_state).randint(2**31 - 1 - self.n_repeats))
        progress = (Progress(__name__, True, "hamiltonian: selection ") if self.verbose
                    else None)
        self.selection_ = forward_select(
            X, y, candidates=candidates, cv=self.cv, n_repeats=self.n_repeats,
            random_state=seed, max_steps=self.max_steps, min_improvement=self.min_improvement,
            start=self.start, n_jobs=self.n_jobs, method=self.method, shortlist=self.shortlist,
            batch=self.batch, progress=progress, **params)
        self.estimator_ = self.selection_.estimator().fit(X, y)
        self.n_features_in_ = X.shape[1]
        self.feature_names_in_ = self.estimator_.feature_names_in_
        return self

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """Predict with the refitted regressor.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The onsite, coupling and covariate columns, by name.

        Returns
        -------
        ndarray of shape (n_samples, N)
            The predicted eigenvalues.
        """
        check_is_fitted(self)
        return self.estimator_.predict(X)

    def corrected_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """The refitted regressor's corrected Hamiltonian parameters.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The onsite, coupling and covariate columns, by name.

        Returns
        -------
        pandas.DataFrame
            The corrected parameters, indexed as ``X``.
        """
        check_is_fitted(self)
        return self.estimator_.corrected_parameters(X)

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "estimator_")
