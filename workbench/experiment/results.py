"""What ``evaluate``, ``sweep`` and ``reproduce`` produce: dataclasses with one ``to_json``.

Modules read fields, never string keys. :meth:`Result.to_json` keeps the JSON that
``--json`` has always written (``targets``, ``prior.test_mae[_avg]``, ``model.test_mae[_avg]``,
``model.test_mse``, ``model.cv_mae[_avg]``, ``model.cv_mse``, ``model.selected``,
``nested_cv_mae[_avg]``, ``best_params``, ``wall_s``, ...), so scripts that read it keep working.
With conformal intervals (``[intervals]``) ``model`` adds ``test_coverage[_avg]``,
``test_width[_avg]``, ``cv_coverage[_avg]`` and ``cv_width[_avg]``, and the result an
``intervals`` section (method, alpha, level, folds).

Every test error comes with a percentile-bootstrap interval over the test rows
(:func:`bootstrap_error_interval`; a row is one experiment, shared by all its targets, so the
rows are resampled jointly): ``prior`` and ``model`` add ``test_mae_ci`` and ``test_mse_ci``
(per target ``[low, high]``) and ``test_mae_avg_ci``, ``test_mse_avg_ci`` (the average over
targets' ``[low, high]``); ``model`` adds the paired interval of its difference to the prior,
``test_mae_diff_ci`` and ``test_mae_diff_avg_ci`` (model - prior on the same resampled rows:
below 0, the model's error is the lower); the result a ``bootstrap`` section (method,
level, resamples, seed, rows). Only keys are added: a script that read the JSON before reads
it unchanged.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from statistics import NormalDist
from typing import Any, NamedTuple

import numpy as np

__all__ = ["BOOTSTRAP_EXACT_ROWS", "BOOTSTRAP_LEVEL", "BOOTSTRAP_RESAMPLES",
           "CORNISH_FISHER_LIMIT", "CVEstimate", "ErrorInterval", "ModelScores", "OuterFold",
           "Result", "Scores", "SweepSummary", "bootstrap_description",
           "bootstrap_error_interval", "bootstrap_method", "bootstrap_test_scores", "mae",
           "mse"]

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


def mae(y, pred) -> list[float]:
    """Per-column mean absolute error."""
    return np.mean(np.abs(np.asarray(y, float) - np.asarray(pred, float)), axis=0).tolist()


def mse(y, pred) -> list[float]:
    """Per-column mean squared error."""
    return np.mean((np.asarray(y, float) - np.asarray(pred, float)) ** 2, axis=0).tolist()


def _avg(values: list[float]) -> float:
    return float(np.mean(values)) if len(values) else math.nan


class ErrorInterval(NamedTuple):
    """Bootstrap intervals of a mean error: ``per_target`` one ``[low, high]`` per target,
    ``average`` the ``[low, high]`` of the average over targets."""

    per_target: list[list[float]]
    average: list[float]


def _error_matrix(name: str, errors) -> np.ndarray:
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


def _percentile_means(stats: np.ndarray, n_resamples: int, random_state) -> np.ndarray:
    """The mean of every column of ``stats`` (n_rows, m) over each of ``n_resamples``
    resamples of the rows with replacement, shape ``(n_resamples, m)``: every column sees the
    same resampled rows. A resample is a row of counts (how often each row was drawn), so all
    the columns' means are one product ``counts @ stats``, in chunks of at most 2e6 counts.
    The rows drawn depend only on ``n_rows``, ``n_resamples`` and ``random_state``."""
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
    """Per column of ``stats`` (n_rows, m): the mean, and the variance, skewness and excess
    kurtosis of the bootstrap distribution of its mean (from the plug-in cumulants k2, k3,
    k4 of the column: k2 / n, k3 / (k2^1.5 sqrt(n)), k4 / (k2^2 n); 0 for a constant
    column)."""
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
    """Per column of ``stats`` (n_rows, m), the ``[low, high]`` percentiles (central
    ``level``) of the bootstrap distribution of its mean, from that distribution's exact
    cumulants (:func:`_cumulants`) through the Cornish-Fisher expansion to second order.
    Shape ``(m, 2)``."""
    mean, var, g1, g2 = _cumulants(stats)
    z = np.array([[NormalDist().inv_cdf((1 - level) / 2),
                   NormalDist().inv_cdf((1 + level) / 2)]])
    g1, g2 = g1[:, None], g2[:, None]
    w = (z + (z ** 2 - 1) * g1 / 6 + (z ** 3 - 3 * z) * g2 / 24
         - (2 * z ** 3 - 5 * z) * g1 ** 2 / 36)
    return mean[:, None] + np.sqrt(var)[:, None] * w


def bootstrap_method(stats) -> str:
    """How :func:`bootstrap_error_interval` computes the intervals of the means of the columns
    of ``stats`` (n_rows, m): ``"percentile"`` (resampling the rows) up to
    :data:`BOOTSTRAP_EXACT_ROWS` rows, or where the resampled mean of some column is far from
    normal (skewness or excess kurtosis above :data:`CORNISH_FISHER_LIMIT`, as for squared
    errors with heavy tails); else ``"cornish_fisher"``: the same percentiles from the
    Cornish-Fisher expansion of that distribution, without resampling."""
    stats = np.asarray(stats, dtype=float)
    if len(stats) <= BOOTSTRAP_EXACT_ROWS:
        return "percentile"
    _, _, skew, kurt = _cumulants(stats.reshape(len(stats), -1))
    near_normal = max(np.abs(skew).max(), np.abs(kurt).max()) <= CORNISH_FISHER_LIMIT
    return "cornish_fisher" if near_normal else "percentile"


def _intervals(stats: np.ndarray, level: float, n_resamples: int, random_state,
               method: str | None = None) -> tuple[np.ndarray, str]:
    """The bootstrap interval of every column's mean, shape ``(m, 2)``, and the method: the
    percentile bootstrap or Cornish-Fisher, as ``method`` or else :func:`bootstrap_method`
    says."""
    method = method or bootstrap_method(stats)
    if method == "cornish_fisher":
        return _cornish_fisher(stats, level), method
    means = _percentile_means(stats, n_resamples, random_state)
    return np.quantile(means, [(1 - level) / 2, (1 + level) / 2], axis=0).T, method


def _error_interval(stat: np.ndarray, level: float, n_resamples: int,
                    random_state) -> tuple[np.ndarray, np.ndarray]:
    """Per-target and average intervals of the mean of ``stat`` (n_rows, n_targets)."""
    both, _ = _intervals(np.column_stack([stat, stat.mean(axis=1)]), level, n_resamples,
                         random_state)
    return both[:-1], both[-1]


def bootstrap_error_interval(errors, *, baseline=None, squared: bool = False,
                             level: float = BOOTSTRAP_LEVEL,
                             n_resamples: int = BOOTSTRAP_RESAMPLES,
                             random_state: int | np.random.Generator | None = 0
                             ) -> ErrorInterval:
    """Bootstrap intervals of the mean absolute (``squared``: squared) error.

    ``errors``: shape ``(n_rows,)`` or ``(n_rows, n_targets)``, e.g. ``y - prediction`` on
    the test rows. Each of ``n_resamples`` resamples draws ``n_rows`` rows with replacement,
    the same rows for every target (a row is one experiment, measured for all its targets),
    and computes each target's mean error and their average over targets; the interval is
    the central ``level`` of those values (percentile bootstrap). With ``baseline`` (the
    errors of another system on the same rows, same shape) the statistic is the difference
    ``mean error(errors) - mean error(baseline)`` on each resample: the paired interval of
    the difference (below 0: ``errors`` are the smaller).

    Above :data:`BOOTSTRAP_EXACT_ROWS` rows, where every resampled mean is near normal,
    nothing is resampled: the same percentiles come from the Cornish-Fisher expansion of the
    resampled mean's distribution, whose cumulants follow exactly from the rows
    (:func:`bootstrap_method`; ``benchmarks/bootstrap.py`` measures how closely the two
    agree: on simulated and IBM gate errors, closer than two seeds of 10,000 resamples).

    The resampled rows depend only on ``n_rows``, ``n_resamples`` and ``random_state``: the
    same seed gives the same numbers, and calls with the same seed on errors of the same rows
    (the prior's, the model's, their difference) see the same resamples.

    Returns an :class:`ErrorInterval`: per target ``[low, high]`` and the average's.
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


@dataclass
class Scores:
    """Per-target test and CV errors of one system (the prior, or the model), and the
    bootstrap intervals of the test errors (:func:`bootstrap_test_scores`; empty: not
    computed): ``test_mae_ci`` one ``[low, high]`` per target, ``test_mae_avg_ci`` the
    average over targets' ``[low, high]``; the same for ``test_mse``."""

    test_mae: list[float]
    test_mse: list[float]
    cv_mae: list[float]
    cv_mse: list[float]
    test_mae_ci: list[list[float]] = field(default_factory=list)
    test_mae_avg_ci: list[float] = field(default_factory=list)
    test_mse_ci: list[list[float]] = field(default_factory=list)
    test_mse_avg_ci: list[float] = field(default_factory=list)

    def avg(self, key: str) -> float:
        """The average over targets of ``key`` (``"test_mae"``, ``"cv_mse"``, ...)."""
        return _avg(getattr(self, key))

    def ci(self, key: str) -> list[list[float]] | None:
        """The bootstrap intervals of ``key`` (``"test_mae"``, ``"test_mse"``; a model's
        ``"test_mae_diff"`` too): one ``[low, high]`` per target, then the average's, the
        rows :func:`~workbench.experiment.figures.mae_bars` takes (``None``: not computed)."""
        per_target, average = getattr(self, f"{key}_ci"), getattr(self, f"{key}_avg_ci")
        if not per_target or not average:
            return None
        return [*map(list, per_target), list(average)]

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name.endswith("_ci") and not value:  # intervals not computed: no key
                continue
            out[f.name] = value
            if f.name in ("test_mae", "test_mse", "cv_mae", "cv_mse"):
                out[f"{f.name}_avg"] = _avg(value)
        return out


#: The per-target interval figures of :class:`ModelScores` (empty lists: no intervals).
INTERVAL_KEYS = ("test_coverage", "test_width", "cv_coverage", "cv_width")


@dataclass
class ModelScores(Scores):
    """The model's scores plus what it chose per target; ``extra``: family-specific per-target
    figures (e.g. ``cv_mae_boosted``). With prediction intervals: per target the fraction of
    test rows inside their interval (``test_coverage``) and the mean width (``test_width``),
    and the same estimated by CV on the training rows (``cv_coverage``, ``cv_width``). With
    bootstrap intervals, those of model - prior test MAE (``test_mae_diff_ci``,
    ``test_mae_diff_avg_ci``), paired: both systems' errors on the same resampled rows."""

    selected: list[str] = field(default_factory=list)
    coefs: list[list[float]] = field(default_factory=list)
    extra: dict[str, list[float]] = field(default_factory=dict)
    test_coverage: list[float] = field(default_factory=list)
    test_width: list[float] = field(default_factory=list)
    cv_coverage: list[float] = field(default_factory=list)
    cv_width: list[float] = field(default_factory=list)
    #: The paired bootstrap interval of model - prior test MAE per target and of the average
    #: over targets (below 0: the model's error is the lower; :func:`bootstrap_test_scores`).
    test_mae_diff_ci: list[list[float]] = field(default_factory=list)
    test_mae_diff_avg_ci: list[float] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        out = super().to_json()
        out.update(out.pop("extra"))
        for key in INTERVAL_KEYS:
            if out[key]:
                out[f"{key}_avg"] = _avg(out[key])
            else:
                del out[key]
        return out


def bootstrap_test_scores(prior: Scores, model: ModelScores, y, prior_pred, pred, *,
                          level: float = BOOTSTRAP_LEVEL,
                          n_resamples: int = BOOTSTRAP_RESAMPLES,
                          random_state: int = 0) -> dict[str, Any]:
    """Set the bootstrap intervals of ``prior``'s and ``model``'s test errors from the test
    rows' targets ``y`` and the two systems' predictions (each of shape ``(n_rows,
    n_targets)``): ``test_mae_ci``, ``test_mae_avg_ci``, ``test_mse_ci``, ``test_mse_avg_ci``
    of both, and the model's paired ``test_mae_diff_ci``, ``test_mae_diff_avg_ci`` (model -
    prior). Every interval is :func:`bootstrap_error_interval` with one ``random_state``, so
    all of them see the same resampled rows. Returns the settings, a :class:`Result`'s
    ``bootstrap`` section."""
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
    """In words, how a result's bootstrap intervals were computed (its ``bootstrap`` section,
    :func:`bootstrap_test_scores`' return), for reports."""
    if settings.get("method") == "cornish_fisher":
        return (f"{settings['n_rows']:,} rows: the percentiles of the bootstrap distribution "
                "from its Cornish-Fisher expansion, without resampling")
    return (f"percentile bootstrap, {settings.get('n_resamples', BOOTSTRAP_RESAMPLES):,} "
            "resamples of the rows")


@dataclass
class CVEstimate:
    """A cross-validated estimate of the chosen model: repeated K-fold CV on the training rows
    (``repeats`` > 0) or nested CV over all rows (``n_rows``)."""

    folds: int
    seed: int
    model_mae: list[float]
    model_mse: list[float]
    prior_mae: list[float]
    repeats: int | None = None
    n_rows: int | None = None
    model_mae_avg_per_repeat: list[float] | None = None

    @property
    def model_mae_avg(self) -> float:
        return _avg(self.model_mae)

    @property
    def prior_mae_avg(self) -> float:
        return _avg(self.prior_mae)

    def to_json(self) -> dict[str, Any]:
        out = {k: v for k, v in asdict(self).items() if v is not None}
        out.update(model_mae_avg=self.model_mae_avg, model_mse_avg=_avg(self.model_mse),
                   prior_mae_avg=self.prior_mae_avg)
        return out


@dataclass
class OuterFold:
    """One outer fold of a sweep: its study's best settings refitted and scored."""

    unit: str
    fold: int
    study: str
    mae: float
    prior_mae: float
    selected: str
    n_train: int
    n_val: int
    params: dict[str, Any] | None
    target_mae: dict[str, float]
    target_prior_mae: dict[str, float]


@dataclass
class SweepSummary:
    """What a sweep adds to a result: nested-CV estimates, the chosen parameters per target
    (a unit's choice repeated for each of its targets), the trial counts."""

    nested_cv_mae: list[float]
    nested_cv_prior_mae: list[float]
    best_params: list[dict[str, Any] | None]
    trials_per_study: int
    trials_counted: int
    studies: int
    outer_folds: list[OuterFold] = field(default_factory=list)

    @property
    def nested_cv_mae_avg(self) -> float:
        return _avg(self.nested_cv_mae)

    @property
    def nested_cv_prior_mae_avg(self) -> float:
        return _avg(self.nested_cv_prior_mae)

    def to_json(self) -> dict[str, Any]:
        return {"nested_cv_mae": self.nested_cv_mae, "nested_cv_mae_avg": self.nested_cv_mae_avg,
                "nested_cv_prior_mae": self.nested_cv_prior_mae,
                "nested_cv_prior_mae_avg": self.nested_cv_prior_mae_avg,
                "best_params": self.best_params,
                "trials": {"per_study": self.trials_per_study, "counted": self.trials_counted,
                           "studies": self.studies}}


@dataclass
class Result:
    """One ``evaluate`` (or a sweep's final evaluation): the model fitted on the training rows
    and scored once on the test rows. ``details``: the family's own JSON-ready section (e.g.
    ``{"hamiltonian": {...}}``); ``wall_s``: the whole command's wall time."""

    name: str
    config: str | None
    family: str
    targets: list[str]
    n_train: int
    n_test: int
    prior: Scores
    model: ModelScores
    details: dict[str, Any] = field(default_factory=dict)
    repeated_cv: CVEstimate | None = None
    nested_cv_all: CVEstimate | None = None
    sweep: SweepSummary | None = None
    #: The prediction intervals' settings (method, alpha, level, ...); empty: none.
    intervals: dict[str, Any] = field(default_factory=dict)
    #: The test errors' bootstrap intervals' settings (method, level, n_resamples,
    #: random_state, n_rows; :func:`bootstrap_test_scores`); empty: none.
    bootstrap: dict[str, Any] = field(default_factory=dict)
    outputs: dict[str, str] = field(default_factory=dict)
    mlflow: dict[str, str] = field(default_factory=dict)
    wall_s: float = math.nan

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": self.name, "config": self.config, "family": self.family,
            "targets": self.targets, "n_train": self.n_train, "n_test": self.n_test,
            "prior": self.prior.to_json(), "model": self.model.to_json(), **self.details}
        for key in ("repeated_cv", "nested_cv_all", "sweep"):
            part = getattr(self, key)
            if part is not None:
                out.update(part.to_json() if key == "sweep" else {key: part.to_json()})
        if self.intervals:
            out["intervals"] = self.intervals
        if self.bootstrap:
            out["bootstrap"] = self.bootstrap
        if self.outputs:
            out["outputs"] = self.outputs
        if self.mlflow:
            out["mlflow"] = self.mlflow
        out["wall_s"] = self.wall_s
        return out
