"""The augmented learning curve (Fig. 4, S5).

Training, CV and incumbent error against the number of training rows used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ...curves import LearningCurve
from ..scoring.units import squared, with_unit
from .style import (
    INCUMBENT_COLOR,
    MODEL_COLOR,
    TRAIN_COLOR,
    fit_text,
    new_figure,
    style_axes,
    with_setting,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["learning_curve_figure"]

_METRICS = {  # scorer name -> (axis label, is the unit squared)
    "neg_mean_absolute_error": ("MAE", False),
    "neg_median_absolute_error": ("median absolute error", False),
    "neg_root_mean_squared_error": ("RMSE", False),
    "neg_mean_squared_error": ("MSE", True),
    "neg_max_error": ("max error", False),
}


def learning_curve_figure(curve: LearningCurve, *, target: str, unit: str | None = None,
                          title: str | None = None, setting: str | None = None) -> Figure:
    """Draw the augmented learning curve: training, CV (+-1 sd over folds), incumbent error.

    The x-axis is the mean number of rows actually used to fit (``curve.n_train_rows``), not
    the requested size. Sizes where a fold failed have no point (NaN).

    Parameters
    ----------
    curve : LearningCurve
        The curve (:func:`workbench.curves.learning_curve`); its scoring names the error.
    target : str
        The target's name, in the default title.
    unit : str, optional
        The target's unit (squared on the axis for a squared error); ``None``: none shown.
    title : str, optional
        Default: the target, the folds and the validation rows per fold.
    setting : str, optional
        A second title line naming the setting.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    metric, is_squared = _METRICS.get(curve.scoring, (curve.scoring, False))
    x = curve.mean_train_rows
    fig = new_figure(6.0, 4.2)
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
    ax.set_ylabel(with_unit(metric, squared(unit) if is_squared else unit), fontsize=11)
    ax.set_ylim(bottom=0)
    ax.margins(x=0.04)
    ax.grid(True, color="#e5e5e5", lw=0.6)
    ax.set_axisbelow(True)
    ax.legend(loc="best", frameon=False, fontsize=9)
    n_val = int(np.round(curve.n_validation_rows.mean()))
    default = (f"Augmented learning curve: {target}\n{curve.n_folds}-fold CV, "
               f"~{n_val} validation rows per fold")
    ax.set_title(with_setting(title or default, setting), fontsize=12)
    style_axes(ax)
    return fit_text(fig)
