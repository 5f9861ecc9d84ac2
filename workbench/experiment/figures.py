"""Figures of the base-boosting paper, as functions that return a matplotlib ``Figure``.

* :func:`mae_bars` -- per-target test error, control program vs learned model (Fig. 2, S4).
* :func:`learning_curve_figure` -- the augmented learning curve (Fig. 4, S5).
* :func:`shap_summary` -- SHAP beeswarm summary of a model's predictions (Fig. 5, S8).
* :func:`save_figure` -- write a figure to PNG and close it.

Figures are built on :class:`matplotlib.figure.Figure` directly, never through pyplot, so no
global figure state is created or leaked and no GUI backend is needed; nothing is shown.
The same data give the same figure.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..boosting import check_predictions
from ..curves import LearningCurve

__all__ = ["learning_curve_figure", "mae_bars", "save_figure", "shap_summary"]

#: Colours (Okabe-Ito, readable in grey scale and by colour-blind readers).
PRIOR_COLOR = "#7f7f7f"
MODEL_COLOR = "#0072B2"
TRAIN_COLOR = "#E69F00"
INCUMBENT_COLOR = "#000000"

_METRICS = {  # scorer name -> (axis label, is the unit squared)
    "neg_mean_absolute_error": ("MAE", False),
    "neg_median_absolute_error": ("median absolute error", False),
    "neg_root_mean_squared_error": ("RMSE", False),
    "neg_mean_squared_error": ("MSE", True),
    "neg_max_error": ("max error", False),
}


def _new_figure(width: float, height: float) -> Figure:
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


def mae_bars(targets: Sequence[str], prior, model, *, metric: str = "MAE", unit: str = "MHz",
             title: str | None = None, labels: tuple[str, str] = ("control program",
                                                                  "base boosting"),
             setting: str | None = None, average: bool = True) -> Figure:
    """Grouped bars of a per-target error for the prior and the model, plus their averages.

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
    """
    names = [str(t) for t in targets]
    if not names:
        raise ValueError("targets is empty")
    prior = _values("prior", prior, len(names))
    model = _values("model", model, len(names))
    if average:
        names = [*names, "average"]
        prior = np.append(prior, prior.mean())
        model = np.append(model, model.mean())

    fig = _new_figure(max(5.0, 0.95 * len(names) + 1.8), 4.0)
    ax = fig.add_subplot()
    x = np.arange(len(names), dtype=float)
    width = 0.38
    bars_prior = ax.bar(x - width / 2, prior, width, label=labels[0], color=PRIOR_COLOR)
    bars_model = ax.bar(x + width / 2, model, width, label=labels[1], color=MODEL_COLOR)
    for bars in (bars_prior, bars_model):
        ax.bar_label(bars, fmt="%.2f", padding=2, fontsize=8)
    if average:
        ax.axvline(len(names) - 1.5, color="#bbbbbb", lw=1, ls=":")
    ax.set_xticks(x, names, fontsize=10)
    ax.set_xlabel("target", fontsize=11)
    ax.set_ylabel(f"{metric} ({unit})", fontsize=11)
    top = np.nanmax(np.concatenate([prior, model])) if np.any(np.isfinite(prior)) else 1.0
    ax.set_ylim(0, top * 1.22 if np.isfinite(top) and top > 0 else 1.0)
    ax.legend(loc="upper right", frameon=False, fontsize=10, ncols=2)
    ax.set_title(_with_setting(title or f"Test {metric} per target: {labels[0]} vs {labels[1]}",
                               setting), fontsize=12)
    _style(ax)
    return fig


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

    ``predict`` receives plain 2-D float arrays (the columns of ``X``, in order) and is
    wrapped in a lambda, never passed as a bound method (see the SHAP notes in the docs).
    The explainer is ``shap.KernelExplainer`` with ``background_size`` rows of ``X`` sampled
    with ``random_state`` as background: for up to ~11 features its default ``nsamples``
    enumerates every coalition, giving the same values as ``shap.Explainer`` with an
    ``Independent`` masker on that background, without the latter's multi-second JIT
    compile. About a second for 95 rows x 9 features with a small model.

    Returns the figure and the SHAP values, an array of shape ``(n_rows, n_features)`` in
    the prediction's unit.
    """
    import shap  # heavy; imported only when a SHAP figure is asked for

    if not isinstance(X, pd.DataFrame):
        raise TypeError(f"X must be a pandas DataFrame (its columns name the features); got "
                        f"{type(X).__name__}")
    if len(X) == 0 or X.shape[1] == 0:
        raise ValueError(f"X is empty: shape {X.shape}")
    names = [str(c) for c in X.columns]
    data = X.to_numpy(dtype=float)
    background = shap.sample(data, background_size, random_state=random_state)
    explainer = shap.KernelExplainer(lambda a: check_predictions(predict(a), len(a), "predict"), background,
                                     seed=random_state)
    values = np.asarray(explainer.shap_values(data, nsamples=nsamples, silent=True),
                        dtype=float)
    explanation = shap.Explanation(values=values,
                                   base_values=np.full(len(data), explainer.expected_value),
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
    ax.set_xlabel(f"SHAP value: effect on predicted {target} ({unit})", fontsize=11)
    ax.tick_params("y", labelsize=10)
    default = f"SHAP summary: {target}, {len(data)} rows x {len(names)} features"
    ax.set_title(_with_setting(title or default, setting), fontsize=12)
    return fig, values


def save_figure(fig: Figure, path: str | Path, *, dpi: int = 120) -> Path:
    """Write ``fig`` as a PNG (creating parent directories), close it, return the path.

    A path without a suffix gets ``.png``; any other suffix than ``.png`` is an error.
    """
    path = Path(path)
    if path.suffix == "":
        path = path.with_suffix(".png")
    if path.suffix.lower() != ".png":
        raise ValueError(f"save_figure writes PNG files; got the suffix {path.suffix!r} in {path}")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, format="png")
    if getattr(fig.canvas, "manager", None) is not None:  # a pyplot figure: drop its reference
        import matplotlib.pyplot as plt

        plt.close(fig)
    return path
