"""Figures of the base-boosting paper, as functions that return a matplotlib ``Figure``.

* :func:`mae_bars` -- per-target test error, control program vs learned model (Fig. 2, S4),
  with the errors' bootstrap intervals as error bars when given them.
* :func:`learning_curve_figure` -- the augmented learning curve (Fig. 4, S5).
* :func:`shap_summary` -- SHAP beeswarm summary of a model's predictions (Fig. 5, S8);
  :func:`shap_values` and :func:`shap_figure` are its two halves.
* :func:`correction_shap_figure` -- the SHAP summary of what a base-boosting model adds to its
  prior (model - prior), or a note that the model is the prior.
* :func:`correlation_heatmap` -- pairwise Pearson correlations of the training examples (Fig. 3).
* :func:`voltage_boxplots` -- boxplots of the qubit and coupler bias voltages (Fig. S2).
* :func:`prior_target_boxplots` -- paired boxplots of prior and target eigenenergies (Fig. S3).
* :func:`model_comparison_bars` -- per-target error bars of 2 to 6 systems (Fig. S6, S7), with
  intervals as error bars when given them.
* :func:`parameter_corrections` -- control-model vs corrected Hamiltonian parameters.
* :func:`selection_path_figure` -- CV error along a forward covariate selection.
* :func:`interval_figure` -- measured against predicted with each row's prediction interval.
* :func:`save_figure` -- write a figure to PNG and close it.

Figures are built on :class:`matplotlib.figure.Figure` directly, never through pyplot, so no
global figure state is created or leaked and no GUI backend is needed; nothing is shown.
The same data give the same figure. matplotlib is imported when the first figure is drawn:
the model families import this module, and a command that draws nothing (``evaluate
--no-track``) does not load it.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .._io import atomic_write
from ..curves import LearningCurve
from .explain import ShapValues, check_shap_frame, shap_values

if TYPE_CHECKING:
    from matplotlib.artist import Artist
    from matplotlib.figure import Figure

__all__ = ["correction_shap_figure", "correlation_heatmap", "interval_figure",
           "learning_curve_figure", "mae_bars", "model_comparison_bars", "parameter_corrections",
           "prior_target_boxplots", "save_figure", "selection_path_figure", "shap_figure",
           "shap_summary", "shap_values", "voltage_boxplots"]

#: Colours (Okabe-Ito, readable in grey scale and by colour-blind readers).
PRIOR_COLOR = "#7f7f7f"
MODEL_COLOR = "#0072B2"
TRAIN_COLOR = "#E69F00"
INCUMBENT_COLOR = "#000000"
MEASURED_COLOR = "#009E73"
QUBIT_COLOR = "#56B4E9"
COUPLER_COLOR = "#E69F00"
#: Colours of the systems of :func:`model_comparison_bars` not named after a known system.
OTHER_SYSTEM_COLORS = ("#D55E00", "#009E73", "#CC79A7", "#56B4E9")

_METRICS = {  # scorer name -> (axis label, is the unit squared)
    "neg_mean_absolute_error": ("MAE", False),
    "neg_median_absolute_error": ("median absolute error", False),
    "neg_root_mean_squared_error": ("RMSE", False),
    "neg_mean_squared_error": ("MSE", True),
    "neg_max_error": ("max error", False),
}


def _new_figure(width: float, height: float) -> Figure:
    from matplotlib.figure import Figure  # (b) matplotlib: not for evaluate --no-track

    fig = Figure(figsize=(width, height), layout="constrained")
    return fig


def _style(ax) -> None:
    ax.spines["top"].set_visible(False)
    ax.spines["right"].set_visible(False)
    ax.tick_params(labelsize=10)


def _with_setting(title: str, setting: str | None) -> str:
    return f"{title}\n{setting}" if setting else title


def _values(name: str, values, n: int) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have one value per target ({n}); got shape {arr.shape}")
    return arr


#: Error bars of the bar charts: thin, dark, capped.
ERROR_BAR_STYLE = {"ecolor": "#222222", "elinewidth": 0.8, "capsize": 3.0, "capthick": 0.8}


def _intervals(name: str, intervals, values: np.ndarray, n_targets: int,
               average: bool) -> np.ndarray:
    """Bounds ``[low, high]`` per bar (one per target, then the average's when ``average``)
    as matplotlib's ``yerr`` (shape ``(2, n_bars)``: the distances below and above each bar's
    value; an interval that misses its bar's value, which a percentile bootstrap interval of
    a skewed statistic may, is drawn from the value on)."""
    arr = np.asarray(intervals, dtype=float)
    n_bars = n_targets + 1 if average else n_targets
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] not in (n_bars, n_targets + 1):
        expected = (f"{n_targets} targets' and the average's" if average
                    else f"{n_targets} targets'")
        raise ValueError(f"{name} must hold the {expected} [low, high] (shape ({n_bars}, 2)); "
                         f"got shape {arr.shape}")
    arr = arr[:n_bars]  # without the average bar, its interval (last row) is not drawn
    if not np.isfinite(arr).all() or (arr[:, 0] > arr[:, 1]).any():
        raise ValueError(f"{name} must be finite with low <= high; got {arr.tolist()}")
    return np.clip(np.stack([values - arr[:, 0], arr[:, 1] - values]), 0.0, None)


def _grouped_bars(ax, names: list[str], series: Sequence[tuple[str, np.ndarray, str]], *,
                  average: bool, fmt: str = "%.2f", fontsize: float = 8,
                  errors: Sequence[np.ndarray | None] | None = None) -> list:
    """Draw one bar per (label, values, colour) series in each group of ``names``, annotated.

    The series of a group share a total width of 0.76, side by side in the given order; with
    ``average`` the last group is set apart by a dotted line. ``errors``: per series ``None``
    or its error bars (``yerr``, shape ``(2, n_bars)``); a bar's value is written above its
    error bar. Returns the bar containers.
    """
    x = np.arange(len(names), dtype=float)
    n = len(series)
    width = 0.76 / n
    errors = list(errors) if errors is not None else [None] * n
    containers = [ax.bar(x + (i - (n - 1) / 2) * width, values, width, label=label, color=color,
                         **({} if yerr is None else {"yerr": yerr,
                                                     "error_kw": ERROR_BAR_STYLE}))
                  for i, ((label, values, color), yerr) in enumerate(zip(series, errors,
                                                                         strict=True))]
    for bars in containers:
        ax.bar_label(bars, fmt=fmt, padding=2, fontsize=fontsize)
    if average:
        ax.axvline(len(names) - 1.5, color="#bbbbbb", lw=1, ls=":")
    ax.set_xticks(x, names, fontsize=10)
    ax.set_xlabel("target", fontsize=11)
    return containers


def mae_bars(targets: Sequence[str], prior, model, *, metric: str = "MAE", unit: str = "MHz",
             title: str | None = None, labels: tuple[str, str] = ("control program",
                                                                  "base boosting"),
             setting: str | None = None, average: bool = True, prior_ci=None, model_ci=None,
             ci_note: str | None = "error bars: 95% bootstrap intervals over the test rows"
             ) -> Figure:
    """Grouped bars of a per-target error for the prior and the model, plus their averages,
    with error bars when given the errors' intervals.

    Parameters
    ----------
    targets : sequence of str
        Target names, one bar group each.
    prior, model : sequence of float
        The error of the control program (prior) and of the learned model per target.
    metric, unit : str
        Axis label ``"<metric> (<unit>)"``; give ``unit="MHz²"`` for an MSE.
    title : str, optional
        Default: ``"Test <metric> per target: <labels[0]> vs <labels[1]>"``.
    labels : (str, str)
        Legend entries of the prior's and the model's bars.
    setting : str, optional
        A second title line naming the setting (e.g. the config).
    average : bool, default=True
        Append an "average" group (the mean over targets), set apart by a dotted line.
    prior_ci, model_ci : array-like of shape (n_targets + 1, 2), optional
        Intervals drawn as error bars: ``[low, high]`` per target, then the average's (an
        interval of the average over targets is not the average of the targets' intervals:
        give the one computed with them, e.g. :meth:`Scores.ci
        <workbench.experiment.results.Scores.ci>` ``("test_mae")``); without ``average``,
        ``(n_targets, 2)`` is enough. Either may be given alone.
    ci_note : str or None
        With error bars, a note under the axis saying what they are (``None``: none); the
        default describes :func:`~workbench.experiment.bootstrap.bootstrap_test_scores`'
        intervals, give another for other intervals.
    """
    names = [str(t) for t in targets]
    if not names:
        raise ValueError("targets is empty")
    n_targets = len(names)
    prior = _values("prior", prior, n_targets)
    model = _values("model", model, n_targets)
    if average:
        names = [*names, "average"]
        prior = np.append(prior, prior.mean())
        model = np.append(model, model.mean())
    errors = [None if ci is None else _intervals(name, ci, values, n_targets, average)
              for name, ci, values in (("prior_ci", prior_ci, prior),
                                       ("model_ci", model_ci, model))]

    fig = _new_figure(max(5.0, 0.95 * len(names) + 1.8), 4.0)
    ax = fig.add_subplot()
    _grouped_bars(ax, names, [(labels[0], prior, PRIOR_COLOR), (labels[1], model, MODEL_COLOR)],
                  average=average, errors=errors)
    ax.set_ylabel(f"{metric} ({unit})", fontsize=11)
    tops = [values + (0 if err is None else err[1])
            for values, err in zip((prior, model), errors)]
    top = np.nanmax(np.concatenate(tops)) if np.any(np.isfinite(prior)) else 1.0
    ax.set_ylim(0, top * 1.22 if np.isfinite(top) and top > 0 else 1.0)
    ax.legend(loc="upper right", frameon=False, fontsize=10, ncols=2)
    ax.set_title(_with_setting(title or f"Test {metric} per target: {labels[0]} vs {labels[1]}",
                               setting), fontsize=12)
    if ci_note and any(err is not None for err in errors):
        _note_under_xlabel(ax, ci_note)
    _style(ax)
    return fig


def _note_under_xlabel(ax, note: str) -> None:
    """A small grey line of text centred under the x-axis label (a caption's note)."""
    ax.annotate(note, xy=(0.5, 0.0), xycoords=ax.xaxis.label, xytext=(0, -3),
                textcoords="offset points", ha="center", va="top", fontsize=8,
                color="#555555")


def learning_curve_figure(curve: LearningCurve, *, target: str, unit: str = "MHz",
                          title: str | None = None, setting: str | None = None) -> Figure:
    """The augmented learning curve: training, CV (+-1 sd over folds) and incumbent error.

    The x-axis is the mean number of rows actually used to fit (``curve.n_train_rows``), not
    the requested size. Sizes where a fold failed have no point (NaN).
    """
    metric, squared = _METRICS.get(curve.scoring, (curve.scoring, False))
    unit_label = f"{unit}²" if squared else unit
    x = curve.mean_train_rows
    fig = _new_figure(6.0, 4.2)
    ax = fig.add_subplot()
    cv_mean, cv_sd = curve.cv_error_mean, curve.cv_error_std
    ax.fill_between(x, cv_mean - cv_sd, cv_mean + cv_sd, color=MODEL_COLOR, alpha=0.18, lw=0,
                    label="CV error ±1 sd over folds")
    ax.plot(x, curve.train_error_mean, "o--", color=TRAIN_COLOR, ms=5, lw=1.5,
            label="training error")
    ax.plot(x, cv_mean, "o-", color=MODEL_COLOR, ms=5, lw=2, label="CV error")
    ax.plot(x, curve.incumbent_error_mean, "s:", color=INCUMBENT_COLOR, ms=4, lw=1.5,
            label="incumbent (prior) CV error")
    ax.set_xlabel(f"training rows used (mean over {curve.n_folds} folds)", fontsize=11)
    ax.set_ylabel(f"{metric} ({unit_label})", fontsize=11)
    ax.set_ylim(bottom=0)
    ax.margins(x=0.04)
    ax.grid(True, color="#e5e5e5", lw=0.6)
    ax.set_axisbelow(True)
    ax.legend(loc="best", frameon=False, fontsize=9)
    n_val = int(np.round(curve.n_validation_rows.mean()))
    default = (f"Augmented learning curve: {target}\n{curve.n_folds}-fold CV, "
               f"~{n_val} validation rows per fold")
    ax.set_title(_with_setting(title or default, setting), fontsize=12)
    _style(ax)
    return fig


def shap_summary(predict: Callable[[np.ndarray], np.ndarray], X: pd.DataFrame, *, target: str,
                 unit: str = "MHz", background_size: int = 50, nsamples: int | str = "auto",
                 max_display: int = 10, random_state: int = 0, title: str | None = None,
                 setting: str | None = None) -> tuple[Figure, np.ndarray]:
    """SHAP values of ``predict`` on the rows of ``X`` and their beeswarm summary.

    ``predict`` receives plain 2-D float arrays (the columns of ``X``, in order). The
    background is ``background_size`` rows of ``X`` sampled with ``random_state``. With
    ``nsamples="auto"`` and up to ten features the values are exact: every coalition is
    enumerated (:func:`workbench.experiment.explain.exact_shap_values`, the values
    ``shap.KernelExplainer`` estimates at its default ``nsamples``) with the model called on
    all rows' coalitions at once. Otherwise ``shap.KernelExplainer`` with ``nsamples``
    (``predict`` wrapped in a lambda, never passed as a bound method: see the SHAP notes in
    the docs).

    Returns the figure and the SHAP values, an array of shape ``(n_rows, n_features)`` in
    the prediction's unit.
    """
    values, expected = shap_values(predict, X, background_size=background_size,
                                   nsamples=nsamples, random_state=random_state)
    fig = shap_figure(values, expected, X, target=target, unit=unit, max_display=max_display,
                      random_state=random_state, title=title, setting=setting)
    return fig, values


#: What a SHAP summary explains (``explained=``): the words of its axis label and title.
EXPLAINED = {"prediction": "the whole prediction", "correction": "the correction (model − prior)"}


def shap_figure(values: np.ndarray, expected: float, X: pd.DataFrame, *, target: str,
                unit: str = "MHz", max_display: int = 10, random_state: int = 0,
                title: str | None = None, setting: str | None = None,
                explained: str | None = None) -> Figure:
    """The beeswarm summary of SHAP ``values`` (shape ``(n_rows, n_features)``) of the rows of
    ``X`` (see :func:`shap_summary`). ``explained``: ``"prediction"`` (a base-boosting
    model's whole prediction) or ``"correction"`` (what it adds to its prior, model - prior),
    named in the axis label and the default title; ``None``: "predicted <target>", a model
    without a prior."""
    import shap  # (b) SHAP: not for evaluate --no-track

    if explained is not None and explained not in EXPLAINED:
        raise ValueError(f"explained must be one of {sorted(EXPLAINED)} or None; got "
                         f"{explained!r}")

    check_shap_frame(X)
    names = [str(c) for c in X.columns]
    data = X.to_numpy(dtype=float)
    values = np.asarray(values, dtype=float)
    if values.shape != data.shape:
        raise ValueError(f"values must have the shape of X {data.shape}; got {values.shape}")
    explanation = shap.Explanation(values=values, base_values=np.full(len(data), expected),
                                   data=data, feature_names=names)
    n_shown = min(len(names), max_display)
    fig = _new_figure(7.0, 0.42 * n_shown + 1.9)
    ax = fig.add_subplot()
    # shap's beeswarm jitters with numpy's global generator: seed it, then restore it.
    state = np.random.get_state()
    try:
        np.random.seed(random_state)
        shap.plots.beeswarm(explanation, max_display=max_display, ax=ax, show=False,
                            plot_size=None, s=18)
    finally:
        np.random.set_state(state)
    size = f"{len(data)} rows x {len(names)} features"
    if explained is None:
        ax.set_xlabel(f"SHAP value: effect on predicted {target} ({unit})", fontsize=11)
        default = f"SHAP summary: {target}, {size}"
    else:
        ax.set_xlabel(f"SHAP value: effect on {EXPLAINED[explained]} of {target} ({unit})",
                      fontsize=11)
        default = f"SHAP summary of {EXPLAINED[explained]}: {target}\n{size}"
    ax.tick_params("y", labelsize=10)
    ax.set_title(_with_setting(title or default, setting), fontsize=12)
    return fig


def correction_shap_figure(shap: ShapValues | None, *, target: str, unit: str = "MHz",
                           note: str = "", max_display: int = 10, random_state: int = 0,
                           title: str | None = None, setting: str | None = None) -> Figure:
    """The SHAP summary of a per-target model's correction (model - prior), ``shap`` from
    :func:`~workbench.experiment.explain.target_shap_values` (its ``correction``). ``None``:
    the model is the prior (its correction is 0 on every row), and the figure says so, with
    ``note`` (why: :func:`~workbench.experiment.explain.prior_reason`), instead of a beeswarm
    of zeros."""
    if shap is not None:
        return shap_figure(shap.values, shap.expected, shap.rows, target=target, unit=unit,
                           max_display=max_display, random_state=random_state, title=title,
                           setting=setting, explained="correction")
    fig = _new_figure(7.0, 2.2)
    ax = fig.add_subplot()
    ax.set_axis_off()
    why = f" ({note})" if note else ""
    ax.text(0.5, 0.5, f"The model of {target} is its prior{why}:\nthe correction "
                      f"(model − prior) is 0 {unit} on every row; nothing to explain.",
            ha="center", va="center", fontsize=11, transform=ax.transAxes, wrap=True)
    default = f"SHAP summary of {EXPLAINED['correction']}: {target}"
    ax.set_title(_with_setting(title or default, setting), fontsize=12)
    return fig


def _numeric_frame(name: str, frame) -> pd.DataFrame:
    """``frame`` as a float DataFrame; a clear error for anything else, empty or non-numeric."""
    if not isinstance(frame, pd.DataFrame):
        raise TypeError(f"{name} must be a pandas DataFrame (its columns name the series); got "
                        f"{type(frame).__name__}")
    if frame.shape[0] == 0 or frame.shape[1] == 0:
        raise ValueError(f"{name} is empty: shape {frame.shape}")
    bad = [str(c) for c in frame.columns if not pd.api.types.is_numeric_dtype(frame[c])
           or pd.api.types.is_bool_dtype(frame[c])]
    if bad:
        raise ValueError(f"{name} has non-numeric columns: {bad}")
    return frame.astype(float)


def _column_data(name: str, frame: pd.DataFrame) -> list[np.ndarray]:
    """Each column's finite values (NaN rows dropped); an error naming an all-missing column."""
    data = []
    for column in frame.columns:
        values = frame[column].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if values.size == 0:
            raise ValueError(f"{name} column {str(column)!r} has no finite values")
        data.append(values)
    return data


def _boxplot(ax, data: list[np.ndarray], positions, color: str, *, width: float = 0.6) -> dict:
    """Filled boxplots (median line black, outliers as small open circles) at ``positions``."""
    return ax.boxplot(data, positions=positions, widths=width, patch_artist=True,
                      manage_ticks=False,
                      boxprops={"facecolor": color, "edgecolor": "#333333", "linewidth": 1},
                      medianprops={"color": "#000000", "linewidth": 1.5},
                      whiskerprops={"color": "#333333"}, capprops={"color": "#333333"},
                      flierprops={"marker": "o", "markersize": 3.5, "markerfacecolor": "none",
                                  "markeredgecolor": "#333333", "alpha": 0.8})


def correlation_heatmap(frame: pd.DataFrame, *, title: str | None = None,
                        setting: str | None = None) -> Figure:
    """Heatmap of the pairwise Pearson correlations of the columns of ``frame`` (Fig. 3).

    For the paper's figure, pass the training examples' prior columns and targets renamed
    ``X1..X5`` and ``Y1..Y5``. Every cell is annotated with its correlation (2 decimals); the
    diverging colour map is fixed to [-1, 1] so that colours compare across figures. A
    constant column has no correlation: its cells are grey and read "n/a".
    """
    frame = _numeric_frame("frame", frame)
    if frame.shape[1] < 2:
        raise ValueError(f"a correlation heatmap needs at least 2 columns; got "
                         f"{list(map(str, frame.columns))}")
    if len(frame) < 2:
        raise ValueError(f"a correlation needs at least 2 rows; got {len(frame)}")
    corr = frame.corr(method="pearson")
    names = [str(c) for c in corr.columns]
    n = len(names)
    values = corr.to_numpy(dtype=float)

    import matplotlib  # (b) matplotlib: not for evaluate --no-track

    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="#d9d9d9")
    side = max(4.0, 0.58 * n + 1.6)
    fig = _new_figure(side + 1.1, side)
    ax = fig.add_subplot()
    image = ax.imshow(np.ma.masked_invalid(values), cmap=cmap, vmin=-1.0, vmax=1.0,
                      interpolation="nearest")
    fontsize = 9 if n <= 10 else 7 if n <= 16 else 5
    for i in range(n):
        for j in range(n):
            v = values[i, j]
            text = "n/a" if not np.isfinite(v) else f"{v:.2f}".replace("-0.00", "0.00")
            ax.text(j, i, text, ha="center",
                    va="center", fontsize=fontsize,
                    color="#ffffff" if np.isfinite(v) and abs(v) > 0.6 else "#000000")
    ax.set_xticks(np.arange(n), names, fontsize=10, rotation=90 if max(map(len, names)) > 4
                  else 0)
    ax.set_yticks(np.arange(n), names, fontsize=10)
    ax.tick_params(length=0)
    for spine in ax.spines.values():
        spine.set_visible(False)
    bar = fig.colorbar(image, ax=ax, shrink=0.85, ticks=[-1, -0.5, 0, 0.5, 1])
    bar.set_label("Pearson correlation", fontsize=11)
    bar.ax.tick_params(labelsize=9)
    default = f"Pairwise Pearson correlation, {len(frame)} rows x {n} columns"
    ax.set_title(_with_setting(title or default, setting), fontsize=12)
    return fig


def voltage_boxplots(voltages: pd.DataFrame, *, title: str | None = None,
                     unit: str = "a.u.") -> Figure:
    """Boxplots of the bias voltage features (Fig. S2): qubit and coupler biases side by side.

    Columns whose name starts with ``q`` (``qvolt5..qvolt9``) are qubit biases, those starting
    with ``c`` (``cvolt5..cvolt8``) coupler biases; each kind gets its own panel and y axis,
    as their ranges differ by an order of magnitude. The data only name these columns
    "voltages" and give no unit, hence the default ``unit="a.u."``. Boxes span the quartiles,
    whiskers 1.5 IQR; circles are the rows beyond. Missing values are left out.
    """
    voltages = _numeric_frame("voltages", voltages)
    columns = [str(c) for c in voltages.columns]
    qubits = [c for c in voltages.columns if str(c).lower().startswith("q")]
    couplers = [c for c in voltages.columns if str(c).lower().startswith("c")]
    other = [str(c) for c in voltages.columns if c not in qubits and c not in couplers]
    if other:
        raise ValueError(f"cannot tell qubit from coupler voltages: the columns {other} start "
                         f"with neither 'q' (qubit) nor 'c' (coupler); got {columns}")
    panels = [(kind, cols, color) for kind, cols, color in
              (("qubit", qubits, QUBIT_COLOR), ("coupler", couplers, COUPLER_COLOR)) if cols]

    widths = [len(cols) for _, cols, _ in panels]
    fig = _new_figure(max(6.0, 0.72 * sum(widths) + 2.6), 4.4)
    axes = fig.subplots(1, len(panels), width_ratios=widths, squeeze=False)[0]
    for ax, (kind, cols, color) in zip(axes, panels, strict=True):
        data = _column_data("voltages", voltages[cols])
        x = np.arange(len(cols), dtype=float)
        _boxplot(ax, data, x, color)
        ax.axhline(0.0, color="#bbbbbb", lw=0.8, ls=":", zorder=0)
        ax.set_xticks(x, [str(c) for c in cols], fontsize=10)
        ax.set_xlim(-0.6, len(cols) - 0.4)
        ax.set_title(f"{kind} biases ({len(cols)})", fontsize=11)
        ax.set_xlabel(f"{kind} bias feature", fontsize=11)
        ax.set_ylabel(f"bias voltage ({unit})", fontsize=11)
        ax.grid(True, axis="y", color="#e5e5e5", lw=0.6)
        ax.set_axisbelow(True)
        _style(ax)
    fig.suptitle(title or f"Bias voltages, {len(voltages)} rows", fontsize=12)
    return fig


def _pair_label(j: int, prior_name: str, target_name: str) -> str:
    label = f"X{j} | Y{j}"
    if prior_name != target_name and (prior_name, target_name) != (f"X{j}", f"Y{j}"):
        label += f"\n{prior_name} | {target_name}"
    return label


def prior_target_boxplots(prior: pd.DataFrame, targets: pd.DataFrame, *, unit: str = "MHz",
                          title: str | None = None,
                          labels: tuple[str, str] = ("control program (X)", "measured (Y)")
                          ) -> Figure:
    """Joint boxplots of prior and targets (Fig. S3): for each eigenenergy j, the prior's
    column j (Xj) and the targets' column j (Yj) side by side.

    The columns are paired by position; both frames hold the same examples (same number of
    rows). Values are plotted as given (about -6000 MHz on the benchmark), without an axis
    offset. Missing values are left out.
    """
    prior = _numeric_frame("prior", prior)
    targets = _numeric_frame("targets", targets)
    if prior.shape[1] != targets.shape[1]:
        raise ValueError(f"prior and targets must have one column per eigenenergy each: prior "
                         f"has {prior.shape[1]} columns, targets {targets.shape[1]}")
    if len(prior) != len(targets):
        raise ValueError(f"prior and targets must hold the same examples: prior has "
                         f"{len(prior)} rows, targets {len(targets)}")
    n = prior.shape[1]
    x = np.arange(1, n + 1, dtype=float)
    offset, width = 0.2, 0.36
    fig = _new_figure(max(6.0, 1.15 * n + 2.2), 4.6)
    ax = fig.add_subplot()
    box_prior = _boxplot(ax, _column_data("prior", prior), x - offset, PRIOR_COLOR,
                         width=width)
    box_target = _boxplot(ax, _column_data("targets", targets), x + offset, MEASURED_COLOR,
                          width=width)
    names = [_pair_label(j, str(p), str(t))
             for j, p, t in zip(range(1, n + 1), prior.columns, targets.columns, strict=True)]
    ax.set_xticks(x, names, fontsize=10)
    ax.set_xlim(0.4, n + 0.6)
    ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    ax.set_xlabel("eigenenergy j (sorted, lowest first)", fontsize=11)
    ax.set_ylabel(f"eigenenergy ({unit})", fontsize=11)
    ax.grid(True, axis="y", color="#e5e5e5", lw=0.6)
    ax.set_axisbelow(True)
    ax.legend([box_prior["boxes"][0], box_target["boxes"][0]], list(labels), loc="upper left",
              frameon=False, fontsize=10)
    default = f"{labels[0]} and {labels[1]} eigenenergies, {len(prior)} rows"
    ax.set_title(title or default, fontsize=12)
    _style(ax)
    return fig


def _system_colors(systems: list[str]) -> list[str]:
    """The control program grey and base boosting blue (as in :func:`mae_bars`), other
    systems the next unused colour of :data:`OTHER_SYSTEM_COLORS`, in order."""
    colors, used, others = [], set(), iter(OTHER_SYSTEM_COLORS)
    for system in systems:
        name = system.lower()
        color = (PRIOR_COLOR if "control program" in name else
                 MODEL_COLOR if "base boost" in name else None)
        if color is None or color in used:
            color = next((c for c in others if c not in used), None)
            if color is None:
                raise ValueError(f"more than {len(OTHER_SYSTEM_COLORS)} systems other than "
                                 f"the control program and base boosting: {systems}")
        used.add(color)
        colors.append(color)
    return colors


def model_comparison_bars(targets: Sequence[str], values: Mapping[str, Sequence[float]], *,
                          metric: str = "MAE", unit: str = "MHz", title: str | None = None,
                          setting: str | None = None, log: bool = False,
                          average: bool = True,
                          intervals: Mapping[str, Sequence[Sequence[float]]] | None = None,
                          ci_note: str | None = ("error bars: 95% bootstrap intervals over "
                                                 "the test rows")) -> Figure:
    """Grouped bars of a per-target error for 2 to 6 systems (at most 4 besides the control
    program and base boosting), plus their averages (Fig. S6, S7), with error bars for the
    systems given intervals.

    Parameters
    ----------
    targets : sequence of str
        Target names, one bar group each.
    values : mapping of str to sequence of float
        System name (legend entry) -> its error per target, in the order of the bars. A system
        named "control program ..." is grey and "base boosting ..." blue, as in
        :func:`mae_bars`.
    metric, unit : str
        Axis label ``"<metric> (<unit>)"``; give ``unit="MHz²"`` for an MSE.
    title : str, optional
        Default: ``"Test <metric> per target: <system 1> vs <system 2> ..."``.
    setting : str, optional
        A second title line naming the setting.
    log : bool, default=False
        Logarithmic y axis, for systems an order of magnitude apart (needs positive values).
    average : bool, default=True
        Append an "average" group (the mean over targets), set apart by a dotted line.
    intervals : mapping of str to array-like of shape (n_targets + 1, 2), optional
        System name -> ``[low, high]`` per target, then the average's (as ``model_ci`` of
        :func:`mae_bars`), drawn as error bars; systems not in it have none.
    ci_note : str or None
        With error bars, a note under the axis saying what they are (``None``: none; the
        default as in :func:`mae_bars`).
    """
    names = [str(t) for t in targets]
    if not names:
        raise ValueError("targets is empty")
    n_targets = len(names)
    if not isinstance(values, Mapping):
        raise TypeError(f"values must map each system's name to its values; got "
                        f"{type(values).__name__}")
    systems = [str(s) for s in values]
    most = len(OTHER_SYSTEM_COLORS) + 2  # the control program and base boosting: their own
    if not 2 <= len(systems) <= most:
        raise ValueError(f"model_comparison_bars compares 2 to {most} systems; got "
                         f"{len(systems)}: {systems}")
    colors = _system_colors(systems)
    arrays = []
    for system, v in zip(systems, values.values(), strict=True):
        arr = _values(f"values[{system!r}]", v, len(names))
        if not np.isfinite(arr).all():
            raise ValueError(f"values[{system!r}] has non-finite values: {arr.tolist()}")
        if log and (arr <= 0).any():
            raise ValueError(f"log=True needs positive values; values[{system!r}] has "
                             f"{arr.tolist()}")
        arrays.append(np.append(arr, arr.mean()) if average else arr)
    if average:
        names = [*names, "average"]
    intervals = dict(intervals or {})
    unknown = sorted(set(map(str, intervals)) - set(systems))
    if unknown:
        raise ValueError(f"intervals of unknown systems {unknown}; the systems are {systems}")
    errors = [None if intervals.get(system) is None
              else _intervals(f"intervals[{system!r}]", intervals[system], arr, n_targets,
                              average)
              for system, arr in zip(systems, arrays)]

    n = len(systems)
    fig = _new_figure(max(5.0, (0.42 * n + 0.15) * len(names) + 1.8), 4.4)
    ax = fig.add_subplot()
    every = np.concatenate(arrays)
    biggest = np.abs(every).max()
    fmt = "%.2f" if biggest < 100 else "%.1f" if biggest < 1000 else "%.0f"
    _grouped_bars(ax, names, list(zip(systems, arrays, colors, strict=True)),
                  average=average, fmt=fmt, fontsize=8 if n <= 3 else 7, errors=errors)
    # the axis holds the error bars' ends too
    ends = [every] + [bounds for arr, err in zip(arrays, errors) if err is not None
                      for bounds in (arr - err[0], arr + err[1])]
    every = np.concatenate(ends)
    if log:
        every = every[every > 0]
    ax.set_ylabel(f"{metric} ({unit}, log scale)" if log else f"{metric} ({unit})", fontsize=11)
    if log:
        from matplotlib.ticker import FuncFormatter  # (b) matplotlib: not for evaluate --no-track

        ax.set_yscale("log")
        ax.set_ylim(every.min() / 2.0, every.max() * 2.5)
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    else:
        top, bottom = max(every.max(), 0.0), min(every.min(), 0.0)
        span = top - bottom if top > bottom else 1.0
        ax.set_ylim(bottom - (0.12 * span if bottom < 0 else 0), top + 0.12 * span)
        if bottom < 0:
            ax.axhline(0.0, color="#333333", lw=0.8)
    handles, legend_labels = ax.get_legend_handles_labels()
    ncols = n if sum(map(len, systems)) <= 100 else 2
    if ncols == 2 and n == 4:  # legends fill column by column: keep the bars' order in rows
        handles, legend_labels = ([seq[i] for i in (0, 2, 1, 3)]
                                  for seq in (handles, legend_labels))
    fig.legend(handles, legend_labels, loc="outside lower center", ncols=ncols, frameon=False,
               fontsize=10)
    default = f"Test {metric} per target: " + " vs ".join(systems)
    ax.set_title(_with_setting(title or default, setting), fontsize=12)
    if ci_note and any(err is not None for err in errors):
        _note_under_xlabel(ax, ci_note)
    _style(ax)
    return fig


def parameter_corrections(control: pd.DataFrame, corrected: pd.DataFrame, *,
                          groups: Mapping[str, Iterable] | None = None, unit: str = "MHz",
                          title: str | None = None, setting: str | None = None) -> Figure:
    """One panel per Hamiltonian parameter: its correction (corrected - control) against the
    control model's value, one point per experiment.

    ``control`` and ``corrected`` share columns (parameters) and rows (experiments).
    ``groups`` optionally maps a legend label to row labels (e.g. ``{"training": idx,
    "test": idx}``); rows in no group are drawn as "other".
    """
    control, corrected = _numeric_frame("control", control), _numeric_frame("corrected",
                                                                            corrected)
    if list(control.columns) != list(corrected.columns) or not control.index.equals(
            corrected.index):
        raise ValueError("control and corrected must have the same columns and rows; got "
                         f"{list(control.columns)} and {list(corrected.columns)}")
    delta = corrected - control
    names = [str(c) for c in control.columns]
    ncols = min(5, len(names))
    nrows = -(-len(names) // ncols)
    fig = _new_figure(2.6 * ncols + 0.6, 2.4 * nrows + 0.9)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    members = {label: control.index.isin(list(rows)) for label, rows in (groups or {}).items()}
    rest = ~np.any(list(members.values()), axis=0) if members else np.ones(len(control), bool)
    if rest.any():
        members["other" if members else "experiments"] = rest
    colors = dict(zip(members, (MODEL_COLOR, TRAIN_COLOR, *OTHER_SYSTEM_COLORS)))
    for ax, name in zip(axes.ravel(), names):
        for label, mask in members.items():
            ax.scatter(control.loc[mask, name], delta.loc[mask, name], s=12, alpha=0.75,
                       color=colors[label], label=label, edgecolors="none")
        ax.axhline(0.0, color=INCUMBENT_COLOR, lw=0.8, ls=":")
        d = delta[name]
        ax.set_title(f"{name}: {d.mean():+.2f} ± {d.std():.2f} {unit}", fontsize=10)
        ax.set_xlabel(f"control {name} ({unit})", fontsize=9)
        ax.set_ylabel(f"correction ({unit})", fontsize=9)
        _style(ax)
        ax.tick_params(labelsize=8)
    for ax in axes.ravel()[len(names):]:
        ax.set_visible(False)
    axes.ravel()[0].legend(frameon=False, fontsize=8)
    fig.suptitle(_with_setting(title or "Hamiltonian parameters: correction vs control model "
                               "(mean ± sd)", setting), fontsize=12)
    return fig


def selection_path_figure(path: pd.DataFrame, *, unit: str = "MHz", title: str | None = None,
                          setting: str | None = None) -> Figure:
    """CV MAE after each step of a forward covariate selection (``path``: the columns step,
    parameter, covariate, cv_mae of :class:`workbench.param_select.SelectionResult`)."""
    missing = {"step", "parameter", "covariate", "cv_mae"} - set(path.columns)
    if missing or path.empty:
        raise ValueError(f"path needs rows and the columns step, parameter, covariate, cv_mae; "
                         f"missing {sorted(missing)}" if missing else "path has no rows")
    labels = ["start" if i == 0 else f"{p} ← {c}" for i, (p, c) in
              enumerate(zip(path["parameter"], path["covariate"]))]
    fig = _new_figure(max(5.0, 0.42 * len(labels) + 2.0), 4.2)
    ax = fig.add_subplot()
    ax.plot(np.arange(len(labels)), path["cv_mae"].to_numpy(dtype=float), marker="o",
            color=MODEL_COLOR)
    ax.set_xticks(np.arange(len(labels)), labels, rotation=60, ha="right", fontsize=8)
    ax.set_xlabel("covariate added (parameter ← covariate)", fontsize=10)
    ax.set_ylabel(f"CV MAE ({unit})", fontsize=11)
    ax.set_title(_with_setting(title or "Forward covariate selection", setting), fontsize=12)
    _style(ax)
    return fig


#: Colour of the rows whose measured value lies outside their interval.
MISSED_COLOR = "#D55E00"


def interval_figure(table: pd.DataFrame, *, level: float, unit: str = "MHz",
                    title: str | None = None, setting: str | None = None) -> Figure:
    """Prediction intervals against measurements, a column of panels per target.

    ``table``: one row per experiment and target with the columns ``target``, ``measured``,
    ``predicted``, ``lower``, ``upper`` (as
    :func:`workbench.experiment.intervals.interval_table` writes). Top row: measured against
    predicted, each experiment's interval as a vertical bar at its prediction (the diagonal is
    measured = predicted); bottom row: the same relative to the prediction (measured -
    predicted), where the intervals' widths can be read. Experiments whose measured value
    lies outside their interval are drawn in another colour; each panel's title gives the
    coverage and mean width.
    """
    need = {"target", "measured", "predicted", "lower", "upper"}
    missing = sorted(need - set(table.columns))
    if missing or table.empty:
        raise ValueError(f"table needs rows and the columns {sorted(need)}; missing {missing}"
                         if missing else "table has no rows")
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    targets = list(dict.fromkeys(str(t) for t in table["target"]))
    fig = _new_figure(2.9 * len(targets) + 0.6, 6.4)
    axes = fig.subplots(2, len(targets), squeeze=False)
    for j, target in enumerate(targets):
        rows = table[table["target"].astype(str) == target]
        pred = rows["predicted"].to_numpy(dtype=float)
        meas = rows["measured"].to_numpy(dtype=float)
        low, up = rows["lower"].to_numpy(dtype=float), rows["upper"].to_numpy(dtype=float)
        inside = (meas >= low) & (meas <= up)
        for ax, ref in ((axes[0, j], np.zeros_like(pred)), (axes[1, j], pred)):
            for mask, color, label in ((inside, MODEL_COLOR, "inside its interval"),
                                       (~inside, MISSED_COLOR, "outside")):
                if not mask.any():
                    continue
                ax.errorbar(pred[mask], (low[mask] + up[mask]) / 2 - ref[mask],
                            yerr=(up[mask] - low[mask]) / 2, fmt="none", ecolor=color,
                            alpha=0.45, lw=1.2)
                ax.scatter(pred[mask], meas[mask] - ref[mask], s=10, color=color, zorder=3,
                           label=f"measured, {label}", edgecolors="none")
            _style(ax)
            ax.tick_params(labelsize=8)
            ax.set_xlabel(f"predicted ({unit})", fontsize=9)
        span = np.array([min(pred.min(), meas.min()), max(pred.max(), meas.max())])
        axes[0, j].plot(span, span, color=INCUMBENT_COLOR, lw=0.8, ls=":")
        axes[1, j].axhline(0.0, color=INCUMBENT_COLOR, lw=0.8, ls=":")
        axes[0, j].set_title(f"{target}: {inside.sum()}/{len(inside)} inside "
                             f"({inside.mean():.0%}),\nmean width {np.mean(up - low):.2f} "
                             f"{unit}", fontsize=10)
        axes[0, j].set_ylabel(f"measured ({unit})", fontsize=9)
        axes[1, j].set_ylabel(f"measured - predicted ({unit})", fontsize=9)
    handles: dict[str, Artist] = {}
    for ax in axes[1]:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, handle)
    fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncols=2,
               frameon=False, fontsize=8)
    fig.suptitle(_with_setting(title or f"{level:.0%} prediction intervals", setting),
                 fontsize=12)
    return fig


def save_figure(fig: Figure, path: str | Path, *, dpi: int = 120) -> Path:
    """Write ``fig`` as a PNG (creating parent directories), close it, return the path.

    A path without a suffix gets ``.png``; any other suffix than ``.png`` is an error.
    """
    path = Path(path)
    if path.suffix == "":
        path = path.with_suffix(".png")
    if path.suffix.lower() != ".png":
        raise ValueError(f"save_figure writes PNG files; got the suffix {path.suffix!r} in {path}")
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=dpi, format="png")
    atomic_write(path, buffer.getvalue())
    if getattr(fig.canvas, "manager", None) is not None:  # a pyplot figure: drop its reference
        import matplotlib.pyplot as plt  # (b) matplotlib: not for evaluate --no-track

        plt.close(fig)
    return path
