"""The outer folds of a sweep's nested CV in one figure.

:func:`outer_folds_figure`: a bar per outer fold of every study block, its length the chosen
configuration's MAE on the fold's validation rows, the prior's beside it, each
labelled with the configuration the fold's study chose (its best trial's parameters).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..scoring.units import with_unit
from .style import MODEL_COLOR, PRIOR_COLOR, fit_text, new_figure, style_axes

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..scoring.results import OuterFold

__all__ = ["configuration_label", "outer_folds_figure"]

#: Most characters of a configuration's label.
LABEL_CHARS = 70


def _short(value: Any) -> str:
    """Write a parameter's value short: numbers to 3 significant digits."""
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def configuration_label(params: dict[str, Any] | None) -> str:
    """Label a chosen configuration in one short line.

    Parameters
    ----------
    params : dict or None
        The best trial's parameters; ``None`` where no trial completed (the prior stands).

    Returns
    -------
    str
        ``basis`` first when there is one, then ``name=value`` pairs, at most
        :data:`LABEL_CHARS` characters.
    """
    if params is None:
        return "prior (no trial completed)"
    items = sorted(params.items(), key=lambda kv: (kv[0] != "basis", kv[0]))
    text = ", ".join(_short(v) if k == "basis" else f"{k}={_short(v)}" for k, v in items)
    return text if len(text) <= LABEL_CHARS else text[:LABEL_CHARS - 3] + "..."


def outer_folds_figure(folds: Sequence[OuterFold], unit: str | None = None,
                       title: str = "Nested CV: each outer fold's choice", *,
                       prior_label: str = "prior") -> Figure:
    """Draw each outer fold's chosen configuration and its score on the fold's held-out rows.

    Parameters
    ----------
    folds : sequence of OuterFold
        The sweep's outer folds
        (:attr:`~workbench.experiment.scoring.results.SweepSummary.outer_folds`).
    unit : str, optional
        The targets' unit (``None``: none shown).
    title : str, default="Nested CV: each outer fold's choice"
        The figure's title.
    prior_label : str, default="prior"
        The prior's legend entry (the data set's name of its prior,
        :attr:`~workbench.datasets.Dataset.prior_label`).

    Returns
    -------
    matplotlib.figure.Figure
        One bar pair per fold, top to bottom in the sweep's order.
    """
    n = len(folds)
    fig = new_figure(9.0, 1.2 + 0.42 * max(n, 1))
    ax = fig.add_subplot()
    style_axes(ax)
    rows = list(range(n))[::-1]
    ax.barh([r + 0.2 for r in rows], [f.prior_mae for f in folds], height=0.4,
            color=PRIOR_COLOR, label=prior_label)
    ax.barh([r - 0.2 for r in rows], [f.mae for f in folds], height=0.4, color=MODEL_COLOR,
            label="chosen configuration")
    ax.set_yticks(rows, [f"{f.block} fold {f.fold}: {configuration_label(f.params)}"
                         for f in folds], fontsize=7)
    ax.set_xlabel(with_unit("MAE on the fold's validation rows", unit))
    ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    return fit_text(fig)
