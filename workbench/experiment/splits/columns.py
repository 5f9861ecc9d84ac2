"""What ``workbench init`` reads off a CSV's columns.

:func:`numeric_columns` finds the default features; :func:`group_columns` the text
columns whose values repeat (a device, a cooldown), candidates for ``[data] group_column``;
:func:`find_order_column` the column that orders the rows in time (dates, datetimes, run
numbers), which ``init`` writes as ``[data] order_column``: forward-chaining CV folds and
the latest rows as the test rows.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...datasets import read_csv_cells
from ...datasets.order import parse_dates

__all__ = ["ORDER_NAMES", "OrderColumn", "find_order_column", "group_columns",
           "numeric_columns"]

#: What the loader reads as a missing cell (``workbench.datasets.csv``).
_MISSING = ("", "nan", "na", "null")

#: Words in a column's name that say a number orders the rows (``run_number``, ``epoch``,
#: ``timestamp``, ``RunNumber``...): such a column of whole numbers, mostly increasing down
#: the file, is an order column.
ORDER_NAMES = ("time", "date", "datetime", "timestamp", "run", "runnumber", "epoch")
#: The share of consecutive rows whose number does not decrease, at least, for "mostly
#: increasing" (a file sorted by device, then by run, still passes).
MONOTONE_SHARE = 0.9


@dataclass(frozen=True)
class OrderColumn:
    """A column found to order the rows in time.

    Parameters
    ----------
    column : str
        Its name.
    kind : {"dates", "numbers"}
        Dates and times, or numbers (run numbers, epochs).
    first, last : str
        Its earliest and latest values, as shown.
    n_values : int
        Its distinct values.
    """

    column: str
    kind: str
    first: str
    last: str
    n_values: int

    @classmethod
    def of(cls, order: pd.Series) -> OrderColumn:
        """Describe a dataset's ``order`` (numbers or datetimes).

        Parameters
        ----------
        order : Series
            The rows' order values, named by their column.

        Returns
        -------
        OrderColumn
            Its kind, range and distinct values.
        """
        dates = pd.api.types.is_datetime64_any_dtype(order)
        show = (lambda v: str(v.date() if v == v.normalize() else v)) if dates else \
            (lambda v: f"{v:.15g}")
        return cls(str(order.name), "dates" if dates else "numbers", show(order.min()),
                   show(order.max()), int(order.nunique()))

    def describe(self) -> str:
        """Say what was found, e.g. ``column 'date' holds dates (2024-01-01 to ...)``.

        Returns
        -------
        str
            One phrase.
        """
        return (f"column {self.column!r} holds {self.kind} ({self.first} to {self.last}, "
                f"{self.n_values} distinct)")


def numeric_columns(path: str | os.PathLike[str], exclude: Sequence[str]
                    ) -> tuple[list[str], dict[str, str]]:
    """Split the CSV's columns into the numeric ones and the others.

    Cells are read as the loader reads them (text, stripped; empty, ``nan``, ``na``, ``null``
    missing); call it once the loader has read the file.

    Parameters
    ----------
    path : path-like
        The CSV file.
    exclude : sequence of str
        Columns not considered.

    Returns
    -------
    taken : list of str
        The columns whose every cell is a finite number, in the file's order.
    skipped : dict of str to str
        The others, with the reason they were left out.
    """
    frame = read_csv_cells(path)
    taken: list[str] = []
    skipped: dict[str, str] = {}
    for column in frame.columns:
        if column in exclude:
            continue
        raw = frame[column].str.strip()
        missing = raw.str.lower().isin(_MISSING)
        values = pd.to_numeric(raw.where(~missing, "nan"), errors="coerce")
        if (values.isna() & ~missing).any():
            skipped[column] = "not numeric"
        elif not np.isfinite(values.to_numpy(dtype=float)).all():
            skipped[column] = "missing or infinite values"
        else:
            taken.append(column)
    return taken, skipped


def group_columns(path: str | os.PathLike[str], exclude: Sequence[str]) -> dict[str, int]:
    """Find the text columns whose values repeat, candidates for ``[data] group_column``.

    Rows that share such a value (the device or the cooldown a row was measured in) are often
    alike, so plain K-fold CV, which puts some of them on each side of a fold, rewards what
    only repeats within a group; ``[data] group_column`` keeps each group whole in one fold.

    Parameters
    ----------
    path : path-like
        The CSV file.
    exclude : sequence of str
        Columns not considered.

    Returns
    -------
    dict of str to int
        Each such column with its number of distinct values (between 2 and half the rows).
    """
    frame = read_csv_cells(path)
    out = {}
    for column in frame.columns:
        if column in exclude:
            continue
        raw = frame[column].str.strip()
        if pd.to_numeric(raw, errors="coerce").notna().all():
            continue  # a number: a feature, not a name
        n = raw.nunique()
        if 2 <= n <= len(raw) // 2:
            out[column] = int(n)
    return out


def _order_name(name: str) -> bool:
    """Whether a column's name says it orders the rows (:data:`ORDER_NAMES`)."""
    spaced = re.sub(r"([a-z0-9])([A-Z])", r"\1 \2", name).lower()
    words = re.split(r"[^a-z0-9]+", spaced)
    joined = "".join(words)
    return any(w in ORDER_NAMES for w in words) or joined in ORDER_NAMES


def _as_order(column: str, raw: pd.Series) -> OrderColumn | None:
    """Read the column as an order column, or ``None``.

    Dates in every cell (each with a digit), or whole numbers under an order name, mostly
    increasing down the file.
    """
    if raw.nunique() < 2 or raw.str.lower().isin((*_MISSING, "nat")).any():
        return None
    numbers = pd.to_numeric(raw, errors="coerce")
    if numbers.notna().all():
        values = numbers.to_numpy(dtype=float)
        if not (_order_name(column) and np.all(np.isfinite(values))
                and np.all(values == np.round(values))
                and np.mean(np.diff(values) >= 0) >= MONOTONE_SHARE):
            return None
        return OrderColumn(column, "numbers", f"{values.min():.0f}", f"{values.max():.0f}",
                           int(raw.nunique()))
    if not raw.str.contains(r"\d").all():
        return None  # month or day names alone are no dates to order by
    dates = parse_dates(raw)
    if dates.isna().any():
        return None
    return OrderColumn(column, "dates", str(raw[dates.idxmin()]), str(raw[dates.idxmax()]),
                       int(dates.nunique()))


def find_order_column(path: str | os.PathLike[str],
                      exclude: Sequence[str]) -> OrderColumn | None:
    """Find the column that orders the CSV's rows in time.

    A column of dates or datetimes (every cell one), else a column of whole numbers whose
    name says it orders the rows (:data:`ORDER_NAMES`: ``run``, ``run_number``, ``epoch``,
    ``time``, ...) and that mostly increases down the file; the first such in the file.

    Parameters
    ----------
    path : path-like
        The CSV file.
    exclude : sequence of str
        Columns not considered (the prior, target and split columns).

    Returns
    -------
    OrderColumn or None
        What was found, dates before numbers; ``None``: no such column.
    """
    frame = read_csv_cells(path)
    found = [o for c in frame.columns if c not in exclude
             if (o := _as_order(c, frame[c].str.strip())) is not None]
    dates = [o for o in found if o.kind == "dates"]
    best = dates or found
    return best[0] if best else None
