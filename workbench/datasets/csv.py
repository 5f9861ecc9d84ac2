"""Datasets from a CSV file of your own experiments.

One row per experiment; columns named by the caller: one prior column per target (same
order), the targets, optional extra basis inputs (features), and optionally the control
model's Hamiltonian parameters. The split comes from a ``train``/``test`` column, from a
seeded random ``test_fraction``, or (``split="time"``) from the latest ``test_fraction`` of
the rows by an order column (dates, times or run numbers, :mod:`workbench.datasets.order`).
Every problem is reported as a :class:`DatasetError` that
names the file, the columns and the rows; nothing is written anywhere.

A message never quotes the file's content beyond its header, and the header only when it
looks like one (names of at most 64 characters, shortened): a config pointing at some
other file (``csv = "/etc/shadow"``) does not have its first line printed.
"""

from __future__ import annotations

import csv
import re
from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._text import clip
from ..hamiltonian import CouplingGraph, make_graph
from .base import Dataset, Hamiltonian
from .order import BadOrderValues, latest_rows, order_values

__all__ = ["DatasetError", "load_csv_dataset", "read_csv_cells", "read_numeric_columns",
           "read_once"]


class DatasetError(ValueError):
    """Input data that cannot be used; the message says what is wrong and where."""


#: The largest magnitude a value may have: beyond it, squares and sums of squares overflow
#: (a single 1e308 target gave a test MAE of 7e305 and no warning).
MAX_MAGNITUDE = 1e150
#: A column name as spreadsheets and scripts write them.
_NAME = re.compile(r"[^\W\d][\w .()\[\]%+/-]{0,63}")
#: Delimiters of other locales' exports, with their names.
_DELIMITERS = {";": "semicolons", "\t": "tabs", "|": "vertical bars"}


def _names(names: Iterable[Any], limit: int = 4, width: int = 30) -> str:
    """``'a', 'b', ... (N in all)``: at most ``limit`` names, each cut to ``width``."""
    names = [str(n) for n in names]
    shown = [repr(clip(n, width)) for n in names[:limit]]
    return ", ".join(shown) + (f", ... ({len(names)} in all)" if len(names) > limit else "")


def _is_header(names: Sequence[object]) -> bool:
    """Whether ``names`` look like a CSV header (two or more column names)."""
    return len(names) >= 2 and all(_NAME.fullmatch(str(n).strip()) for n in names)


def _one_column(path: Path, name: str) -> str:
    """The message for a first line without commas: a header with another delimiter, or not
    a CSV file at all (its content not shown)."""
    for delimiter, what in _DELIMITERS.items():
        parts = name.split(delimiter)
        if len(parts) >= 2 and _is_header(parts):
            shown = delimiter.join(p[:30] for p in parts[:3]) + (delimiter + "..."
                                                                   if len(parts) > 3 else "")
            return (f"{path} has one column named {shown!r} ({len(parts)} names separated by "
                    f"{what}): wrong delimiter? the workbench reads comma-separated files")
    return (f"{path} does not look like a CSV file: its first line is not a comma-separated "
            f"header (one row per experiment, a header row naming the columns)")


def _rows(labels: Sequence[int] | pd.Index, limit: int = 5) -> str:
    """Row labels as the lines of the file they come from (header is line 1)."""
    lines = [f"line {int(i) + 2}" for i in list(labels)[:limit]]
    more = len(labels) - limit
    return ", ".join(lines) + (f" and {more} more" if more > 0 else "")


def _header(path: Path, min_columns: int = 1) -> list[str]:
    """The header of the CSV file ``path``, checked: the file exists, is UTF-8 text, has a
    header of at least ``min_columns`` names (fewer: another delimiter, or not a CSV) and no
    name twice."""
    if not path.is_file():
        raise DatasetError(f"CSV file not found: {path}")
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            header = next(csv.reader(fh), None)
    except UnicodeDecodeError:
        raise DatasetError(f"{path} is not UTF-8 text: is it a CSV file?") from None
    except OSError as exc:
        raise DatasetError(f"cannot read {path}: {exc.strerror or type(exc).__name__}"
                           ) from None
    except csv.Error:  # e.g. a NUL byte
        raise DatasetError(f"{path} cannot be read as CSV: is it a CSV file?") from None
    if not header or not any(h.strip() for h in header):
        raise DatasetError(f"{path} is empty: expected a header row and one row per experiment")
    if len(header) < min_columns:
        raise DatasetError(_one_column(path, header[0]))
    dups = sorted(name for name, count in Counter(header).items() if count > 1)
    if dups:
        raise DatasetError(f"{path}: duplicated column names "
                           + (f"[{_names(dups)}]" if _is_header(header) else f"({len(dups)})"))
    return header


def _read(path: Path, min_columns: int = 1) -> pd.DataFrame:
    """Every cell of the CSV file ``path`` as text; ``min_columns``: fewer columns in its
    header is an error (a first line without commas: another delimiter, or not a CSV)."""
    return _cells(path, min_columns)[1]


def _cells(path: Path, min_columns: int) -> tuple[list[str], pd.DataFrame]:
    """The checked header and every cell as text; inside :func:`read_once`, read once."""
    memo = _ONCE.get()
    key = path.resolve()
    if memo is not None and key in memo:
        header, frame = memo[key]
        if len(header) < min_columns:
            raise DatasetError(_one_column(path, header[0]))
        return header, frame
    header = _header(path, min_columns)
    try:
        frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        reason = " ".join(str(exc).split())
        reason = clip(reason, 100)
        raise DatasetError(f"{path} is not a well-formed CSV file: {reason}") from None
    if frame.empty:
        raise DatasetError(f"{path} has a header but no rows")
    if memo is not None:
        memo[key] = (header, frame)
    return header, frame


#: Inside :func:`read_once`: each file's header and cells, by resolved path.
_ONCE: ContextVar[dict[Path, tuple[list[str], pd.DataFrame]] | None] = ContextVar(
    "workbench_csv_once", default=None)


@contextmanager
def read_once() -> Iterator[None]:
    """Read each CSV file once inside the block, however many times it is loaded.

    A command that loads one file several times (``workbench init``: the loader's checks,
    the columns it proposes, the config's own load) reads it from disk once: the first read
    keeps the file's header and cells (as text), the later ones reuse them. Inside the block
    the numbers come from the text cells (the loader's checked text path), as for any file
    its fast path cannot read; the file is not expected to change meanwhile.

    Yields
    ------
    None
        The block, during which files are read once.
    """
    token = _ONCE.set({})
    try:
        yield
    finally:
        _ONCE.reset(token)


def read_csv_cells(path: str | PathLike[str]) -> pd.DataFrame:
    """Read every cell of a CSV file as text, with the loader's checks and messages.

    Inside :func:`read_once`, the file is read once.

    Parameters
    ----------
    path : str or path-like
        The CSV file.

    Returns
    -------
    pandas.DataFrame
        One column per header name, every cell a string (empty cells ``""``).

    Raises
    ------
    DatasetError
        A missing, empty or malformed file, or one with a column name twice.
    """
    return _cells(Path(path), 1)[1]


def _read_numbers(path: Path, numeric: Sequence[str], text: Sequence[str]
                  ) -> tuple[pd.DataFrame, pd.DataFrame] | None:
    """The ``numeric`` columns as floats and the ``text`` columns as text, read by pandas'
    parser at once; ``None`` where that fails for any reason (a cell that is not a number,
    an empty cell, a ragged row, no rows): :func:`_read` and :func:`_numeric` then read the
    file as text and name what is wrong. A clean file takes a fraction of their time
    (30,000 rows: 0.05 s against 1.5 s)."""
    if set(numeric) & set(text):
        return None
    try:
        frame = pd.read_csv(path, usecols=[*numeric, *text], keep_default_na=False,
                            dtype={c: str for c in text})
    except Exception:  # noqa: BLE001 - any failure: the text path reads it and explains
        return None
    if frame.empty or any(frame[c].dtype != np.float64 for c in numeric):
        return None
    return frame[list(numeric)], frame[list(text)]


def _numeric(frame: pd.DataFrame, columns: Sequence[str], path: Path) -> pd.DataFrame:
    out = {}
    for col in columns:
        raw = frame[col].str.strip()
        values = pd.to_numeric(raw.replace({"": "nan"}), errors="coerce")
        bad = values.isna() & ~raw.str.lower().isin(["", "nan", "na", "null"])
        if bad.any():  # the cells are not quoted: the file's content stays out of messages
            raise DatasetError(f"{path}: column {col!r} has non-numeric values at "
                               f"{_rows(frame.index[bad])}")
        out[col] = values.astype(float)
    data = pd.DataFrame(out, index=frame.index)
    _check_values(data, columns, path)
    return data


def _check_values(data: pd.DataFrame, columns: Sequence[str], path: Path) -> None:
    """Every value finite and within +-MAX_MAGNITUDE, else an error naming columns and lines."""
    values = data.to_numpy()
    finite = np.isfinite(values)
    if not finite.all():
        bad_cols = [c for c, ok in zip(columns, finite.all(axis=0)) if not ok]
        bad_rows = data.index[~finite.all(axis=1)]
        raise DatasetError(f"{path}: missing, NaN or infinite values in column(s) "
                           f"[{_names(bad_cols)}] at {_rows(bad_rows)}")
    huge = np.abs(values) > MAX_MAGNITUDE
    if huge.any():
        bad_cols = [c for c, h in zip(columns, huge.any(axis=0)) if h]
        bad_rows = data.index[huge.any(axis=1)]
        raise DatasetError(f"{path}: column(s) [{_names(bad_cols)}] hold values beyond "
                           f"+-{MAX_MAGNITUDE:.0e} at {_rows(bad_rows)}: too large to fit or "
                           f"score (squares overflow); check the units")


def _split(frame: pd.DataFrame, path: Path, test_fraction: Any,
           split_column: str | None, split_seed: int,
           order: pd.Series | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The training and test rows; ``order``: the latest ``test_fraction`` are the test
    rows (``split="time"``)."""
    if (test_fraction is None) == (split_column is None):
        raise DatasetError("give exactly one of test_fraction or split_column")
    if order is not None:
        if split_column is not None:
            raise DatasetError("split = \"time\" takes the latest test_fraction of the rows, "
                               "not split_column")
        if not 0.0 < float(test_fraction) < 1.0:
            raise DatasetError(f"test_fraction must be in (0, 1), got {test_fraction!r}")
        train, test = latest_rows(order, float(test_fraction))
    elif split_column is not None:
        if split_column not in frame.columns:
            raise DatasetError(f"{path}: split column {split_column!r} is missing")
        values = frame[split_column].str.strip().str.lower()
        bad = ~values.isin(["train", "test"])
        if bad.any():
            raise DatasetError(f"{path}: split column {split_column!r} must hold 'train' or "
                               f"'test'; other values at {_rows(frame.index[bad])}")
        train, test = frame.index[values == "train"], frame.index[values == "test"]
    else:
        if not 0.0 <= float(test_fraction) < 1.0:
            raise DatasetError(f"test_fraction must be in [0, 1), got {test_fraction!r}")
        order = np.random.default_rng(split_seed).permutation(len(frame))
        n_test = int(round(len(frame) * float(test_fraction)))
        test, train = np.sort(frame.index[order[:n_test]]), np.sort(frame.index[order[n_test:]])
    if len(test) == 0:
        raise DatasetError(f"{path}: the test split is empty ({len(frame)} rows; "
                           f"test_fraction={test_fraction}, split_column={split_column!r})")
    if len(train) == 0:
        raise DatasetError(f"{path}: the training split is empty")
    return np.asarray(train), np.asarray(test)


def read_numeric_columns(path: str | Path, pattern: str, *,
                         min_columns: int = 2) -> pd.DataFrame:
    """The columns of a CSV file whose names match ``pattern``, as numbers.

    The file gets the checks of every data file (exists, UTF-8, a header of at least
    ``min_columns`` names, no duplicated names, well formed, not empty), then the matching
    columns are read as finite numbers.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    pattern : str
        A regular expression a column's whole name must match.
    min_columns : int, default=2
        Fewer names in the header is an error (another delimiter, or not a CSV).

    Returns
    -------
    DataFrame
        The matching columns, in the file's order, as floats (possibly none).

    Raises
    ------
    DatasetError
        Naming the file, the column and the lines of what is wrong.
    """
    path = Path(path)
    frame = _read(path, min_columns=min_columns)
    columns = [c for c in frame.columns if re.fullmatch(pattern, c)]
    return _numeric(frame, columns, path)


def load_csv_dataset(path: str | Path, *, prior: Sequence[str], targets: Sequence[str],
                     features: Sequence[str] = (), test_fraction: float | None = None,
                     split_column: str | None = None, split_seed: int = 0,
                     onsite: Sequence[str] | None = None, couplings: Sequence[str] | None = None,
                     sign: int = -1, qubit_features: Sequence[str] | None = None,
                     coupler_features: Sequence[str] | None = None,
                     topology: str = "chain", shape: Sequence[int] | None = None,
                     edges: Sequence[Sequence[int]] | None = None,
                     group_column: str | None = None, name: str | None = None,
                     unit: str | None = None, order_column: str | None = None,
                     split: str | None = None, prior_label: str = "prior") -> Dataset:
    """Read a CSV of experiments into a :class:`Dataset`.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    prior : sequence of str
        The prior columns, ``prior[j]`` predicting ``targets[j]`` (empty: the family's own).
    targets : sequence of str
        The target columns.
    features : sequence of str, default=()
        The input columns.
    test_fraction : float, default=None
        A seeded random share of the rows held out (or ``split_column``).
    split_column : str, default=None
        A column holding ``train`` or ``test`` per row.
    split_seed : int, default=0
        Seeds the ``test_fraction`` split.
    onsite, couplings : sequence of str, default=None
        The control model's Hamiltonian per row: N diagonal columns, one coupling column per
        edge of the coupling graph (its prior is the ascending eigenvalues of ``sign * H``).
    sign : {-1, 1}, default=-1
        The sign of ``H``.
    qubit_features, coupler_features : sequence of str, default=None
        Columns among ``features`` that act on each site (N) and coupling (one per edge),
        e.g. bias voltages.
    topology : {"chain", "ring", "grid"}, default="chain"
        The coupling graph ("chain": N - 1 couplings ``(i, i+1)``; see
        :class:`~workbench.hamiltonian.CouplingGraph`).
    shape, edges : default=None
        ``(rows, cols)`` of a grid; an explicit list of 0-based site pairs instead, one per
        coupling column.
    group_column : str, default=None
        Each row's group (e.g. its device): the dataset's ``groups``, which CV folds keep whole.
    name : str, default=None
        The dataset's name (``None``: the file's stem).
    unit, prior_label : str, default=None, "prior"
        The targets' unit (e.g. ``"meV"``; ``None``: none) and the prior's name, as shown.
    order_column : str, default=None
        Each row's place in time, dates (``2024-03-01``, ``2024-03-01T09:30:00Z``; no zone:
        UTC) or numbers (run numbers): the dataset's ``order``, which CV folds follow.
    split : {"time"}, default=None
        ``"time"``: the test rows are the latest ``test_fraction`` by ``order_column``.

    Returns
    -------
    Dataset
        The data and their split.

    Raises
    ------
    DatasetError
        Unusable data, in one line naming the file and what is wrong.
    """
    path = Path(path)
    _check_time_split(split, order_column)
    prior, targets, features = list(prior), list(targets), list(features)
    _check_roles(prior, targets)
    graph = _graph(onsite, couplings, topology, shape, edges)
    if sign not in (-1, 1):
        raise DatasetError(f"sign must be -1 or 1, got {sign!r}")
    _check_site_features(onsite, couplings, qubit_features, coupler_features, features)
    ham_cols = [*(onsite or []), *(couplings or [])]
    used = list(dict.fromkeys([*features, *prior, *targets, *ham_cols]))
    named_twice = sorted(c for c, n in Counter([*features, *prior, *targets]).items() if n > 1)
    if named_twice:
        raise DatasetError(f"column(s) {named_twice} named in more than one role")

    data, frame = _read_columns(path, used, [split_column, group_column, order_column])
    order = None if order_column is None else _order(frame, order_column, path)
    train, test = _split(frame, path, test_fraction, split_column, split_seed,
                         order if split else None)
    hamiltonian = None if onsite is None else _hamiltonian(
        data, onsite, couplings, sign, qubit_features, coupler_features, graph)
    groups = None if group_column is None else _groups(frame, group_column, used, path)
    return Dataset(name=name or path.stem, features=data[features], prior=data[prior],
                   targets=data[targets], train_index=train, test_index=test,
                   hamiltonian=hamiltonian, groups=groups, unit=unit, order=order,
                   prior_label=prior_label)


def _hamiltonian(data: pd.DataFrame, onsite: Sequence[str], couplings: Sequence[str] | None,
                 sign: int, qubit_features: Sequence[str] | None,
                 coupler_features: Sequence[str] | None,
                 graph: CouplingGraph | None) -> Hamiltonian:
    """The rows' Hamiltonian from their onsite and coupling columns (checked by _graph)."""
    assert couplings is not None and graph is not None  # both set with onsite (_graph)
    return Hamiltonian(
        onsite=data[list(onsite)], couplings=data[list(couplings)], sign=int(sign),
        qubit_features=tuple(qubit_features) if qubit_features is not None else None,
        coupler_features=tuple(coupler_features) if coupler_features is not None else None,
        edges=None if graph.topology == "chain" else graph.edges)


def _graph(onsite: Sequence[str] | None, couplings: Sequence[str] | None, topology: str,
           shape: Sequence[int] | None,
           edges: Sequence[Sequence[int]] | None) -> CouplingGraph | None:
    """Check the Hamiltonian's columns against its coupling graph; return the graph."""
    if (onsite is None) != (couplings is None):
        raise DatasetError("give both onsite and couplings columns for the Hamiltonian, or neither")
    if onsite is None:
        if edges is not None or shape is not None or topology != "chain":
            raise DatasetError("topology, shape and edges need the Hamiltonian's onsite and "
                               "couplings columns")
        return None
    assert couplings is not None  # both or neither, checked above
    if len(onsite) < 2:
        raise DatasetError(f"the Hamiltonian needs at least 2 onsite columns, got "
                           f"{list(onsite)}")
    try:
        graph = make_graph(len(onsite), topology, None if shape is None else tuple(shape),
                           edges)
    except (ValueError, TypeError) as exc:
        raise DatasetError(f"hamiltonian graph: {exc}") from None
    if len(couplings) != graph.n_edges:
        what = "edges" if edges is not None else f"{graph.topology}"
        raise DatasetError(f"a {what} of {len(onsite)} sites has {graph.n_edges} "
                           f"couplings, got {len(couplings)}: {list(couplings)}")
    return graph


def _check_site_features(onsite: Sequence[str] | None, couplings: Sequence[str] | None,
                         qubit_features: Sequence[str] | None,
                         coupler_features: Sequence[str] | None,
                         features: list[str]) -> None:
    """Check the features named per site and per coupling: one each, among ``features``."""
    for what, names, size in (("qubit_features", qubit_features, len(onsite or [])),
                              ("coupler_features", coupler_features, len(couplings or []))):
        if names is None:
            continue
        if onsite is None:
            raise DatasetError(f"{what} needs the Hamiltonian's onsite and couplings columns")
        if len(names) != size:
            raise DatasetError(f"{what} needs {size} column(s), one per "
                               f"{'site' if what == 'qubit_features' else 'coupling'}, got "
                               f"{len(names)}: {list(names)}")
        outside = [c for c in names if c not in features]
        if outside:
            raise DatasetError(f"{what} {outside} must be among the features {features}")


def _read_columns(path: Path, used: list[str],
                  text_columns: list[str | None]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Read the ``used`` columns as checked numbers, and the file's frame for the text ones.

    Every named column must be in the header; ``text_columns`` (``None`` entries: not
    given) are the split and group columns, read as text.
    """
    once = _ONCE.get() is not None
    # a prior and a target at least
    header = _cells(path, 2)[0] if once else _header(path, min_columns=2)
    text = list(dict.fromkeys(c for c in text_columns if c))
    missing = [c for c in [*used, *text] if c not in header]
    if missing:
        has = (f"the file has columns [{_names(header)}]" if _is_header(header) else
               "the file's first line does not look like a CSV header")
        raise DatasetError(f"{path}: missing column(s) [{_names(missing)}]; {has}")
    fast = None if once else _read_numbers(path, used, text)
    if fast is None:
        frame = _read(path, min_columns=2)
        return _numeric(frame, used, path), frame
    data, frame = fast
    _check_values(data, used, path)
    return data, frame


def _groups(frame: pd.DataFrame, group_column: str, used: list[str], path: Path) -> pd.Series:
    """Read each row's group from ``group_column`` (text, none empty)."""
    if group_column in used:
        raise DatasetError(f"group column {group_column!r} is also named as a prior, "
                           f"target, feature or Hamiltonian column")
    groups = frame[group_column].str.strip()
    empty = groups == ""
    if empty.any():
        raise DatasetError(f"{path}: group column {group_column!r} is empty at "
                           f"{_rows(frame.index[empty])}")
    return groups


def _check_roles(prior: list[str], targets: list[str]) -> None:
    """Check the prior and target columns: some targets, one prior column each (or none:
    the model family supplies the prior)."""
    if not targets:
        raise DatasetError("no target columns given")
    if prior and len(prior) != len(targets):
        raise DatasetError(f"{len(prior)} prior column(s) {prior} for {len(targets)} target(s) "
                           f"{targets}: give one prior column per target, in the same order")


def _check_time_split(split: str | None, order_column: str | None) -> None:
    """Check a CSV's ``split``: ``"time"`` (with an order column) or none."""
    if split not in (None, "time"):
        raise DatasetError(f"split must be \"time\" or not given for a CSV, got {split!r}")
    if split == "time" and order_column is None:
        raise DatasetError("split = \"time\" needs an order_column (the rows' dates, times "
                           "or run numbers)")


def _order(frame: pd.DataFrame, order_column: str, path: Path) -> pd.Series:
    """Read each row's order value from ``order_column`` (numbers, else dates)."""
    try:
        return order_values(frame[order_column])
    except BadOrderValues as exc:
        what = ("is empty or NaN" if exc.what == "missing" else
                "holds values that are neither numbers nor dates (e.g. 2024-03-01)")
        raise DatasetError(f"{path}: order column {order_column!r} {what} at "
                           f"{_rows(frame.index[exc.rows])}") from None
