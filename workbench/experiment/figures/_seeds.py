"""The spread of the test error over seeds: each seed's error as a point, the mean +- sd."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..scoring.units import with_unit
from .style import (
    INCUMBENT_COLOR,
    MODEL_COLOR,
    PRIOR_COLOR,
    fit_text,
    new_figure,
    style_axes,
    text_inches,
    with_setting,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["seed_spread"]


def seed_spread(targets: Sequence[str], errors: ArrayLike, *, random_states: Sequence[int],
                prior: Sequence[float] | None = None, metric: str = "test MAE",
                unit: str | None = None, title: str | None = None,
                setting: str | None = None, prior_label: str = "prior") -> Figure:
    """Draw how a model's error spreads over seeds, per target and on average.

    Per target (and their average, set apart by a dotted line) each seed's error as a point,
    jittered sideways in the seeds' order, and the mean over seeds +- the sample standard
    deviation as a bar; the prior's error, which no seed changes, as a short grey line.

    Parameters
    ----------
    targets : sequence of str
        Target names, one column each.
    errors : array-like of shape (n_seeds, n_targets)
        Each seed's error per target.
    random_states : sequence of int
        The seeds (each a ``random_state``), in the rows' order (the title names them).
    prior : sequence of float, optional
        The prior's error per target; ``None``: not drawn.
    metric : str, default="test MAE"
        The error's name on the axis.
    unit : str, optional
        The error's unit; ``None``: none shown.
    title : str, optional
        Default: ``"<metric> over <n> seeds"``.
    setting : str, optional
        A second title line naming the setting.
    prior_label : str, default="prior"
        The prior's legend entry (the data set's name of its prior,
        :attr:`~workbench.datasets.Dataset.prior_label`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    Raises
    ------
    ValueError
        If the errors are not one row per seed and one column per target, or there are
        fewer than two seeds.
    """
    seeds = list(random_states)
    names = [str(t) for t in targets]
    values = np.asarray(errors, dtype=float)
    if values.ndim != 2 or values.shape != (len(seeds), len(names)) or not names:
        raise ValueError(f"errors must have one row per seed and one column per target, "
                         f"shape ({len(seeds)}, {len(names)}); got {values.shape}")
    if len(seeds) < 2:
        raise ValueError(f"a spread needs two or more seeds, got {len(seeds)}")
    values = np.column_stack([values, values.mean(axis=1)])
    names.append("average")
    x = np.arange(len(names), dtype=float)
    rotate = len(names) > 6
    longest = min(max(map(len, names)), 16)  # longer names wrap (fit_text)
    column = 1.1 if rotate else max(1.1, text_inches(longest, 10) + 0.2)
    fig = new_figure(max(4.5, column * len(names) + 1.5), 4.2)
    ax = fig.subplots()
    jitter = np.linspace(-0.18, 0.18, len(seeds))
    for i in range(len(seeds)):
        ax.scatter(x + jitter[i], values[i], s=16, color=MODEL_COLOR, alpha=0.55,
                   edgecolors="none", zorder=3, label="one seed" if i == 0 else None)
    mean, sd = values.mean(axis=0), values.std(axis=0, ddof=1)
    ax.errorbar(x + 0.3, mean, yerr=sd, fmt="o", color=INCUMBENT_COLOR, ms=5, capsize=4,
                lw=1.4, zorder=4, label="mean +- sd over seeds")
    if prior is not None:
        p = np.asarray(prior, dtype=float)
        p = np.append(p, p.mean())
        ax.hlines(p, x - 0.3, x + 0.3, color=PRIOR_COLOR, lw=1.6, zorder=2,
                  label=prior_label)
    ax.axvline(len(names) - 1.5, color=INCUMBENT_COLOR, lw=0.8, ls=":")
    ax.set_xticks(x, names, rotation=30 if rotate else 0, ha="right" if rotate else "center",
                  rotation_mode="anchor")
    ax.set_ylabel(with_unit(metric, unit))
    style_axes(ax)
    fig.legend(loc="outside lower center", ncols=3, frameon=False, fontsize=8)
    shown = ", ".join(str(s) for s in seeds[:8]) + (", ..." if len(seeds) > 8 else "")
    fig.suptitle(with_setting(title or f"{metric[:1].upper()}{metric[1:]} over {len(seeds)} "
                              f"seeds ({shown})", setting), fontsize=12)
    return fit_text(fig)
