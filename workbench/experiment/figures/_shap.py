"""SHAP beeswarm summaries (Fig. 5, S8).

Of a model's whole prediction, or of what a base-boosting model adds to its prior (the
correction).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..scoring.explain import ShapValues, check_shap_frame, shap_values
from ..scoring.units import unit_suffix, with_unit
from .style import fit_text, new_figure, text_inches, with_setting

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["EXPLAINED", "correction_shap_figure", "shap_figure", "shap_summary"]

#: What a SHAP summary explains (``explained=``): the words of its axis label and title.
EXPLAINED = {"prediction": "the whole prediction", "correction": "the correction (model − prior)"}


def shap_summary(predict: Callable[[np.ndarray], np.ndarray], X: pd.DataFrame, *, target: str,
                 unit: str | None = None, background_size: int = 50,
                 nsamples: int | str = "auto", max_display: int = 10, random_state: int = 0,
                 title: str | None = None, setting: str | None = None
                 ) -> tuple[Figure, np.ndarray]:
    """Compute the SHAP values of ``predict`` on the rows of ``X`` and draw their summary.

    ``predict`` receives plain 2-D float arrays (the columns of ``X``, in order). The
    background is ``background_size`` rows of ``X`` sampled with ``random_state``. With
    ``nsamples="auto"`` and up to ten features the values are exact: every coalition is
    enumerated (:func:`workbench.experiment.scoring.explain.exact_shap_values`, the values
    ``shap.KernelExplainer`` estimates at its default ``nsamples``) with the model called on
    all rows' coalitions at once. Otherwise ``shap.KernelExplainer`` with ``nsamples``
    (``predict`` wrapped in a lambda, never passed as a bound method: see the SHAP notes in
    the docs).

    Parameters
    ----------
    predict : callable
        The model's prediction of one target, on a 2-D float array.
    X : pandas.DataFrame
        The rows explained (and the background's source).
    target : str
        The target's name, on the axis and in the default title.
    unit : str, optional
        The prediction's unit; ``None``: none shown.
    background_size : int, default=50
        Rows of the background.
    nsamples : int or "auto", default="auto"
        As ``shap.KernelExplainer``'s.
    max_display : int, default=10
        Features shown.
    random_state : int, default=0
        Seeds the background and the beeswarm's jitter.
    title, setting : str, optional
        As :func:`shap_figure`'s.

    Returns
    -------
    figure : matplotlib.figure.Figure
        The summary.
    values : numpy.ndarray of shape (n_rows, n_features)
        The SHAP values, in the prediction's unit.
    """
    values, expected = shap_values(predict, X, background_size=background_size,
                                   nsamples=nsamples, random_state=random_state)
    fig = shap_figure(values, expected, X, target=target, unit=unit, max_display=max_display,
                      random_state=random_state, title=title, setting=setting)
    return fig, values


def shap_figure(values: np.ndarray, expected: float, X: pd.DataFrame, *, target: str,
                unit: str | None = None, max_display: int = 10, random_state: int = 0,
                title: str | None = None, setting: str | None = None,
                explained: str | None = None) -> Figure:
    """Draw the beeswarm summary of SHAP ``values`` of the rows of ``X``.

    See :func:`shap_summary`.

    Parameters
    ----------
    values : numpy.ndarray of shape (n_rows, n_features)
        The SHAP values.
    expected : float
        The expected value (the explanation's base value).
    X : pandas.DataFrame
        The rows explained, numeric.
    target : str
        The target's name.
    unit : str, optional
        The prediction's unit; ``None``: none shown.
    max_display : int, default=10
        Features shown.
    random_state : int, default=0
        Seeds the beeswarm's jitter (numpy's global generator, restored afterwards).
    title : str, optional
        Default: what is explained, the target and the size.
    setting : str, optional
        A second title line naming the setting.
    explained : {"prediction", "correction"} or None
        ``"prediction"`` (a base-boosting model's whole prediction) or ``"correction"``
        (what it adds to its prior, model - prior), named in the axis label and the default
        title; ``None``: "predicted <target>", a model without a prior.

    Returns
    -------
    matplotlib.figure.Figure
        The summary.

    Raises
    ------
    ValueError
        If ``explained`` is unknown, ``X`` is not numeric, or ``values`` does not have its
        shape.
    """
    import shap  # deferred: a command that draws nothing skips SHAP

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
    fig = new_figure(max(7.0, 5.8 + text_inches(max(map(len, names)), 10)), 0.42 * n_shown + 1.9)
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
        ax.set_xlabel(with_unit(f"SHAP value: effect on predicted {target}", unit), fontsize=11)
        default = f"SHAP summary: {target}, {size}"
    else:
        ax.set_xlabel(with_unit(f"SHAP value: effect on {EXPLAINED[explained]} of {target}",
                                unit), fontsize=11)
        default = f"SHAP summary of {EXPLAINED[explained]}: {target}\n{size}"
    ax.tick_params("y", labelsize=10)
    ax.set_title(with_setting(title or default, setting), fontsize=12)
    return fit_text(fig)


def correction_shap_figure(shap: ShapValues | None, *, target: str, unit: str | None = None,
                           note: str = "", max_display: int = 10, random_state: int = 0,
                           title: str | None = None, setting: str | None = None) -> Figure:
    """Draw the SHAP summary of a per-target model's correction (model - prior).

    Parameters
    ----------
    shap : ShapValues or None
        The correction's SHAP values (the ``correction`` of
        :func:`~workbench.experiment.scoring.explain.target_shap_values`). ``None``: the model
        is the prior (its correction is 0 on every row), and the figure says so, with ``note``,
        instead of a beeswarm of zeros.
    target : str
        The target's name.
    unit : str, optional
        The prediction's unit; ``None``: none shown.
    note : str, default=""
        Why the model is its prior (:func:`~workbench.experiment.scoring.explain.prior_reason`).
    max_display, random_state, title, setting
        As :func:`shap_figure`'s.

    Returns
    -------
    matplotlib.figure.Figure
        The summary, or the figure saying there is nothing to explain.
    """
    if shap is not None:
        return shap_figure(shap.values, shap.expected, shap.rows, target=target, unit=unit,
                           max_display=max_display, random_state=random_state, title=title,
                           setting=setting, explained="correction")
    fig = new_figure(7.0, 2.2)
    ax = fig.add_subplot()
    ax.set_axis_off()
    why = f" ({note})" if note else ""
    ax.text(0.5, 0.5, f"The model of {target} is its prior{why}:\nthe correction "
                      f"(model − prior) is 0{unit_suffix(unit)} on every row; nothing to "
                      "explain.",
            ha="center", va="center", fontsize=11, transform=ax.transAxes, wrap=True)
    default = f"SHAP summary of {EXPLAINED['correction']}: {target}"
    ax.set_title(with_setting(title or default, setting), fontsize=12)
    return fit_text(fig)
