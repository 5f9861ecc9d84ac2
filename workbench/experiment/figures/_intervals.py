"""Prediction intervals against measurements, a column of panels per target."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..scoring.units import unit_suffix, with_unit
from .style import INCUMBENT_COLOR, MODEL_COLOR, fit_text, new_figure, style_axes, with_setting

if TYPE_CHECKING:
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["interval_figure"]

#: Colour of the rows whose measured value lies outside their interval.
MISSED_COLOR = "#D55E00"


def _target_panels(top: Axes, bottom: Axes, target: str, rows: pd.DataFrame,
                   unit: str | None) -> None:
    """Draw one target's two panels of :func:`interval_figure`.

    Measured against predicted with each row's interval (``top``), and the same relative to
    the prediction (``bottom``).
    """
    pred = rows["predicted"].to_numpy(dtype=float)
    meas = rows["measured"].to_numpy(dtype=float)
    low, up = rows["lower"].to_numpy(dtype=float), rows["upper"].to_numpy(dtype=float)
    inside = (meas >= low) & (meas <= up)
    for ax, ref in ((top, np.zeros_like(pred)), (bottom, pred)):
        for mask, color, label in ((inside, MODEL_COLOR, "inside its interval"),
                                   (~inside, MISSED_COLOR, "outside")):
            if not mask.any():
                continue
            ax.errorbar(pred[mask], (low[mask] + up[mask]) / 2 - ref[mask],
                        yerr=(up[mask] - low[mask]) / 2, fmt="none", ecolor=color,
                        alpha=0.45, lw=1.2)
            ax.scatter(pred[mask], meas[mask] - ref[mask], s=10, color=color, zorder=3,
                       label=f"measured, {label}", edgecolors="none")
        style_axes(ax)
        ax.tick_params(labelsize=8)
        ax.set_xlabel(with_unit("predicted", unit), fontsize=9)
    span = np.array([min(pred.min(), meas.min()), max(pred.max(), meas.max())])
    top.plot(span, span, color=INCUMBENT_COLOR, lw=0.8, ls=":")
    bottom.axhline(0.0, color=INCUMBENT_COLOR, lw=0.8, ls=":")
    top.set_title(f"{target}: {inside.sum()}/{len(inside)} inside "
                  f"({inside.mean():.0%}),\nmean width {np.mean(up - low):.2f}"
                  f"{unit_suffix(unit)}", fontsize=10)
    top.set_ylabel(with_unit("measured", unit), fontsize=9)
    bottom.set_ylabel(with_unit("measured - predicted", unit), fontsize=9)


def interval_figure(table: pd.DataFrame, *, level: float, unit: str | None = None,
                    title: str | None = None, setting: str | None = None) -> Figure:
    """Draw prediction intervals against measurements, a column of panels per target.

    Top row: measured against predicted, each experiment's interval as a vertical bar at its
    prediction (the diagonal is measured = predicted); bottom row: the same relative to the
    prediction (measured - predicted), where the intervals' widths can be read. Experiments
    whose measured value lies outside their interval are drawn in another colour; each
    panel's title gives the coverage and mean width.

    Parameters
    ----------
    table : pandas.DataFrame
        One row per experiment and target with the columns ``target``, ``measured``,
        ``predicted``, ``lower``, ``upper`` (as
        :func:`workbench.experiment.runs.intervals.interval_table` writes).
    level : float
        The intervals' level, in (0, 1).
    unit : str, optional
        The targets' unit; ``None``: none shown.
    title : str, optional
        Default: the level.
    setting : str, optional
        A second title line naming the setting.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    Raises
    ------
    ValueError
        If ``table`` lacks rows or a column, or ``level`` is outside (0, 1).
    """
    need = {"target", "measured", "predicted", "lower", "upper"}
    missing = sorted(need - set(table.columns))
    if missing or table.empty:
        raise ValueError(f"table needs rows and the columns {sorted(need)}; missing {missing}"
                         if missing else "table has no rows")
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    targets = list(dict.fromkeys(str(t) for t in table["target"]))
    fig = new_figure(2.9 * len(targets) + 0.6, 6.4)
    axes = fig.subplots(2, len(targets), squeeze=False)
    for j, target in enumerate(targets):
        _target_panels(axes[0, j], axes[1, j], target,
                       table[table["target"].astype(str) == target], unit)
    handles: dict[str, Artist] = {}
    for ax in axes[1]:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, handle)
    fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncols=2,
               frameon=False, fontsize=8)
    fig.suptitle(with_setting(title or f"{level:.0%} prediction intervals", setting),
                 fontsize=12)
    return fit_text(fig)
