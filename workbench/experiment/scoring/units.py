"""How a unit is written beside a number, on an axis and in a sentence.

Every error the workbench reports is in its targets' unit, which the data carry
(:attr:`workbench.datasets.Dataset.unit`: ``"MHz"`` for the Google benchmark, ``"%"`` for the
IBM gates, a CSV's ``[data] unit``); without one (``None``), no unit is shown.
"""

from __future__ import annotations

__all__ = ["squared", "unit_name", "unit_suffix", "with_unit"]


def with_unit(label: str, unit: str | None) -> str:
    """Follow a label with its unit in parentheses, as axes and table columns show it.

    Parameters
    ----------
    label : str
        What is labelled, e.g. ``"MAE"``.
    unit : str or None
        The unit, e.g. a dataset's :attr:`~workbench.datasets.Dataset.unit`; ``None`` (or
        empty): no unit is shown.

    Returns
    -------
    str
        ``"<label> (<unit>)"``, or ``label`` alone without a unit.
    """
    return f"{label} ({unit})" if unit else label


def unit_suffix(unit: str | None) -> str:
    """Write the unit as it follows a number in a sentence.

    Parameters
    ----------
    unit : str or None
        The unit; ``None`` (or empty): no unit.

    Returns
    -------
    str
        ``" <unit>"`` (e.g. ``" MHz"``), or ``""`` without a unit.
    """
    return f" {unit}" if unit else ""


def unit_name(unit: str | None) -> str:
    """Name the unit in a sentence, also when the data name none.

    Parameters
    ----------
    unit : str or None
        The unit.

    Returns
    -------
    str
        ``unit``, or ``"the targets' units"`` without one.
    """
    return unit or "the targets' units"


def squared(unit: str | None) -> str | None:
    """Square a unit, for a squared error (an MSE).

    Parameters
    ----------
    unit : str or None
        The targets' unit.

    Returns
    -------
    str or None
        ``"<unit>²"`` (``"MHz²"`` for ``"MHz"``), or ``None`` without a unit.
    """
    return f"{unit}²" if unit else None
