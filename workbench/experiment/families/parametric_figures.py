"""Family ``parametric``'s figure of the drift: corrected parameters against covariates.

(The corrections against the start values and the selection path are the Hamiltonian
family's figures, :mod:`.hamiltonian_figures`.)
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..._covariates import variable
from ..figures.style import (
    INCUMBENT_COLOR,
    MODEL_COLOR,
    OTHER_SYSTEM_COLORS,
    TRAIN_COLOR,
    fit_text,
    new_figure,
    style_axes,
    with_setting,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["covariate_axis", "drift_axes", "parameter_drift_figure"]


def covariate_axis(name: str, X: pd.DataFrame) -> tuple[str, np.ndarray] | None:
    """Return the variable a covariate is a power of, and its values on ``X``'s rows.

    ``"day^2"`` -> ``("day", X["day"])``; ``"a*b"``, ``"a-b"``, ``"sqrt|a*b|"`` (and their
    powers) -> the product, the difference, the geometric mean. ``None`` for a name that is
    none of these (:func:`workbench._covariates.variable` reads the names).
    """
    base, sep, power = name.rpartition("^")
    axis = base if sep and power.isdigit() else name
    columns = {str(c): c for c in X.columns}
    var = variable(axis, set(columns))
    if var is None:
        return None
    if len(var) == 1:
        return axis, X[columns[axis]].to_numpy(dtype=float)
    op, x, y = var[0], *(X[columns[c]].to_numpy(dtype=float) for c in var[1:])
    return axis, {"*": x * y, "-": x - y, "gm": np.sqrt(np.abs(x * y))}[op]


def drift_axes(coefficients: pd.DataFrame, X: pd.DataFrame) -> dict[str, tuple[str, np.ndarray]]:
    """Choose each drifting parameter's axis: the variable of its largest coefficient.

    Parameters
    ----------
    coefficients : DataFrame
        The columns parameter, covariate, coef (the coefficients in the parameter's unit
        per covariate sd: comparable within a parameter).
    X : DataFrame
        The rows.

    Returns
    -------
    dict
        Parameter -> (variable, its values); parameters with only an intercept are left out.
    """
    out: dict[str, tuple[str, np.ndarray]] = {}
    drifts = coefficients[coefficients["covariate"] != "intercept"]
    for p, rows in drifts.groupby("parameter", sort=False):
        for name in rows.loc[rows["coef"].abs().sort_values(ascending=False).index, "covariate"]:
            axis = covariate_axis(str(name), X)
            if axis is not None:
                out[str(p)] = axis
                break
    return out


def parameter_drift_figure(corrected: pd.DataFrame, axes_by: Mapping[str, tuple[str, np.ndarray]],
                           *, calibrated: Mapping[str, float] | None = None,
                           groups: Mapping[str, Iterable[object]] | None = None,
                           title: str | None = None, setting: str | None = None) -> Figure:
    """Draw each drifting parameter's corrected value against its covariate.

    One panel per parameter of ``axes_by``: the corrected parameter of each row against the
    variable its drift depends on most (:func:`drift_axes`), the calibrated value (no
    drift) as a dotted line where given.

    Parameters
    ----------
    corrected : DataFrame
        The corrected parameters, one column per parameter, one row per experiment.
    axes_by : mapping
        Parameter -> (variable name, its values on ``corrected``'s rows).
    calibrated : mapping of str to float, optional
        Each parameter's calibrated (global) value.
    groups : mapping of str to row labels, optional
        A legend label -> its rows (e.g. training and test rows).
    title : str, optional
        Default: "Corrected parameters against the covariates they drift with".
    setting : str, optional
        A second title line naming the setting.

    Returns
    -------
    matplotlib.figure.Figure
        The panels.

    Raises
    ------
    ValueError
        For no parameter to draw, or one ``corrected`` lacks.
    """
    names = list(axes_by)
    missing = [p for p in names if p not in corrected.columns]
    if not names or missing:
        raise ValueError(f"no parameter to draw, or parameters missing from corrected: "
                         f"{missing}")
    ncols = min(4, len(names))
    nrows = -(-len(names) // ncols)
    fig = new_figure(2.8 * ncols + 0.6, 2.5 * nrows + 0.9)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    members = {label: corrected.index.isin(list(rows)) for label, rows in (groups or {}).items()}
    rest = (~np.any(list(members.values()), axis=0) if members
            else np.ones(len(corrected), bool))
    if rest.any():
        members["other" if members else "experiments"] = rest
    colors = dict(zip(members, (MODEL_COLOR, TRAIN_COLOR, *OTHER_SYSTEM_COLORS)))
    for ax, p in zip(axes.ravel(), names):
        variable, x = axes_by[p]
        for label, mask in members.items():
            ax.scatter(x[mask], corrected.loc[mask, p], s=12, alpha=0.75, color=colors[label],
                       label=label, edgecolors="none")
        if calibrated is not None and p in calibrated:
            ax.axhline(calibrated[p], color=INCUMBENT_COLOR, lw=0.8, ls=":",
                       label="calibrated")
        ax.set_title(p, fontsize=10)
        ax.set_xlabel(variable, fontsize=9)
        ax.set_ylabel(f"corrected {p}", fontsize=9)
        style_axes(ax)
        ax.tick_params(labelsize=8)
    for ax in axes.ravel()[len(names):]:
        ax.set_visible(False)
    axes.ravel()[0].legend(frameon=False, fontsize=8)
    fig.suptitle(with_setting(title or "Corrected parameters against the covariates they "
                              "drift with", setting), fontsize=12)
    return fit_text(fig)
