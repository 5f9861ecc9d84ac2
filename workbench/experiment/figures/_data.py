"""Figures of the data themselves.

The correlation of the training examples (Fig. 3), the bias voltages (Fig. S2) and the prior
beside the measured targets (Fig. S3).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..scoring.units import with_unit
from .style import (
    COUPLER_COLOR,
    MEASURED_COLOR,
    PRIOR_COLOR,
    QUBIT_COLOR,
    fit_text,
    new_figure,
    numeric_frame,
    style_axes,
    text_inches,
    with_setting,
    wrap,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["correlation_heatmap", "prior_target_boxplots", "voltage_boxplots"]

#: Most characters of a column's name on one line (longer names wrap).
NAME_CHARS = 16


def _name_inches(names: Sequence[str], least: float, fontsize: float = 10) -> float:
    """Measure one column's tick label: ``least``, or its longest line's (inches, wrapped)."""
    longest = max(len(line) for name in names for line in str(name).split("\n"))
    return max(least, text_inches(min(longest, NAME_CHARS), fontsize) + 0.2)


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


def _boxplot(ax: Axes, data: list[np.ndarray], positions: Sequence[float] | np.ndarray,
             color: str, *, width: float = 0.6) -> dict[str, Any]:
    """Draw filled boxplots (median black, outliers small open circles) at ``positions``."""
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

    Parameters
    ----------
    frame : pandas.DataFrame
        Numeric columns, one row per example.
    title : str, optional
        Default: the size of ``frame``.
    setting : str, optional
        A second title line naming the setting.

    Returns
    -------
    matplotlib.figure.Figure
        The heatmap.

    Raises
    ------
    TypeError
        If ``frame`` is not a DataFrame.
    ValueError
        If it is not numeric or has fewer than 2 columns or rows.
    """
    frame = numeric_frame("frame", frame)
    if frame.shape[1] < 2:
        raise ValueError(f"a correlation heatmap needs at least 2 columns; got "
                         f"{list(map(str, frame.columns))}")
    if len(frame) < 2:
        raise ValueError(f"a correlation needs at least 2 rows; got {len(frame)}")
    corr = frame.corr(method="pearson")
    names = [wrap(str(c), 2 * NAME_CHARS) for c in corr.columns]
    n = len(names)
    values = corr.to_numpy(dtype=float)

    import matplotlib  # deferred: as style.new_figure

    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="#d9d9d9")
    labels = max(0.0, _name_inches(names, 0.0) - 0.6) if max(map(len, names)) > 4 else 0.0
    side = max(4.0, 0.58 * n + 1.6) + labels  # the cells keep their size beside long names
    fig = new_figure(side + 1.1, side)
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
    ax.set_title(with_setting(title or default, setting), fontsize=12)
    return fit_text(fig)


def voltage_boxplots(voltages: pd.DataFrame, *, title: str | None = None,
                     unit: str = "a.u.") -> Figure:
    """Boxplots of the bias voltage features (Fig. S2): qubit and coupler biases side by side.

    Columns whose name starts with ``q`` (``qvolt5..qvolt9``) are qubit biases, those starting
    with ``c`` (``cvolt5..cvolt8``) coupler biases; each kind gets its own panel and y axis,
    as their ranges differ by an order of magnitude. The data only name these columns
    "voltages" and give no unit, hence the default ``unit="a.u."``. Boxes span the quartiles,
    whiskers 1.5 IQR; circles are the rows beyond. Missing values are left out.

    Parameters
    ----------
    voltages : pandas.DataFrame
        The voltage columns (names starting with ``q`` or ``c``), one row per example.
    title : str, optional
        Default: the number of rows.
    unit : str, default="a.u."
        The voltages' unit.

    Returns
    -------
    matplotlib.figure.Figure
        The boxplots.

    Raises
    ------
    TypeError
        If ``voltages`` is not a DataFrame.
    ValueError
        If it is empty, not numeric, has an all-missing column or a column that is neither a
        qubit's nor a coupler's.
    """
    voltages = numeric_frame("voltages", voltages)
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
    column = _name_inches(columns, 0.72)
    fig = new_figure(max(6.0, column * sum(widths) + 2.6), 4.4)
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
        style_axes(ax)
    fig.suptitle(title or f"Bias voltages, {len(voltages)} rows", fontsize=12)
    return fit_text(fig)


def _pair_label(j: int, prior_name: str, target_name: str) -> str:
    label = f"X{j} | Y{j}"
    if prior_name != target_name and (prior_name, target_name) != (f"X{j}", f"Y{j}"):
        names = f"{prior_name} | {target_name}"
        label += f"\n{names}" if len(names) <= NAME_CHARS else f"\n{prior_name} |\n{target_name}"
    return label


def prior_target_boxplots(prior: pd.DataFrame, targets: pd.DataFrame, *,
                          unit: str | None = None,
                          title: str | None = None,
                          labels: tuple[str, str] = ("prior (X)", "measured (Y)")
                          ) -> Figure:
    """Draw joint boxplots of prior and targets (Fig. S3).

    For each eigenenergy j, the prior's column j (Xj) and the targets' column j (Yj) side by
    side.

    The columns are paired by position; both frames hold the same examples (same number of
    rows). Values are plotted as given (about -6000 MHz on the benchmark), without an axis
    offset. Missing values are left out.

    Parameters
    ----------
    prior, targets : pandas.DataFrame
        One column per eigenenergy each, paired by position, on the same examples.
    unit : str, optional
        Their unit; ``None``: none shown.
    title : str, optional
        Default: the labels and the number of rows.
    labels : (str, str)
        Legend entries of the prior's and the targets' boxes (the prior's: the data set's
        name of its prior, :attr:`~workbench.datasets.Dataset.prior_label`, and ``(X)``).

    Returns
    -------
    matplotlib.figure.Figure
        The boxplots.

    Raises
    ------
    TypeError
        If either is not a DataFrame.
    ValueError
        If either is empty or not numeric, or they differ in columns or rows.
    """
    prior = numeric_frame("prior", prior)
    targets = numeric_frame("targets", targets)
    if prior.shape[1] != targets.shape[1]:
        raise ValueError(f"prior and targets must have one column per eigenenergy each: prior "
                         f"has {prior.shape[1]} columns, targets {targets.shape[1]}")
    if len(prior) != len(targets):
        raise ValueError(f"prior and targets must hold the same examples: prior has "
                         f"{len(prior)} rows, targets {len(targets)}")
    n = prior.shape[1]
    x = np.arange(1, n + 1, dtype=float)
    offset, width = 0.2, 0.36
    names = [_pair_label(j, str(p), str(t))
             for j, p, t in zip(range(1, n + 1), prior.columns, targets.columns, strict=True)]
    fig = new_figure(max(6.0, _name_inches(names, 1.15) * n + 2.2), 4.6)
    ax = fig.add_subplot()
    box_prior = _boxplot(ax, _column_data("prior", prior), x - offset, PRIOR_COLOR,
                         width=width)
    box_target = _boxplot(ax, _column_data("targets", targets), x + offset, MEASURED_COLOR,
                          width=width)
    ax.set_xticks(x, names, fontsize=10)
    ax.set_xlim(0.4, n + 0.6)
    ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    ax.set_xlabel("eigenenergy j (sorted, lowest first)", fontsize=11)
    ax.set_ylabel(with_unit("eigenenergy", unit), fontsize=11)
    ax.grid(True, axis="y", color="#e5e5e5", lw=0.6)
    ax.set_axisbelow(True)
    ax.legend([box_prior["boxes"][0], box_target["boxes"][0]], list(labels), loc="upper left",
              frameon=False, fontsize=10)
    default = f"{labels[0]} and {labels[1]} eigenenergies, {len(prior)} rows"
    ax.set_title(title or default, fontsize=12)
    style_axes(ax)
    return fit_text(fig)
