"""Augmented learning curves: the model, its training error and the incumbent, per training size.

The base-boosting paper's "augmented" learning curve adds a third line to the usual two: at
each training size it shows the model's training error, its cross-validated error, and the
cross-validated error of the incumbent (the prior alone, i.e. the scientific model), all on
the same folds and the same rows. Where the model's CV error falls below the incumbent's,
learning from data beats the physics alone.

Protocol (:func:`augmented_learning_curve`):

* ``cv`` splits the rows into fold-training and fold-validation rows (an int ``k`` means
  ``KFold(k, shuffle=True, random_state=...)``).
* Each fold's training rows are shuffled once with a seeded permutation; size ``s`` uses the
  first ``s`` rows of that permutation, so the subsets of one fold are nested. A size equal
  to the whole fold-training set uses those rows in the fold's own order: the same fit as
  a cross-validation on the fold.
* At each (size, fold) a clone of the estimator and a clone of the incumbent are fitted on
  those ``s`` rows. The training error is the estimator's error on the same ``s`` rows; the
  CV error and the incumbent error are measured on the fold's validation rows.
* ``train_sizes`` are absolute row counts. A size larger than the smallest fold-training set
  is an error (the reference implementation silently trained on fewer rows than it
  reported); the rows actually used are recorded in ``LearningCurve.n_train_rows``.
* A failing candidate fit gives NaN at that (size, fold) and one ``FitFailedWarning``;
  the curve is still computed everywhere else.

:func:`selection_learning_curve` draws the curve of a fitted :class:`~workbench.BaseBoostCV`
on its own folds, with its candidate as seeded there: the points at the whole fold size are
the selection's own fold fits, taken from it instead of fitted again.

The (size, fold) fits run on ``n_jobs`` processes (:mod:`workbench.parallel`), the largest
first; :func:`learning_curve_plan` and :func:`selection_curve_plan` give them as plans, so
the curves of several targets share the workers. The numbers do not depend on ``n_jobs``.

This module belongs to the core: it imports only numpy, pandas and scikit-learn. The
figure lives in :mod:`workbench.experiment.figures`.
"""

from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from sklearn.base import clone
from sklearn.exceptions import FitFailedWarning
from sklearn.metrics import check_scoring
from sklearn.model_selection import KFold, check_cv
from sklearn.utils import _safe_indexing, check_random_state

from .boosting import PriorModel, seed_estimator
from .parallel import Plan, Task, run_plans
from .selection import find_prior

__all__ = ["LearningCurve", "augmented_learning_curve", "learning_curve_plan",
           "selection_curve_plan", "selection_learning_curve"]

_SEED_MAX = np.iinfo(np.int32).max


def _readonly(values: ArrayLike, dtype: Any) -> np.ndarray:
    arr = np.array(values, dtype=dtype)  # a copy the caller cannot alias
    arr.setflags(write=False)
    return arr


def _json_list(arr: np.ndarray) -> Any:
    """Nested lists with NaN/inf replaced by ``None`` (strict JSON has no NaN); a 0-d array's
    value (or ``None``)."""
    if arr.ndim == 0:
        v = arr.item()
        return None if isinstance(v, float) and not math.isfinite(v) else v
    return [_json_list(a) for a in arr]


@dataclass(frozen=True, eq=False)
class LearningCurve:
    """The result of :func:`augmented_learning_curve`.

    Errors are positive (``-score``, e.g. the MAE for ``"neg_mean_absolute_error"``); rows
    are training sizes, columns folds. NaN marks a (size, fold) where the candidate failed.

    Parameters
    ----------
    train_sizes : ndarray of int, shape (n_sizes,)
        The requested training sizes (row counts), ascending.
    n_train_rows : ndarray of int, shape (n_sizes, n_folds)
        Rows actually used to fit at each (size, fold).
    train_error, cv_error, incumbent_error : ndarray of shape (n_sizes, n_folds)
        The candidate's error on its own training rows, its error on the fold's validation
        rows, and the incumbent's error on the same validation rows.
    n_validation_rows : ndarray of int, shape (n_folds,)
        Validation rows of each fold.
    scoring : str
        The scorer's name (or ``repr`` of a callable scorer).
    fit_errors : tuple of str
        ``"size=<s>, fold=<f>: <exception>"`` for each failed candidate fit.
    """

    train_sizes: np.ndarray
    n_train_rows: np.ndarray
    train_error: np.ndarray
    cv_error: np.ndarray
    incumbent_error: np.ndarray
    n_validation_rows: np.ndarray
    scoring: str = "neg_mean_absolute_error"
    fit_errors: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        """Check the arrays' shapes and store them read-only."""
        sizes = _readonly(self.train_sizes, int)
        object.__setattr__(self, "train_sizes", sizes)
        rows = _readonly(self.n_train_rows, int)
        object.__setattr__(self, "n_train_rows", rows)
        shape = (len(sizes), rows.shape[1] if rows.ndim == 2 else -1)
        if rows.shape != shape:
            raise ValueError(f"n_train_rows must have shape (n_sizes, n_folds) = "
                             f"({len(sizes)}, n_folds); got {rows.shape}")
        for name in ("train_error", "cv_error", "incumbent_error"):
            arr = _readonly(getattr(self, name), float)
            if arr.shape != rows.shape:
                raise ValueError(f"{name} must have shape {rows.shape}; got {arr.shape}")
            object.__setattr__(self, name, arr)
        val = _readonly(self.n_validation_rows, int)
        if val.shape != (rows.shape[1],):
            raise ValueError(f"n_validation_rows must have shape ({rows.shape[1]},); "
                             f"got {val.shape}")
        object.__setattr__(self, "n_validation_rows", val)
        object.__setattr__(self, "fit_errors", tuple(self.fit_errors))

    @property
    def n_folds(self) -> int:
        """The number of folds."""
        return int(self.n_train_rows.shape[1])

    @property
    def mean_train_rows(self) -> np.ndarray:
        """Mean rows actually used per size (the honest x-axis of the curve)."""
        return self.n_train_rows.mean(axis=1)

    # Means over folds are NaN where any fold failed: a partial mean would not be comparable
    # with the incumbent's, which is measured on every fold.
    @property
    def train_error_mean(self) -> np.ndarray:
        """Mean training error over folds per size."""
        return self.train_error.mean(axis=1)

    @property
    def train_error_std(self) -> np.ndarray:
        """Standard deviation of the training error across folds per size (``ddof=0``)."""
        return self.train_error.std(axis=1)

    @property
    def cv_error_mean(self) -> np.ndarray:
        """Mean validation error over folds per size."""
        return self.cv_error.mean(axis=1)

    @property
    def cv_error_std(self) -> np.ndarray:
        """Standard deviation across folds (``ddof=0``, as scikit-learn's curve displays)."""
        return self.cv_error.std(axis=1)

    @property
    def incumbent_error_mean(self) -> np.ndarray:
        """The incumbent's mean validation error over folds per size."""
        return self.incumbent_error.mean(axis=1)

    @property
    def incumbent_error_std(self) -> np.ndarray:
        """Standard deviation of the incumbent's validation error across folds (``ddof=0``)."""
        return self.incumbent_error.std(axis=1)

    def to_dict(self) -> dict[str, Any]:
        """Write the curve as JSON-ready data: plain lists, NaN as ``None``.

        Returns
        -------
        dict
            The fields and the means over folds by name.
        """
        return {
            "scoring": self.scoring,
            "n_folds": self.n_folds,
            "train_sizes": self.train_sizes.tolist(),
            "n_train_rows": self.n_train_rows.tolist(),
            "n_validation_rows": self.n_validation_rows.tolist(),
            "train_error": _json_list(self.train_error),
            "cv_error": _json_list(self.cv_error),
            "incumbent_error": _json_list(self.incumbent_error),
            "train_error_mean": _json_list(self.train_error_mean),
            "cv_error_mean": _json_list(self.cv_error_mean),
            "cv_error_std": _json_list(self.cv_error_std),
            "incumbent_error_mean": _json_list(self.incumbent_error_mean),
            "fit_errors": list(self.fit_errors),
        }


def _check_train_sizes(train_sizes: ArrayLike) -> np.ndarray:
    sizes = np.atleast_1d(np.asarray(train_sizes))
    if sizes.ndim != 1 or sizes.size == 0:
        raise ValueError(f"train_sizes must be a non-empty 1-D sequence of row counts; got "
                         f"{train_sizes!r}")
    if sizes.dtype == bool or not all(isinstance(s, numbers.Real) for s in sizes.tolist()):
        raise ValueError(f"train_sizes must be integer row counts; got {train_sizes!r}")
    if not np.all(np.isfinite(sizes)) or np.any(sizes != np.round(sizes)):
        raise ValueError("train_sizes must be absolute, whole row counts (not fractions of the "
                         f"training set); got {sizes.tolist()}")
    sizes = sizes.astype(int)
    if np.any(sizes < 1):
        raise ValueError(f"train_sizes must be >= 1; got {sizes.tolist()}")
    if len(np.unique(sizes)) != len(sizes):
        raise ValueError(f"train_sizes contains duplicates: {sizes.tolist()}")
    return np.sort(sizes)


def _check_cv(cv: Any, y: np.ndarray, random_state: int | None) -> Any:
    if isinstance(cv, numbers.Integral) and not isinstance(cv, bool):
        if cv < 2:
            raise ValueError(f"cv must be >= 2 folds; got {cv}")
        return KFold(int(cv), shuffle=True, random_state=random_state)
    return check_cv(cv, y, classifier=False)


def _rows(perm: np.ndarray, train: np.ndarray, size: int) -> np.ndarray:
    """The rows of one (size, fold): a prefix of the fold's permutation, or at the whole fold
    size the fold's rows in their own order."""
    return train if size == len(train) else perm[:size]


def _error_of(scorer: Callable, model: Any, X: Any, y: np.ndarray) -> float:
    return -float(scorer(model, X, y))


def _one(estimator: Any, incumbent: Any, X: Any, y: np.ndarray, rows: np.ndarray,
         val: np.ndarray, size: int, fold: int,
         scorer: Callable) -> tuple[int, float, float, float, str | None]:
    """Fit and score candidate and incumbent at one (size, fold)."""
    X_fit, y_fit = _safe_indexing(X, rows), y[rows]
    X_val, y_val = _safe_indexing(X, val), y[val]
    inc_error = _error_of(scorer, clone(incumbent).fit(X_fit, y_fit), X_val, y_val)
    try:
        model = clone(estimator).fit(X_fit, y_fit)
        train_error = _error_of(scorer, model, X_fit, y_fit)
        cv_error = _error_of(scorer, model, X_val, y_val)
        error = None
    except Exception as exc:  # a failed candidate is recorded, never crashes the curve
        train_error = cv_error = np.nan
        error = f"size={size}, fold={fold}: {type(exc).__name__}: {exc}"
    return len(rows), train_error, cv_error, inc_error, error


def augmented_learning_curve(estimator: Any, X: Any, y: ArrayLike, *, train_sizes: ArrayLike,
                             cv: Any = 5, incumbent: Any = None,
                             scoring: str | Callable = "neg_mean_absolute_error",
                             random_state: int | np.random.RandomState | None = None,
                             n_jobs: int | None = None) -> LearningCurve:
    """The augmented learning curve of ``estimator`` against its incumbent (see module doc).

    Parameters
    ----------
    estimator : regressor
        The candidate, cloned for every (size, fold).
    X : array-like or DataFrame of shape (n_samples, n_features)
        DataFrames are kept as such, so column-name priors and basis features work.
    y : array-like of shape (n_samples,) (or one column)
        The targets.
    train_sizes : sequence of int
        Absolute training sizes (row counts). Each must be at most the smallest
        fold-training set; otherwise ``ValueError`` names the size and the maximum.
    cv : int or CV splitter, default=5
        An int ``k`` means ``KFold(k, shuffle=True, random_state=...)``; any scikit-learn
        splitter or iterable of (train, validation) index pairs is used as given.
    incumbent : regressor, default=None
        The prior-alone model; ``None`` builds ``PriorModel(prior=find_prior(estimator))``.
    scoring : str or callable, default="neg_mean_absolute_error"
        A "greater is better" scorer of an error: the reported error is ``-score``. Strings
        must name a ``neg_*`` scorer.
    random_state : int, RandomState or None, default=None
        Seeds the folds (int ``cv``), the per-fold row permutations and, when not ``None``,
        every ``random_state`` of the estimator (as :class:`~workbench.BaseBoostCV` does).
        The same value gives identical numbers.
    n_jobs : int, default=None
        Processes for the (size, fold) fits (``-1``: every core; :mod:`workbench.parallel`).
        The curve does not depend on it.

    Returns
    -------
    LearningCurve
        Per training size, the candidate's and the incumbent's errors over the folds.
    """
    plan = learning_curve_plan(estimator, X, y, train_sizes=train_sizes, cv=cv,
                               incumbent=incumbent, scoring=scoring, random_state=random_state)
    return run_plans([plan], n_jobs)[0]


def _inputs(X: Any, y: ArrayLike, scoring: str | Callable,
            train_sizes: ArrayLike) -> tuple[Any, np.ndarray, np.ndarray]:
    if isinstance(scoring, str) and not scoring.startswith("neg_"):
        raise ValueError(f"scoring must name an error scorer ('neg_...', reported as a positive "
                         f"error), got {scoring!r}")
    sizes = _check_train_sizes(train_sizes)
    if not hasattr(X, "iloc"):  # keep DataFrames (column names) for the sub-estimators
        X = np.asarray(X)
    y = np.asarray(y, dtype=float)
    if y.ndim == 2 and y.shape[1] == 1:
        y = y[:, 0]
    if len(X) != len(y):
        raise ValueError(f"X and y have different numbers of rows: {len(X)} and {len(y)}")
    return X, y, sizes


def _check_sizes(sizes: np.ndarray, folds: list[tuple[np.ndarray, np.ndarray]],
                 n_rows: int) -> None:
    if len(folds) == 0:
        raise ValueError("cv produced no folds")
    fold_sizes = [len(tr) for tr, _ in folds]
    max_size = min(fold_sizes)
    too_big = sizes[sizes > max_size]
    if too_big.size:
        raise ValueError(
            f"train size {int(too_big[0])} is larger than the smallest fold-training set: at "
            f"most {max_size} rows can be used ({len(folds)} folds of {n_rows} rows; "
            f"fold-training sizes {sorted(set(fold_sizes))}). Use train_sizes <= {max_size}.")


def learning_curve_plan(estimator: Any, X: Any, y: ArrayLike, *, train_sizes: ArrayLike,
                        cv: Any = 5, incumbent: Any = None,
                        scoring: str | Callable = "neg_mean_absolute_error",
                        random_state: int | np.random.RandomState | None = None) -> Plan:
    """:func:`augmented_learning_curve` as a plan (:mod:`workbench.parallel`).

    Parameters
    ----------
    estimator, X, y, train_sizes, cv, incumbent, scoring, random_state
        As in :func:`augmented_learning_curve`.

    Returns
    -------
    LearningCurve
        The plan's value (a generator's: run by :func:`~workbench.parallel.run_plans`).

    Yields
    ------
    list of Task
        Each batch of tasks to run (:func:`~workbench.parallel.run_plans` runs them).
        The batch's results are sent back, in its order.
    """
    X, y, sizes = _inputs(X, y, scoring, train_sizes)
    rng = check_random_state(random_state)
    cv_seed, estimator_seed = (int(s) for s in rng.randint(_SEED_MAX, size=2))
    estimator = clone(estimator)
    if random_state is not None:
        seed_estimator(estimator, estimator_seed)
    if incumbent is None:
        incumbent = PriorModel(prior=find_prior(estimator))
    scorer = check_scoring(estimator, scoring=scoring)
    splitter = _check_cv(cv, y, cv_seed if random_state is not None else None)
    folds = [(np.asarray(tr), np.asarray(va)) for tr, va in splitter.split(X, y)]
    _check_sizes(sizes, folds, len(y))
    perms = [check_random_state(int(seed)).permutation(tr)
             for seed, (tr, _) in zip(rng.randint(_SEED_MAX, size=len(folds)), folds)]
    return (yield from _curve(estimator, incumbent, X, y, sizes, folds, perms, scorer,
                              scoring, {}))


def selection_learning_curve(model: Any, X: Any, y: ArrayLike, *, train_sizes: ArrayLike,
                             random_state: int | np.random.RandomState | None = None,
                             n_jobs: int | None = None) -> LearningCurve:
    """The augmented learning curve of a fitted :class:`~workbench.BaseBoostCV` on its own
    folds (``X``, ``y``: the rows it was fitted on), with its candidate seeded as in its
    selection and its incumbent and scoring: where a size is a fold's whole training set
    the selection's fold fit is the point (no fit again; it needs the training scores of
    ``BaseBoostCV(return_train_score=True)``).

    Parameters
    ----------
    model : BaseBoostCV
        The fitted model.
    X, y : array-like
        The rows it was fitted on.
    train_sizes : array-like of int
        The training sizes (row counts).
    random_state : int, RandomState instance or None, default=None
        Seeds the per-fold row permutations.
    n_jobs : int, default=None
        Processes for the fits (:mod:`workbench.parallel`; ``None``: 1).

    Returns
    -------
    LearningCurve
        The curve.
    """
    return run_plans([selection_curve_plan(model, X, y, train_sizes=train_sizes,
                                           random_state=random_state)], n_jobs)[0]


def selection_curve_plan(model: Any, X: Any, y: ArrayLike, *, train_sizes: ArrayLike,
                         random_state: int | np.random.RandomState | None = None) -> Plan:
    """:func:`selection_learning_curve` as a plan (:mod:`workbench.parallel`).

    Parameters
    ----------
    model, X, y, train_sizes, random_state
        As in :func:`selection_learning_curve`.

    Returns
    -------
    LearningCurve
        The plan's value (a generator's: run by :func:`~workbench.parallel.run_plans`).

    Yields
    ------
    list of Task
        Each batch of tasks to run (:func:`~workbench.parallel.run_plans` runs them).
        The batch's results are sent back, in its order.
    """
    if not hasattr(model, "cv_splits_"):
        raise ValueError(f"{type(model).__name__} is not a fitted BaseBoostCV (no cv_splits_)")
    scoring = model.scoring
    X, y, sizes = _inputs(X, y, scoring, train_sizes)
    folds = model.cv_splits_
    if len(y) != len(model.cv_predictions_prior_):
        raise ValueError(f"X has {len(y)} rows but the model was fitted on "
                         f"{len(model.cv_predictions_prior_)}")
    _check_sizes(sizes, folds, len(y))
    estimator = model._candidate()
    incumbent = (PriorModel(prior=find_prior(estimator)) if model.incumbent is None
                 else model.incumbent)
    scorer = check_scoring(estimator, scoring=scoring)
    rng = check_random_state(random_state)
    perms = [check_random_state(int(seed)).permutation(tr)
             for seed, (tr, _) in zip(rng.randint(_SEED_MAX, size=len(folds)), folds)]
    known = {}
    for j, (tr, _) in enumerate(folds):
        if np.isfinite(model.cv_scores_boosted_[j]) and \
                np.isfinite(model.cv_train_scores_boosted_[j]):  # else: fitted again
            known[(len(tr), j)] = (len(tr), -float(model.cv_train_scores_boosted_[j]),
                                   -float(model.cv_scores_boosted_[j]),
                                   -float(model.cv_scores_prior_[j]), None)
    return (yield from _curve(estimator, incumbent, X, y, sizes, folds, perms, scorer,
                              scoring, known))


def _curve(estimator: Any, incumbent: Any, X: Any, y: np.ndarray, sizes: np.ndarray,
           folds: list[tuple[np.ndarray, np.ndarray]], perms: list[np.ndarray], scorer: Callable,
           scoring: str | Callable, known: dict[tuple[int, int], tuple]) -> Plan:
    """The (size, fold) fits not in ``known`` ((size, fold) -> point), as one batch of tasks;
    returns the curve."""
    points = [(i, j) for i in range(len(sizes)) for j in range(len(folds))]
    todo, tasks = [], []
    for i, j in points:
        size, (tr, va) = int(sizes[i]), folds[j]
        if (size, j) in known:
            continue
        task = Task(_one, estimator, incumbent, X, y, _rows(perms[j], tr, size), va, size, j,
                    scorer)
        task.priority = size  # on several processes the largest fits first
        todo.append((i, j))
        tasks.append(task)
    done = dict(zip(todo, (yield tasks) if tasks else []))
    shape = (len(sizes), len(folds))
    n_rows = np.zeros(shape, dtype=int)
    train_err, cv_err, inc_err = (np.full(shape, np.nan) for _ in range(3))
    errors = []
    for i, j in points:
        n, tr_e, cv_e, inc_e, err = done.get((i, j)) or known[(int(sizes[i]), j)]
        n_rows[i, j], train_err[i, j], cv_err[i, j], inc_err[i, j] = n, tr_e, cv_e, inc_e
        if err is not None:
            errors.append(err)
    if errors:
        warnings.warn(f"{len(errors)} of {len(points)} candidate fits of the learning curve "
                      f"failed and are NaN. First error: {errors[0]}", FitFailedWarning,
                      stacklevel=2)
    return LearningCurve(
        train_sizes=sizes,
        n_train_rows=n_rows,
        train_error=train_err,
        cv_error=cv_err,
        incumbent_error=inc_err,
        n_validation_rows=np.array([len(va) for _, va in folds]),
        scoring=scoring if isinstance(scoring, str) else repr(scoring),
        fit_errors=tuple(errors),
    )
