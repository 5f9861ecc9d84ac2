"""The CV folds on the training rows, and what they follow: groups, the rows' order, or neither.

Every fold of a command is made here, so the data's structure reaches all of them: a
dataset with an order (``[data] order_column``: dates, times, run numbers) gets
forward-chaining folds (:class:`~workbench.selection.LabelTimeSeriesSplit`, scikit-learn's
``TimeSeriesSplit`` over the rows sorted by it) in BaseBoostCV and BasisChoiceCV
(``[selection]``), the learning curves, the out-of-fold intervals and a sweep's inner and
outer folds (``[cv]``), and a family's own choices (:func:`family_cv`: the parametric
family's covariate selection, its choice among its candidates and its out-of-fold priors); a
dataset with groups (``[selection] groups``) keeps each whole in those folds; else plain
K-fold. :func:`check_fold_settings` refuses, in one line, the settings whose folds cannot
follow an order; :func:`describe_folds` says which folds a run used.
"""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np
from sklearn.model_selection import KFold

from ...selection import LabelGroupKFold, LabelTimeSeriesSplit, ordered_splits
from ..process.errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from ...datasets import Dataset
    from ..config import DataConfig, ExperimentConfig

__all__ = ["check_fold_settings", "curve_cv", "describe_folds", "family_cv",
           "largest_curve_size", "make_folds", "outer_order_splits", "selection_cv",
           "sweep_inner_cv"]


def make_folds(ds: Dataset | None, n_splits: int, *, shuffle: bool = False,
               random_state: int | None = None, groups: bool = False) -> Any:
    """Make ``n_splits`` folds that follow ``ds``: its order, else its groups, else none.

    Parameters
    ----------
    ds : Dataset or None
        The dataset (its ``order`` and ``groups``); ``None``: plain folds.
    n_splits : int
        The folds.
    shuffle : bool, default=False
        Plain and grouped folds: shuffle the rows (groups) first (never ordered folds).
    random_state : int, default=None
        Seeds the shuffle.
    groups : bool, default=False
        Keep the dataset's groups whole (when it has no order).

    Returns
    -------
    cross-validator
        ``LabelTimeSeriesSplit``, ``LabelGroupKFold`` or ``KFold``.
    """
    seed = random_state if shuffle else None
    if ds is not None and ds.order is not None:
        return LabelTimeSeriesSplit(ds.order, n_splits)
    if groups and ds is not None and ds.groups is not None:
        n_splits = _group_folds(ds, n_splits)
        return LabelGroupKFold(ds.groups, n_splits, shuffle=shuffle, random_state=seed)
    return KFold(n_splits, shuffle=shuffle, random_state=seed)


def _group_folds(ds: Dataset, n_splits: int) -> int:
    """Count the grouped folds: ``n_splits``, or the training rows' groups if fewer.

    Fewer groups than folds: one group held out per fold, with a warning; at least two
    groups are needed (else a ConfigError naming the column).
    """
    groups = ds.groups
    assert groups is not None  # make_folds' caller checked
    n_groups = int(groups.loc[ds.train_index].nunique())
    if n_groups >= n_splits:
        return n_splits
    if n_groups < 2:
        raise ConfigError(f"the training rows hold {n_groups} group(s) of `{groups.name}`: "
                          "grouped folds need at least 2 (set [selection] groups = false)")
    warnings.warn(f"the training rows hold {n_groups} groups of `{groups.name}`, fewer than "
                  f"the {n_splits} folds: {n_groups} folds, one group held out in each",
                  UserWarning, stacklevel=3)
    return n_groups


def selection_cv(cfg: ExperimentConfig, ds: Dataset | None = None) -> Any:
    """Make BaseBoostCV's folds (``[selection]`` cv, shuffle, groups).

    Forward-chaining when the dataset has an order, whole groups when it has groups and
    ``[selection] groups`` is true (its default), else ``KFold`` (contiguous unless
    ``shuffle``, seeded by ``random_state``).

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.
    ds : Dataset, optional
        The dataset (its order and groups).

    Returns
    -------
    cross-validator
        The folds.
    """
    s = cfg.selection
    return make_folds(ds, s.cv, shuffle=s.shuffle, random_state=cfg.random_state,
                      groups=s.groups)


def family_cv(cfg: ExperimentConfig, ds: Dataset | None, n_splits: int) -> Any:
    """Make the folds of a family's own CV (e.g. ``[model.parametric] selection_cv``).

    BaseBoostCV's semantics: forward-chaining by the dataset's order when it has one; whole
    groups when it has groups and ``[selection] groups`` is true (the groups shuffled,
    seeded by ``random_state``); else ``KFold(n_splits, shuffle=True)`` seeded by
    ``random_state`` (0 when unset), a family's folds before they followed the data.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config (``random_state``, ``[selection] groups``).
    ds : Dataset or None
        The dataset (its order and groups).
    n_splits : int
        The folds.

    Returns
    -------
    cross-validator
        ``LabelTimeSeriesSplit``, ``LabelGroupKFold`` or shuffled ``KFold``.
    """
    return make_folds(ds, n_splits, shuffle=True, random_state=cfg.random_state or 0,
                      groups=cfg.selection.groups)


def sweep_inner_cv(cfg: ExperimentConfig, ds: Dataset | None = None) -> Any:
    """Make a sweep's inner folds.

    ``[cv]`` inner_folds, shuffled with its ``sweep_seed``; forward-chaining when the dataset has an
    order.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.
    ds : Dataset, optional
        The dataset (its order and groups).

    Returns
    -------
    cross-validator
        The folds.
    """
    return make_folds(ds, cfg.cv.inner_folds, shuffle=True, random_state=cfg.cv.sweep_seed)


def outer_order_splits(cfg: ExperimentConfig, ds: Dataset) -> list[tuple[np.ndarray, np.ndarray]]:
    """Chain a sweep's outer folds forward by the dataset's order.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config (``[cv]`` outer_folds; one repeat).
    ds : Dataset
        The dataset, with an order.

    Returns
    -------
    list of (train, validation) index arrays
        Positions into the training rows.
    """
    assert ds.order is not None  # the caller asks only then
    return ordered_splits(ds.order.loc[ds.train_index].to_numpy(), cfg.cv.outer_folds)


def curve_cv(cfg: ExperimentConfig, ds: Dataset) -> Any:
    """Make the learning curves' folds.

    The selection's when they follow the data (its order or groups), else
    ``[selection] cv`` as an int (seeded shuffled folds).

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.
    ds : Dataset
        The dataset.

    Returns
    -------
    int or cross-validator
        The curves' ``cv``.
    """
    cv = selection_cv(cfg, ds)
    return cfg.selection.cv if isinstance(cv, KFold) else cv


def largest_curve_size(cv: Any, X: pd.DataFrame) -> int:
    """Count the rows the smallest fold of ``cv`` trains on.

    Parameters
    ----------
    cv : int or cross-validator
        The folds (an int: ``KFold``'s).
    X : DataFrame
        The rows they split.

    Returns
    -------
    int
        The smallest fold's training rows.
    """
    if isinstance(cv, int):
        return len(X) - math.ceil(len(X) / cv)
    return min(len(train) for train, _ in cv.split(X))


def describe_folds(cv: Any) -> str:
    """Say which folds ``cv`` makes.

    Parameters
    ----------
    cv : cross-validator
        The folds.

    Returns
    -------
    str
        E.g. ``"5 forward-chaining by `date`"``, ``"5 by groups `device`"``,
        ``"5 shuffled"`` or ``"5 contiguous"``.
    """
    n = cv.get_n_splits()
    if isinstance(cv, LabelTimeSeriesSplit):
        return f"{n} forward-chaining by `{cv.order.name or 'order'}`"
    if isinstance(cv, LabelGroupKFold):
        return f"{n} by groups `{cv.groups.name or 'group'}`"
    if isinstance(cv, KFold):
        return f"{n} {'shuffled' if cv.shuffle else 'contiguous'}"
    return f"{n} ({type(cv).__name__})"


def check_fold_settings(cfg: ExperimentConfig) -> None:
    """Refuse the settings whose folds cannot follow ``[data] order_column``.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.

    Raises
    ------
    ValueError
        One line naming the setting and what to do.
    """
    data: DataConfig = cfg.data
    column = data.order_column
    if column is None:
        return
    why = f"[data] order_column = {column!r} makes forward-chaining folds"
    iv, ev = cfg.intervals, cfg.evaluation
    if iv.enabled and iv.method in ("cv_plus", "cv"):
        raise ValueError(f"[intervals] method = {iv.method!r} needs every training row in one "
                         f"validation fold, but {why} (the earliest rows are never held out); "
                         f"use method = 'oof' or 'split'")
    if ev.cv_repeats > 0 or ev.nested_folds > 0:
        key = "cv_repeats" if ev.cv_repeats > 0 else "nested_folds"
        raise ValueError(f"[evaluation] {key}: its folds are shuffled, and {why}; set "
                         f"{key} = 0 (the test rows score the model on later rows)")
    if cfg.cv.repeats > 1:
        raise ValueError(f"[cv] repeats = {cfg.cv.repeats}: {why}, the same on every repeat; "
                         f"set repeats = 1")

