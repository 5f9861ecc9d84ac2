"""The parameter-space model's figures (family ``hamiltonian``).

The corrections of the Hamiltonian parameters against their control values, and the CV error
along the forward covariate selection.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..figures.style import (
    INCUMBENT_COLOR,
    MODEL_COLOR,
    OTHER_SYSTEM_COLORS,
    TRAIN_COLOR,
    fit_text,
    new_figure,
    numeric_frame,
    style_axes,
    text_inches,
    with_setting,
    wrap,
)
from ..scoring.units import unit_suffix, with_unit

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["parameter_corrections", "selection_path_figure"]


def parameter_corrections(control: pd.DataFrame, corrected: pd.DataFrame, *,
                          groups: Mapping[str, Iterable[object]] | None = None,
                          unit: str | None = None, title: str | None = None,
                          setting: str | None = None, reference: str = "control") -> Figure:
    """Draw each Hamiltonian parameter's correction against its control value.

    One panel per parameter: its correction (corrected - control) against the control model's
    value, one point per experiment.

    Parameters
    ----------
    control, corrected : pandas.DataFrame
        The control model's and the corrected parameters: the same columns (parameters) and
        rows (experiments).
    groups : mapping of str to row labels, optional
        A legend label -> its rows (e.g. ``{"training": idx, "test": idx}``); rows in no
        group are drawn as "other".
    unit : str, optional
        The parameters' unit (the targets'); ``None``: none shown.
    title : str, optional
        Default: "Hamiltonian parameters: correction vs control model (mean ± sd)".
    setting : str, optional
        A second title line naming the setting.
    reference : str, default="control"
        What the x axes call the parameters' uncorrected values (e.g. "start").

    Returns
    -------
    matplotlib.figure.Figure
        The panels.

    Raises
    ------
    TypeError
        If either is not a DataFrame.
    ValueError
        If either is empty or not numeric, or they differ in columns or rows.
    """
    control, corrected = numeric_frame("control", control), numeric_frame("corrected",
                                                                           corrected)
    if list(control.columns) != list(corrected.columns) or not control.index.equals(
            corrected.index):
        raise ValueError("control and corrected must have the same columns and rows; got "
                         f"{list(control.columns)} and {list(corrected.columns)}")
    delta = corrected - control
    names = [str(c) for c in control.columns]
    ncols = min(5, len(names))
    nrows = -(-len(names) // ncols)
    fig = new_figure(2.6 * ncols + 0.6, 2.4 * nrows + 0.9)
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
        ax.set_title(f"{name}: {d.mean():+.2f} ± {d.std():.2f}{unit_suffix(unit)}",
                     fontsize=10)
        ax.set_xlabel(with_unit(f"{reference} {name}", unit), fontsize=9)
        ax.set_ylabel(with_unit("correction", unit), fontsize=9)
        style_axes(ax)
        ax.tick_params(labelsize=8)
    for ax in axes.ravel()[len(names):]:
        ax.set_visible(False)
    axes.ravel()[0].legend(frameon=False, fontsize=8)
    fig.suptitle(with_setting(title or "Hamiltonian parameters: correction vs control model "
                              "(mean ± sd)", setting), fontsize=12)
    return fit_text(fig)


def selection_path_figure(path: pd.DataFrame, *, unit: str | None = None,
                          title: str | None = None, setting: str | None = None) -> Figure:
    """Draw the CV MAE after each step of a forward covariate selection.

    Parameters
    ----------
    path : pandas.DataFrame
        The columns step, parameter, covariate, cv_mae of
        :class:`workbench.param_select.SelectionResult`'s ``path``.
    unit : str, optional
        The targets' unit; ``None``: none shown.
    title : str, optional
        Default: "Forward covariate selection".
    setting : str, optional
        A second title line naming the setting.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    Raises
    ------
    ValueError
        If ``path`` has no rows or lacks a column.
    """
    missing = {"step", "parameter", "covariate", "cv_mae"} - set(path.columns)
    if missing or path.empty:
        raise ValueError(f"path needs rows and the columns step, parameter, covariate, cv_mae; "
                         f"missing {sorted(missing)}" if missing else "path has no rows")
    labels = ["start" if i == 0 else wrap(f"{p} ← {c}", 36) for i, (p, c) in
              enumerate(zip(path["parameter"], path["covariate"]))]
    lines = [label.split("\n") for label in labels]
    longest = max(len(line) for label in lines for line in label)
    # the labels hang at 60 degrees under the axis: the figure grows to hold them, and a
    # label of several lines needs the room of as many
    fig = new_figure(max(5.0, 0.42 * max(map(len, lines)) * len(labels) + 2.0),
                     4.2 + max(0.0, 0.87 * text_inches(longest, 8) - 1.0))
    ax = fig.add_subplot()
    ax.plot(np.arange(len(labels)), path["cv_mae"].to_numpy(dtype=float), marker="o",
            color=MODEL_COLOR)
    ax.set_xticks(np.arange(len(labels)), labels, rotation=60, ha="right", fontsize=8)
    ax.set_xlabel("covariate added (parameter ← covariate)", fontsize=10)
    ax.set_ylabel(with_unit("CV MAE", unit), fontsize=11)
    ax.set_title(with_setting(title or "Forward covariate selection", setting), fontsize=12)
    style_axes(ax)
    return fit_text(fig)
