"""Bar charts of per-target errors, with the errors' intervals as error bars.

The prior against the model (Fig. 2, S4), and 2 to 6 systems side by side (Fig. S6, S7).
Figures grow with the number of targets and the length of their names, which wrap to the
space of their bars (:func:`~.style.fit_text`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..scoring.units import squared, with_unit
from .style import (
    MODEL_COLOR,
    OTHER_SYSTEM_COLORS,
    PRIOR_COLOR,
    fit_text,
    new_figure,
    style_axes,
    text_inches,
    with_setting,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.container import BarContainer
    from matplotlib.figure import Figure

    from ..scoring.results import Result

__all__ = ["error_bars", "mae_bars", "model_comparison_bars"]

#: Error bars of the bar charts: thin, dark, capped.
ERROR_BAR_STYLE = {"ecolor": "#222222", "elinewidth": 0.8, "capsize": 3.0, "capthick": 0.8}
#: The note under a chart with error bars, by default.
CI_NOTE = "error bars: 95% bootstrap intervals over the test rows"
#: Most characters of a target's name on one line under its bars (longer names wrap).
NAME_CHARS = 16
#: The widest bar chart, in inches (beyond it, the targets' names wrap to narrower groups).
MAX_WIDTH = 16.0


def _names(targets: Sequence[str]) -> list[str]:
    """Return the targets' names, or raise a ValueError when there are none."""
    names = [str(t) for t in targets]
    if not names:
        raise ValueError("targets is empty")
    return names


def _width(names: list[str], group: float) -> float:
    """Measure a bar chart: groups of at least ``group`` inches, wider for long names."""
    longest = max(len(line) for name in names for line in name.split("\n"))
    group = max(group, text_inches(min(longest, NAME_CHARS), 10) + 0.2)
    return min(MAX_WIDTH, max(5.0, group * len(names) + 1.8))


def _legend(fig: Figure, ax: Axes, labels: list[str], *, inside: Any = None) -> None:
    """Draw the legend of the bars in rows under the axes, as many columns as fit the width.

    With ``inside`` (a location such as ``"upper right"``), in the axes on one row instead,
    where that row takes less than 60% of the axes' width (estimated); legends fill column by
    column, so with two columns the entries are reordered to keep the bars' order in rows.
    """
    handles, texts = ax.get_legend_handles_labels()
    entry = [text_inches(len(t), 10) + 0.6 for t in labels]  # the patch and the gap too
    if inside is not None and sum(entry) <= 0.6 * (fig.get_figwidth() - 1.0):
        ax.legend(loc=inside, frameon=False, fontsize=10, ncols=len(labels))
        return
    ncols = len(labels)
    while ncols > 1 and sum(sorted(entry)[-ncols:]) > fig.get_figwidth() - 0.3:
        ncols -= 1
    if ncols == 2 and len(labels) in (3, 4):  # keep the bars' order in rows
        order = (0, 2, 1, 3)[:len(labels)] if len(labels) == 4 else (0, 2, 1)
        handles, texts = [handles[i] for i in order], [texts[i] for i in order]
    fig.legend(handles, texts, loc="outside lower center", ncols=ncols, frameon=False,
               fontsize=10)


def _values(name: str, values: Any, n: int) -> np.ndarray:
    """``values`` as a float array of one value per target (``n``), or a ValueError."""
    arr = np.asarray(values, dtype=float)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have one value per target ({n}); got shape {arr.shape}")
    return arr


def _intervals(name: str, intervals: Any, values: np.ndarray, n_targets: int,
               average: bool) -> np.ndarray:
    """Turn bounds ``[low, high]`` per bar into matplotlib's ``yerr``.

    One bound per target, then the average's when ``average``; ``yerr`` has shape
    ``(2, n_bars)``: the distances below and above each bar's value. An interval that misses
    its bar's value, which a percentile bootstrap interval of a skewed statistic may, is drawn
    from the value on.
    """
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


def _grouped_bars(ax: Axes, names: list[str], series: Sequence[tuple[str, np.ndarray, str]], *,
                  average: bool, fmt: str = "%.2f", fontsize: float = 8,
                  errors: Sequence[np.ndarray | None] | None = None) -> list[BarContainer]:
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
    containers = []
    for i, ((label, values, color), yerr) in enumerate(zip(series, errors, strict=True)):
        error_bars: dict[str, Any] = ({} if yerr is None
                                      else {"yerr": yerr, "error_kw": ERROR_BAR_STYLE})
        containers.append(ax.bar(x + (i - (n - 1) / 2) * width, values, width, label=label,
                                 color=color, **error_bars))
    for bars in containers:
        ax.bar_label(bars, fmt=fmt, padding=2, fontsize=fontsize)
    if average:
        ax.axvline(len(names) - 1.5, color="#bbbbbb", lw=1, ls=":")
    ax.set_xticks(x, names, fontsize=10)
    ax.set_xlabel("target", fontsize=11)
    return containers


def _note_under_xlabel(ax: Axes, note: str) -> None:
    """Write a small grey line of text centred under the x-axis label (a caption's note)."""
    ax.annotate(note, xy=(0.5, 0.0), xycoords=ax.xaxis.label, xytext=(0, -3),
                textcoords="offset points", ha="center", va="top", fontsize=8,
                color="#555555")


def mae_bars(targets: Sequence[str], prior: Sequence[float], model: Sequence[float], *,
             metric: str = "MAE", unit: str | None = None, title: str | None = None,
             labels: tuple[str, str] = ("prior", "base boosting"),
             setting: str | None = None, average: bool = True, prior_ci: Any = None,
             model_ci: Any = None, ci_note: str | None = CI_NOTE) -> Figure:
    """Draw a per-target error of the prior and the model as grouped bars.

    The bars of each target, plus their averages, with error bars when given the errors'
    intervals.

    Parameters
    ----------
    targets : sequence of str
        Target names, one bar group each.
    prior, model : sequence of float
        The error of the prior and of the learned model per target.
    metric : str, default="MAE"
        The error's name on the axis.
    unit : str, optional
        The error's unit: axis label ``"<metric> (<unit>)"``; give the squared unit
        (:func:`~workbench.experiment.scoring.units.squared`) for an MSE. ``None``: no unit shown.
    title : str, optional
        Default: ``"Test <metric> per target: <labels[0]> vs <labels[1]>"``.
    labels : (str, str)
        Legend entries of the prior's and the model's bars (the data set's name of its prior:
        :attr:`~workbench.datasets.Dataset.prior_label`).
    setting : str, optional
        A second title line naming the setting (e.g. the config).
    average : bool, default=True
        Append an "average" group (the mean over targets), set apart by a dotted line.
    prior_ci, model_ci : array-like of shape (n_targets + 1, 2), optional
        Intervals drawn as error bars: ``[low, high]`` per target, then the average's (an
        interval of the average over targets is not the average of the targets' intervals:
        give the one computed with them, e.g. :meth:`Scores.ci
        <workbench.experiment.scoring.scores.Scores.ci>` ``("test_mae")``); without ``average``,
        ``(n_targets, 2)`` is enough. Either may be given alone.
    ci_note : str or None
        With error bars, a note under the axis saying what they are (``None``: none); the
        default describes :func:`~workbench.experiment.scoring.bootstrap.bootstrap_test_scores`'
        intervals, give another for other intervals.

    Returns
    -------
    matplotlib.figure.Figure
        The chart.

    Raises
    ------
    ValueError
        If ``targets`` is empty, or the errors or intervals do not match the targets.
    """
    names = _names(targets)
    n_targets = len(names)
    prior_v = _values("prior", prior, n_targets)
    model_v = _values("model", model, n_targets)
    if average:
        names = [*names, "average"]
        prior_v = np.append(prior_v, prior_v.mean())
        model_v = np.append(model_v, model_v.mean())
    errors = [None if ci is None else _intervals(name, ci, values, n_targets, average)
              for name, ci, values in (("prior_ci", prior_ci, prior_v),
                                       ("model_ci", model_ci, model_v))]

    fig = new_figure(_width(names, 0.95), 4.0)
    ax = fig.add_subplot()
    _grouped_bars(ax, names, [(labels[0], prior_v, PRIOR_COLOR),
                              (labels[1], model_v, MODEL_COLOR)], average=average, errors=errors)
    ax.set_ylabel(with_unit(metric, unit), fontsize=11)
    tops = [values + (0 if err is None else err[1])
            for values, err in zip((prior_v, model_v), errors)]
    top = np.nanmax(np.concatenate(tops)) if np.any(np.isfinite(prior_v)) else 1.0
    ax.set_ylim(0, top * 1.22 if np.isfinite(top) and top > 0 else 1.0)
    _legend(fig, ax, list(labels), inside="upper right")
    ax.set_title(with_setting(title or f"Test {metric} per target: {labels[0]} vs {labels[1]}",
                              setting), fontsize=12)
    if ci_note and any(err is not None for err in errors):
        _note_under_xlabel(ax, ci_note)
    style_axes(ax)
    return fit_text(fig)



def error_bars(result: Result, metric: str = "MAE", *, unit: str | None = None,
               targets: Sequence[str] | None = None, **kwargs: Any) -> Figure:
    """Draw a result's test MAE (or MSE) per target, prior against model, with their intervals.

    :func:`mae_bars` of the result's ``test_mae`` (``test_mse``) and their bootstrap
    intervals (:meth:`~workbench.experiment.scoring.scores.Scores.ci`).

    Parameters
    ----------
    result : Result
        An ``evaluate`` result.
    metric : {"MAE", "MSE"}, default="MAE"
        The error drawn.
    unit : str, optional
        The targets' unit (a dataset's :attr:`~workbench.datasets.Dataset.unit`); an MSE is
        labelled with its square.
    targets : sequence of str, optional
        The bar groups' labels (default: the result's targets).
    **kwargs
        Passed to :func:`mae_bars` (``title``, ``labels``, ``setting``, ...).

    Returns
    -------
    matplotlib.figure.Figure
        The chart.
    """
    key = f"test_{metric.lower()}"
    return mae_bars(result.targets if targets is None else targets,
                    getattr(result.prior, key), getattr(result.model, key), metric=metric,
                    unit=unit if metric == "MAE" else squared(unit),
                    prior_ci=result.prior.ci(key), model_ci=result.model.ci(key), **kwargs)


def _system_colors(systems: list[str]) -> list[str]:
    """Colour each system: the prior grey, base boosting blue, the rest in turn.

    As in :func:`mae_bars`: a system named "prior ..." or "control program ..." is grey;
    other systems get the next unused colour of :data:`OTHER_SYSTEM_COLORS`, in order.
    """
    colors: list[str] = []
    used: set[str] = set()
    others = iter(OTHER_SYSTEM_COLORS)
    for system in systems:
        name = system.lower()
        prior = "control program" in name or name == "prior" or name.startswith("prior ")
        color = (PRIOR_COLOR if prior else
                 MODEL_COLOR if "base boost" in name else None)
        if color is None or color in used:
            color = next((c for c in others if c not in used), None)
            if color is None:
                raise ValueError(f"more than {len(OTHER_SYSTEM_COLORS)} systems other than "
                                 f"the prior and base boosting: {systems}")
        used.add(color)
        colors.append(color)
    return colors


def _comparison_values(values: Any, n_targets: int, log: bool,
                       average: bool) -> tuple[list[str], list[np.ndarray]]:
    """Check and return the systems' names and values of :func:`model_comparison_bars`.

    The values per target, with their average appended when ``average``.
    """
    if not isinstance(values, Mapping):
        raise TypeError(f"values must map each system's name to its values; got "
                        f"{type(values).__name__}")
    systems = [str(s) for s in values]
    most = len(OTHER_SYSTEM_COLORS) + 2  # the prior and base boosting: their own
    if not 2 <= len(systems) <= most:
        raise ValueError(f"model_comparison_bars compares 2 to {most} systems; got "
                         f"{len(systems)}: {systems}")
    arrays = []
    for system, v in zip(systems, values.values(), strict=True):
        arr = _values(f"values[{system!r}]", v, n_targets)
        if not np.isfinite(arr).all():
            raise ValueError(f"values[{system!r}] has non-finite values: {arr.tolist()}")
        if log and (arr <= 0).any():
            raise ValueError(f"log=True needs positive values; values[{system!r}] has "
                             f"{arr.tolist()}")
        arrays.append(np.append(arr, arr.mean()) if average else arr)
    return systems, arrays


def _comparison_errors(intervals: Mapping[str, Any] | None, systems: list[str],
                       arrays: list[np.ndarray], n_targets: int, average: bool
                       ) -> list[np.ndarray | None]:
    """Check the intervals of :func:`model_comparison_bars` and turn them into error bars.

    One entry per system: its ``yerr``, or ``None`` for a system without intervals.
    """
    bounds = dict(intervals or {})
    unknown = sorted(set(map(str, bounds)) - set(systems))
    if unknown:
        raise ValueError(f"intervals of unknown systems {unknown}; the systems are {systems}")
    return [None if bounds.get(system) is None
            else _intervals(f"intervals[{system!r}]", bounds[system], arr, n_targets, average)
            for system, arr in zip(systems, arrays)]


def _value_axis(ax: Axes, every: np.ndarray, *, metric: str, unit: str | None,
                log: bool) -> None:
    """Label and scale the y axis of :func:`model_comparison_bars`.

    Its range holds every value and error bar end (``every``); logarithmic with ``log``.
    """
    ax.set_ylabel(with_unit(metric, f"{unit}, log scale" if unit else "log scale") if log
                  else with_unit(metric, unit), fontsize=11)
    if log:
        from matplotlib.ticker import FuncFormatter  # deferred: as style.new_figure

        every = every[every > 0]
        ax.set_yscale("log")
        ax.set_ylim(every.min() / 2.0, every.max() * 2.5)
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    else:
        top, bottom = max(every.max(), 0.0), min(every.min(), 0.0)
        span = top - bottom if top > bottom else 1.0
        ax.set_ylim(bottom - (0.12 * span if bottom < 0 else 0), top + 0.12 * span)
        if bottom < 0:
            ax.axhline(0.0, color="#333333", lw=0.8)


def model_comparison_bars(targets: Sequence[str], values: Mapping[str, Sequence[float]], *,
                          metric: str = "MAE", unit: str | None = None,
                          title: str | None = None, setting: str | None = None,
                          log: bool = False, average: bool = True,
                          intervals: Mapping[str, Any] | None = None,
                          ci_note: str | None = CI_NOTE) -> Figure:
    """Draw a per-target error of 2 to 6 systems as grouped bars (Fig. S6, S7).

    At most 4 systems besides the prior and base boosting; their averages are
    appended, with error bars for the systems given intervals.

    Parameters
    ----------
    targets : sequence of str
        Target names, one bar group each.
    values : mapping of str to sequence of float
        System name (legend entry) -> its error per target, in the order of the bars. A system
        named "prior ..." or "control program ..." is grey and "base boosting ..." blue, as in
        :func:`mae_bars`.
    metric : str, default="MAE"
        The error's name on the axis.
    unit : str, optional
        The error's unit, as in :func:`mae_bars` (``None``: no unit shown).
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

    Returns
    -------
    matplotlib.figure.Figure
        The chart.

    Raises
    ------
    TypeError
        If ``values`` is not a mapping.
    ValueError
        If ``targets`` is empty, the number of systems is outside 2 to 6, a system's values
        do not match the targets or are not finite (positive with ``log``), or an interval
        names an unknown system or does not match the targets.
    """
    names = _names(targets)
    n_targets = len(names)
    systems, arrays = _comparison_values(values, n_targets, log, average)
    colors = _system_colors(systems)
    if average:
        names = [*names, "average"]
    errors = _comparison_errors(intervals, systems, arrays, n_targets, average)
    n = len(systems)
    fig = new_figure(_width(names, 0.42 * n + 0.15), 4.4)
    ax = fig.add_subplot()
    every = np.concatenate(arrays)
    biggest = np.abs(every).max()
    fmt = "%.2f" if biggest < 100 else "%.1f" if biggest < 1000 else "%.0f"
    _grouped_bars(ax, names, list(zip(systems, arrays, colors, strict=True)),
                  average=average, fmt=fmt, fontsize=8 if n <= 3 else 7, errors=errors)
    # the axis holds the error bars' ends too
    ends = [every] + [edge for arr, err in zip(arrays, errors) if err is not None
                      for edge in (arr - err[0], arr + err[1])]
    _value_axis(ax, np.concatenate(ends), metric=metric, unit=unit, log=log)
    _legend(fig, ax, systems)
    default = f"Test {metric} per target: " + " vs ".join(systems)
    ax.set_title(with_setting(title or default, setting), fontsize=12)
    if ci_note and any(err is not None for err in errors):
        _note_under_xlabel(ax, ci_note)
    style_axes(ax)
    return fit_text(fig)
