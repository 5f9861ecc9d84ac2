"""The look every figure shares.

Colours, a new figure, axes and titles, the PNG writer, and the check of the data frames a
figure draws.

Figures are built on :class:`matplotlib.figure.Figure` directly, never through pyplot, so no
global figure state is created or leaked and no GUI backend is needed. matplotlib is imported
when the first figure is drawn, so a command that draws nothing does not load it.
"""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from ..._io import atomic_write

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["COUPLER_COLOR", "INCUMBENT_COLOR", "MEASURED_COLOR", "MODEL_COLOR",
           "OTHER_SYSTEM_COLORS", "PRIOR_COLOR", "QUBIT_COLOR", "TRAIN_COLOR", "fit_text",
           "new_figure", "PNG_DPI", "numeric_frame", "save_figure", "style_axes", "text_inches",
           "with_setting", "wrap"]

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


#: A character's width as a share of its font size (DejaVu Sans, matplotlib's font: 0.55-0.6
#: for names and numbers), used to estimate how many characters fit a width.
CHAR_EM = 0.62

_BREAK = re.compile(r"[^ _/,-]*[ _/,-]*")  # a word with the separators after it


def text_inches(chars: int, fontsize: float) -> float:
    """Estimate the width in inches of ``chars`` characters at ``fontsize`` points."""
    return chars * CHAR_EM * fontsize / 72


def wrap(text: str, width: int) -> str:
    """Wrap each line of ``text`` at ``width`` characters.

    Lines break after a space, an underscore, a hyphen, a slash or a comma (column names such
    as ``two_qubit_gate_error`` have no spaces); a word longer than ``width`` is cut.

    Parameters
    ----------
    text : str
        The text; its own line breaks are kept.
    width : int
        The most characters of a line (at least 4).

    Returns
    -------
    str
        The wrapped text.
    """
    width = max(4, int(width))
    lines: list[str] = []
    for line in text.split("\n"):
        current = ""
        for piece in filter(None, _BREAK.findall(line)):
            if current and len(current) + len(piece.rstrip()) > width:
                lines.append(current.rstrip())
                current = ""
            while len(piece.rstrip()) > width:
                lines.append(piece[:width])
                piece = piece[width:]
            current += piece
        lines.append(current.rstrip())
    return "\n".join(lines)


def _wrap_to(text: Any, inches: float, renderer: Any, *, vertical: bool = False,
             obstacles: list[Any] | None = None) -> None:
    """Wrap a Text artist that is longer than ``inches`` (its height if ``vertical``).

    Measured with ``renderer``; a text that fits is left as it is. With ``obstacles``
    (window extents), a text that is longer but stays on the canvas clear of them is left
    too.
    """
    content = text.get_text()
    if not content or not text.get_visible() or inches <= 0:
        return
    if obstacles is not None:
        box = text.get_window_extent(renderer)
        canvas = text.figure.bbox.padded(-2)
        if (box.x0 >= canvas.x0 and box.x1 <= canvas.x1
                and not any(box.overlaps(other) for other in obstacles)):
            return
    room = inches * text.figure.dpi
    longest = max(len(line) for line in content.split("\n"))
    for _ in range(4):  # characters differ in width: narrow further while it does not fit
        box = text.get_window_extent(renderer)
        size = box.height if vertical else box.width
        if size <= room or longest <= 6:
            return
        longest = max(6, min(longest - 1, int(longest * room / size)))
        text.set_text(wrap(content, longest))


def _category_ticks(ax: Axes, fig_width: float, renderer: Any) -> bool:
    """Wrap the x tick labels of a categorical axis to the space between two ticks.

    Returns whether a label changed.
    """
    from matplotlib.ticker import FixedLocator  # deferred: as new_figure

    labels = ax.get_xticklabels()
    locs = ax.get_xticks()
    if (len(locs) < 1 or not isinstance(ax.xaxis.get_major_locator(), FixedLocator)
            or any(t.get_rotation() for t in labels)):
        return False
    low, high = ax.get_xlim()
    axes_inches = ax.get_position().width * fig_width
    step = float(min(abs(b - a) for a, b in zip(locs[:-1], locs[1:]))) if len(locs) > 1 \
        else abs(high - low)
    before = [t.get_text() for t in labels]
    for label in labels:
        _wrap_to(label, 0.92 * step / abs(high - low) * axes_inches, renderer)
    after = [t.get_text() for t in labels]
    if after == before:
        return False
    ax.set_xticks(locs, after, fontsize=labels[0].get_fontsize())
    return True


def _lay_out(fig: Figure) -> None:
    """Place the axes as the figure's layout engine will when it is drawn.

    What :meth:`~matplotlib.figure.Figure.draw_without_rendering` does first, without
    drawing every artist after it (a quarter of the time of making a figure): the texts are
    measured afterwards, and the file is drawn by ``savefig``. A figure without a layout
    engine keeps its axes where they are.
    """
    engine = fig.get_layout_engine()
    if engine is not None:
        engine.execute(fig)


def fit_text(fig: Figure) -> Figure:
    """Wrap a figure's texts that do not fit their place, once the layout is known.

    Lays ``fig`` out (without rendering it), then wraps each axes' title and x-axis label that
    is wider than the axes and leaves the canvas or meets another axes (with its tick labels,
    title and labels), its y-axis label taller than the axes, the tick labels of a
    categorical x axis (ticks at fixed places, labels not rotated) wider than the space
    between two ticks (first: the axes move when they shrink), and the figure's title wider
    than the figure. Texts that fit are left as they are. Call it last, when every text is
    set.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, drawn.

    Returns
    -------
    matplotlib.figure.Figure
        ``fig``.
    """
    from matplotlib.backends.backend_agg import RendererAgg  # deferred: as new_figure

    _lay_out(fig)
    # a renderer of the figure's size measures the texts (the figure's canvas is kept)
    renderer = RendererAgg(int(fig.bbox.width), int(fig.bbox.height), fig.dpi)
    width, height = fig.get_figwidth(), fig.get_figheight()
    shown = [ax for ax in fig.axes if ax.get_visible()]
    ticks = [ax for ax in shown if ax.axison and _category_ticks(ax, width, renderer)]
    if ticks:  # the axes move when their tick labels shrink
        _lay_out(fig)
    # a title or x label wider than its axes stays where it is on the canvas and clear of
    # the other axes (their tick labels, titles and labels too)
    tight = {ax: ax.get_tightbbox(renderer) for ax in shown}
    for ax in shown:
        others = [box for other, box in tight.items() if other is not ax and box is not None]
        box = ax.get_position()
        _wrap_to(ax.title, box.width * width, renderer, obstacles=others)
        _wrap_to(ax.xaxis.label, box.width * width, renderer, obstacles=others)
        _wrap_to(ax.yaxis.label, box.height * height, renderer, vertical=True)
    title = getattr(fig, "_suptitle", None)  # matplotlib keeps no public handle on it
    if title is not None:
        _wrap_to(title, width - 0.3, renderer)
    return fig


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
