"""The look every figure shares.

Colours, a new figure, axes and titles, the PNG writer, and the check of the data frames a
figure draws.

Figures are built on :class:`matplotlib.figure.Figure` directly, never through pyplot, so no
global figure state is created or leaked and no GUI backend is needed. matplotlib is imported
when the first figure is drawn, so a command that draws nothing does not load it.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from ..._io import atomic_write

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["COUPLER_COLOR", "INCUMBENT_COLOR", "MEASURED_COLOR", "MODEL_COLOR",
           "OTHER_SYSTEM_COLORS", "PRIOR_COLOR", "QUBIT_COLOR", "TRAIN_COLOR", "new_figure",
           "PNG_DPI", "numeric_frame", "save_figure", "style_axes", "with_setting"]

#: The resolution of every PNG the workbench writes (``--out``, a run's figures, the report).
PNG_DPI = 120

#: Colours (Okabe-Ito, readable in grey scale and by colour-blind readers).
PRIOR_COLOR = "#7f7f7f"
MODEL_COLOR = "#0072B2"
TRAIN_COLOR = "#E69F00"
INCUMBENT_COLOR = "#000000"
MEASURED_COLOR = "#009E73"
QUBIT_COLOR = "#56B4E9"
COUPLER_COLOR = "#E69F00"
#: Colours of the systems of :func:`~workbench.experiment.figures.model_comparison_bars` not
#: named after a known system.
OTHER_SYSTEM_COLORS = ("#D55E00", "#009E73", "#CC79A7", "#56B4E9")


def new_figure(width: float, height: float) -> Figure:
    """Create a figure with constrained layout, outside pyplot.

    Parameters
    ----------
    width, height : float
        The size in inches.

    Returns
    -------
    matplotlib.figure.Figure
        The empty figure.
    """
    from matplotlib.figure import Figure  # deferred: a command that draws nothing skips it

    return Figure(figsize=(width, height), layout="constrained")


def style_axes(ax: Axes) -> None:
    """Drop the top and right spines and set the tick labels' size.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The axes to style.
    """
    ax.spines["top"].set_visible(False)
    ax.spines["right"].set_visible(False)
    ax.tick_params(labelsize=10)


def with_setting(title: str, setting: str | None) -> str:
    """Add a second line naming the setting to a title.

    Parameters
    ----------
    title : str
        The first line.
    setting : str or None
        The setting (e.g. the config); ``None`` or empty: no second line.

    Returns
    -------
    str
        The title.
    """
    return f"{title}\n{setting}" if setting else title


def save_figure(fig: Figure, path: str | Path, *, dpi: int = PNG_DPI) -> Path:
    """Write ``fig`` as a PNG (creating parent directories) and close it.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or Path
        The file; a path without a suffix gets ``.png``.
    dpi : int, default=PNG_DPI
        The resolution (120 dots per inch).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ValueError
        If ``path`` has a suffix other than ``.png``.
    """
    path = Path(path)
    if path.suffix == "":
        path = path.with_suffix(".png")
    if path.suffix.lower() != ".png":
        raise ValueError(f"save_figure writes PNG files; got the suffix {path.suffix!r} in {path}")
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=dpi, format="png")
    atomic_write(path, buffer.getvalue())
    if getattr(fig.canvas, "manager", None) is not None:  # a pyplot figure: drop its reference
        import matplotlib.pyplot as plt  # deferred: a command that draws nothing skips it

        plt.close(fig)
    return path


def numeric_frame(name: str, frame: Any) -> pd.DataFrame:
    """``frame`` as a float DataFrame, checked.

    Parameters
    ----------
    name : str
        The argument's name, for the error messages.
    frame : pandas.DataFrame
        The data; its columns name the series.

    Returns
    -------
    pandas.DataFrame
        ``frame`` as floats.

    Raises
    ------
    TypeError
        If ``frame`` is not a DataFrame.
    ValueError
        If it is empty or has a non-numeric (or boolean) column.
    """
    if not isinstance(frame, pd.DataFrame):
        raise TypeError(f"{name} must be a pandas DataFrame (its columns name the series); got "
                        f"{type(frame).__name__}")
    if frame.shape[0] == 0 or frame.shape[1] == 0:
        raise ValueError(f"{name} is empty: shape {frame.shape}")
    bad = [str(c) for c in frame.columns if not pd.api.types.is_numeric_dtype(frame[c])
           or pd.api.types.is_bool_dtype(frame[c])]
    if bad:
        raise ValueError(f"{name} has non-numeric columns: {bad}")
    return frame.astype(float)
