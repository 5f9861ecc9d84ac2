"""Bootstrap intervals of the test errors over the test rows.

Per target, the average over targets, and the paired difference of two systems (a row is
one experiment, shared by all its targets, so the rows are resampled jointly).

:func:`bootstrap_error_interval` computes them for one error matrix, :func:`bootstrap_test_scores`
for a result's prior and model at once (one set of resamples for every statistic, each
resample a row of counts, all means one product). Above :data:`BOOTSTRAP_EXACT_ROWS` rows,
where every resampled mean is near normal, the same percentiles come from the Cornish-Fisher
expansion of the bootstrap distribution (:func:`bootstrap_method`).
"""

from __future__ import annotations

from statistics import NormalDist
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from .scores import ModelScores, Scores

#: A seed, or a generator drawn from.
_Seed = int | np.random.Generator | None

__all__ = ["BOOTSTRAP_EXACT_ROWS", "BOOTSTRAP_LEVEL", "BOOTSTRAP_RESAMPLES",
           "CORNISH_FISHER_LIMIT", "ErrorInterval", "bootstrap_description",
           "bootstrap_error_interval", "bootstrap_method", "bootstrap_test_scores"]

#: The level of the test errors' bootstrap intervals.
BOOTSTRAP_LEVEL = 0.95
#: Bootstrap resamples of the test rows: the interval's ends move by about 0.5% of its width
#: from one seed to another (41 rows, 5 targets: a few milliseconds).
BOOTSTRAP_RESAMPLES = 10_000
#: Up to this many rows the intervals resample (percentile bootstrap); above it they come from
#: the Cornish-Fisher expansion of the same bootstrap distribution (:func:`bootstrap_method`).
BOOTSTRAP_EXACT_ROWS = 2_000
#: Cornish-Fisher only where the resampled means' skewness and excess kurtosis are at most
#: this (else the rows are resampled): ``benchmarks/bootstrap.py`` found the expansion within
#: the percentile bootstrap's own Monte Carlo error there, and up to 3 times it beyond.
CORNISH_FISHER_LIMIT = 0.5

class ErrorInterval(NamedTuple):
    """Bootstrap intervals of a mean error.

    Parameters
    ----------
    per_target : list of [low, high]
        One interval per target.
    average : [low, high]
        The interval of the average over targets.
    """

    per_target: list[list[float]]
    average: list[float]


def _error_matrix(name: str, errors: ArrayLike) -> np.ndarray:
    arr = np.asarray(errors, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{name} must have shape (n_rows,) or (n_rows, n_targets) with at "
                         f"least one row and target; got shape {np.shape(errors)}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} has non-finite values")
    return arr


def _check_settings(level: float, n_resamples: int) -> None:
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1); got {level}")
    if isinstance(n_resamples, bool) or not isinstance(n_resamples, (int, np.integer)) \
            or n_resamples < 1:
        raise ValueError(f"n_resamples must be a positive int; got {n_resamples!r}")


def _percentile_means(stats: np.ndarray, n_resamples: int, random_state: _Seed
                      ) -> np.ndarray:
    """Mean of every column of ``stats`` (n_rows, m) over each of ``n_resamples`` resamples.

    Rows are drawn with replacement, shape ``(n_resamples, m)``: every column sees the same
    resampled rows. A resample is a row of counts (how often each row was drawn), so all the
    columns' means are one product ``counts @ stats``, in chunks of at most 2e6 counts. The
    rows drawn depend only on ``n_rows``, ``n_resamples`` and ``random_state``.
    """
    n, m = stats.shape
    rng = np.random.default_rng(random_state)
    means = np.empty((n_resamples, m))
    step = max(1, 2_000_000 // n)
    for start in range(0, n_resamples, step):
        k = min(step, n_resamples - start)
        drawn = rng.integers(0, n, size=(k, n))
        drawn += (np.arange(k) * n)[:, None]  # resample i's rows counted in bins i*n ...
        counts = np.bincount(drawn.ravel(), minlength=k * n).reshape(k, n)
        means[start:start + k] = counts @ stats / n
    return means


def _cumulants(stats: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Moments of the bootstrap distribution of each column's mean.

    Per column of ``stats`` (n_rows, m): the mean, and the variance, skewness and excess
    kurtosis of the bootstrap distribution of its mean (from the plug-in cumulants k2, k3, k4
    of the column: k2 / n, k3 / (k2^1.5 sqrt(n)), k4 / (k2^2 n); 0 for a constant column).
    """
    n = stats.shape[0]
    mean = stats.mean(axis=0)
    c = stats - mean
    k2 = (c ** 2).mean(axis=0)
    k3 = (c ** 3).mean(axis=0)
    k4 = (c ** 4).mean(axis=0) - 3 * k2 ** 2
    safe = np.where(k2 > 0, k2, 1.0)
    skew = np.where(k2 > 0, k3 / (safe ** 1.5 * np.sqrt(n)), 0.0)
    kurt = np.where(k2 > 0, k4 / (safe ** 2 * n), 0.0)
    return mean, k2 / n, skew, kurt


def _cornish_fisher(stats: np.ndarray, level: float) -> np.ndarray:
    """Percentiles of each column mean's bootstrap distribution by Cornish-Fisher.

    Per column of ``stats`` (n_rows, m), the ``[low, high]`` percentiles (central ``level``)
    of the bootstrap distribution of its mean, from that distribution's exact cumulants
    (:func:`_cumulants`) through the Cornish-Fisher expansion to second order. Shape ``(m, 2)``.
    """
    mean, var, g1, g2 = _cumulants(stats)
    z = np.array([[NormalDist().inv_cdf((1 - level) / 2),
                   NormalDist().inv_cdf((1 + level) / 2)]])
    g1, g2 = g1[:, None], g2[:, None]
    w = (z + (z ** 2 - 1) * g1 / 6 + (z ** 3 - 3 * z) * g2 / 24
         - (2 * z ** 3 - 5 * z) * g1 ** 2 / 36)
    return mean[:, None] + np.sqrt(var)[:, None] * w


def bootstrap_method(stats: ArrayLike) -> str:
    """Choose how :func:`bootstrap_error_interval` computes the intervals of the column means.

    Parameters
    ----------
    stats : array-like of shape (n_rows, m)
        Per-row values whose column means get intervals.

    Returns
    -------
    str
        ``"percentile"`` (resampling the rows) up to :data:`BOOTSTRAP_EXACT_ROWS` rows, or
        where the resampled mean of some column is far from normal (skewness or excess
        kurtosis above :data:`CORNISH_FISHER_LIMIT`, as for squared errors with heavy tails);
        else ``"cornish_fisher"``: the same percentiles from the Cornish-Fisher expansion of
        that distribution, without resampling.
    """
    stats = np.asarray(stats, dtype=float)
    if len(stats) <= BOOTSTRAP_EXACT_ROWS:
        return "percentile"
    _, _, skew, kurt = _cumulants(stats.reshape(len(stats), -1))
    near_normal = max(np.abs(skew).max(), np.abs(kurt).max()) <= CORNISH_FISHER_LIMIT
    return "cornish_fisher" if near_normal else "percentile"


def _intervals(stats: np.ndarray, level: float, n_resamples: int, random_state: _Seed,
               method: str | None = None) -> tuple[np.ndarray, str]:
    """Bootstrap interval of every column's mean, shape ``(m, 2)``, and the method used.

    The percentile bootstrap or Cornish-Fisher, as ``method`` or else
    :func:`bootstrap_method` says.
    """
    method = method or bootstrap_method(stats)
    if method == "cornish_fisher":
        return _cornish_fisher(stats, level), method
    means = _percentile_means(stats, n_resamples, random_state)
    return np.quantile(means, [(1 - level) / 2, (1 + level) / 2], axis=0).T, method


def _error_interval(stat: np.ndarray, level: float, n_resamples: int,
                    random_state: _Seed) -> tuple[np.ndarray, np.ndarray]:
    """Per-target and average intervals of the mean of ``stat`` (n_rows, n_targets)."""
    both, _ = _intervals(np.column_stack([stat, stat.mean(axis=1)]), level, n_resamples,
                         random_state)
    return both[:-1], both[-1]


def bootstrap_error_interval(errors: ArrayLike, *, baseline: ArrayLike | None = None,
                             squared: bool = False,
                             level: float = BOOTSTRAP_LEVEL,
                             n_resamples: int = BOOTSTRAP_RESAMPLES,
                             random_state: int | np.random.Generator | None = 0
                             ) -> ErrorInterval:
    """Bootstrap intervals of the mean absolute (``squared``: squared) error.

    Each of ``n_resamples`` resamples draws ``n_rows`` rows with replacement, the same rows
    for every target (a row is one experiment, measured for all its targets), and computes
    each target's mean error and their average over targets; the interval is the central
    ``level`` of those values (percentile bootstrap).

    Above :data:`BOOTSTRAP_EXACT_ROWS` rows, where every resampled mean is near normal,
    nothing is resampled: the same percentiles come from the Cornish-Fisher expansion of the
    resampled mean's distribution, whose cumulants follow exactly from the rows
    (:func:`bootstrap_method`; ``benchmarks/bootstrap.py`` measures how closely the two
    agree: on simulated and IBM gate errors, closer than two seeds of 10,000 resamples).

    The resampled rows depend only on ``n_rows``, ``n_resamples`` and ``random_state``: the
    same seed gives the same numbers, and calls with the same seed on errors of the same rows
    (the prior's, the model's, their difference) see the same resamples.

    Parameters
    ----------
    errors : array-like of shape (n_rows,) or (n_rows, n_targets)
        E.g. ``y - prediction`` on the test rows.
    baseline : array-like of the shape of ``errors``, default=None
        The errors of another system on the same rows: the statistic is then the difference
        ``mean error(errors) - mean error(baseline)`` on each resample, the paired interval of
        the difference (below 0: ``errors`` are the smaller).
    squared : bool, default=False
        Squared errors instead of absolute ones.
    level : float, default=BOOTSTRAP_LEVEL
        Central probability of the intervals, in (0, 1).
    n_resamples : int, default=BOOTSTRAP_RESAMPLES
        Resamples of the rows.
    random_state : int, Generator or None, default=0
        Seed of the resamples.

    Returns
    -------
    ErrorInterval
        Per target ``[low, high]`` and the average's.

    Raises
    ------
    ValueError
        An empty or non-finite error matrix, a baseline of another shape, a level outside
        (0, 1) or a non-positive number of resamples.
    """
    _check_settings(level, n_resamples)
    e = _error_matrix("errors", errors)
    stat = e ** 2 if squared else np.abs(e)
    if baseline is not None:
        b = _error_matrix("baseline", baseline)
        if b.shape != e.shape:
            raise ValueError(f"baseline must have the shape of errors {e.shape}; got {b.shape}")
        stat = stat - (b ** 2 if squared else np.abs(b))
    per_target, average = _error_interval(stat, level, n_resamples, random_state)
    return ErrorInterval(per_target=per_target.tolist(), average=average.tolist())



def bootstrap_test_scores(prior: Scores, model: ModelScores, y: ArrayLike,
                          prior_pred: ArrayLike, pred: ArrayLike, *,
                          level: float = BOOTSTRAP_LEVEL,
                          n_resamples: int = BOOTSTRAP_RESAMPLES,
                          random_state: int = 0) -> dict[str, Any]:
    """Set the bootstrap intervals of ``prior``'s and ``model``'s test errors.

    Sets ``test_mae_ci``, ``test_mae_avg_ci``, ``test_mse_ci``, ``test_mse_avg_ci`` of both,
    and the model's paired ``test_mae_diff_ci``, ``test_mae_diff_avg_ci`` (model - prior).
    Every interval is :func:`bootstrap_error_interval` with one ``random_state``, so all of
    them see the same resampled rows.

    Parameters
    ----------
    prior : Scores
        The prior's scores, updated in place.
    model : ModelScores
        The model's scores, updated in place.
    y : array-like of shape (n_rows, n_targets)
        The test rows' targets.
    prior_pred, pred : array-like of shape (n_rows, n_targets)
        The prior's and the model's predictions.
    level : float, default=BOOTSTRAP_LEVEL
        Central probability of the intervals.
    n_resamples : int, default=BOOTSTRAP_RESAMPLES
        Resamples of the rows (percentile bootstrap).
    random_state : int, default=0
        Seed of the resamples.

    Returns
    -------
    dict
        The settings used: a :class:`~workbench.experiment.scoring.results.Result`'s ``bootstrap``
        section.

    Raises
    ------
    ValueError
        As :func:`bootstrap_error_interval`.
    """
    _check_settings(level, n_resamples)
    y = _error_matrix("y", y)
    model_err = y - np.reshape(np.asarray(pred, dtype=float), y.shape)
    prior_err = y - np.reshape(np.asarray(prior_pred, dtype=float), y.shape)
    # every statistic's per-row values side by side, each followed by its average over
    # targets: one pass over the resamples computes all their intervals
    parts = [(prior, "test_mae", np.abs(prior_err)), (prior, "test_mse", prior_err ** 2),
             (model, "test_mae", np.abs(model_err)), (model, "test_mse", model_err ** 2),
             (model, "test_mae_diff", np.abs(model_err) - np.abs(prior_err))]
    t = y.shape[1]
    stats = np.column_stack([c for _, _, v in parts for c in (v, v.mean(axis=1))])
    bounds, method = _intervals(stats, level, n_resamples, random_state)
    for i, (scores, key, _) in enumerate(parts):
        block = bounds[i * (t + 1):(i + 1) * (t + 1)]
        setattr(scores, f"{key}_ci", block[:-1].tolist())
        setattr(scores, f"{key}_avg_ci", block[-1].tolist())
    settings: dict[str, Any] = {"method": method, "level": level}
    if settings["method"] == "percentile":
        settings["n_resamples"] = n_resamples
    settings.update(random_state=random_state, n_rows=len(y))
    return settings


def bootstrap_description(settings: dict[str, Any]) -> str:
    """Say in words how a result's bootstrap intervals were computed, for reports.

    Parameters
    ----------
    settings : dict
        A result's ``bootstrap`` section (:func:`bootstrap_test_scores`' return).

    Returns
    -------
    str
        One phrase, e.g. ``percentile bootstrap, 10,000 resamples of the rows``.
    """
    if settings.get("method") == "cornish_fisher":
        return (f"{settings['n_rows']:,} rows: the percentiles of the bootstrap distribution "
                "from its Cornish-Fisher expansion, without resampling")
    return (f"percentile bootstrap, {settings.get('n_resamples', BOOTSTRAP_RESAMPLES):,} "
            "resamples of the rows")
