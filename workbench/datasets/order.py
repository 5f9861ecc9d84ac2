"""The order of a data set's rows: a column of dates, times or run numbers.

:func:`order_values` reads such a column (numbers as numbers, else dates and times as UTC
datetimes) for the ordered CV folds (:class:`~workbench.selection.LabelTimeSeriesSplit`)
and the split that tests on the latest rows (:func:`latest_rows`).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

__all__ = ["BadOrderValues", "latest_rows", "order_values", "parse_dates"]

#: What a CSV's cell reads as when missing (as :mod:`workbench.datasets.csv` reads them).
_MISSING = ("", "nan", "na", "null", "nat", "none")


class BadOrderValues(ValueError):
    """An order column with missing or unreadable cells.

    Parameters
    ----------
    what : {"missing", "unreadable"}
        Which cells.
    rows : ndarray of int
        Their positions.
    """

    def __init__(self, what: str, rows: np.ndarray) -> None:
        super().__init__(f"{what} order values at rows {list(rows[:5])}")
        self.what = what
        self.rows = rows


def parse_dates(raw: pd.Series) -> pd.Series:
    """Read text as UTC datetimes (ISO 8601 first, else any format dateutil reads; a value
    without a zone is taken as UTC); NaT where a cell is not a date.

    Parameters
    ----------
    raw : pandas.Series
        The text.

    Returns
    -------
    pandas.Series
        The datetimes, indexed as ``raw``.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pandas' notes on formats it had to guess
        dates = pd.to_datetime(raw, format="ISO8601", utc=True, errors="coerce")
        if dates.isna().any():
            dates = pd.to_datetime(raw, format="mixed", utc=True, errors="coerce")
    return pd.Series(dates, index=raw.index)


def order_values(raw: pd.Series) -> pd.Series:
    """Read a column of text as order values: numbers (run numbers, epochs, times in
    seconds) when every cell is one, else datetimes.

    Parameters
    ----------
    raw : Series of str
        The column's cells.

    Returns
    -------
    Series
        Floats, or UTC datetimes; same index and name.

    Raises
    ------
    BadOrderValues
        For missing cells, or cells that are neither numbers nor dates (their positions).
    """
    text = raw.astype(str).str.strip()
    missing = text.str.lower().isin(_MISSING).to_numpy()
    if missing.any():
        raise BadOrderValues("missing", np.flatnonzero(missing))
    numbers = pd.to_numeric(text, errors="coerce")
    if numbers.notna().all():
        if not np.isfinite(numbers.to_numpy(dtype=float)).all():
            raise BadOrderValues("missing", np.flatnonzero(~np.isfinite(numbers)))
        return numbers.astype(float).rename(raw.name)
    dates = parse_dates(text)
    if dates.isna().any():
        raise BadOrderValues("unreadable", np.flatnonzero(dates.isna().to_numpy()))
    return dates.rename(raw.name)


def latest_rows(order: pd.Series, fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """Split rows into the earlier (training) and the latest (test) ones.

    The test rows are the ``fraction`` of the rows with the largest order values; rows that
    share the value at the cut are all test rows (equal values stay on one side).

    Parameters
    ----------
    order : Series
        Each row's order value, indexed by row label.
    fraction : float
        The test share, in (0, 1).

    Returns
    -------
    train : ndarray
        The training rows' labels, in the index's order.
    test : ndarray
        The test rows' labels, in the index's order.
    """
    n_test = int(round(len(order) * float(fraction)))
    if n_test == 0:
        return np.asarray(order.index), np.asarray(order.index[:0])
    cut = order.sort_values(kind="stable").iloc[len(order) - n_test]
    test = (order >= cut).to_numpy()
    return np.asarray(order.index[~test]), np.asarray(order.index[test])
