"""The logged model: an MLflow pyfunc ``PythonModel`` that checks its input table by column
name and returns a table of predictions (and prediction intervals when the fitted model has
them).

Used three ways, all with the same numbers:

* ``workbench predict MODEL DATA.csv --out predictions.csv`` (:mod:`.predict`);
* ``mlflow.pyfunc.load_model(uri).predict(frame)`` in Python;
* ``mlflow models serve -m <uri> --env-manager local`` (REST, ``dataframe_split``).

Inputs are checked by the model itself, so each problem is one short line naming the column
(and the row): no rows at all, a missing column, a non-numeric value, a NaN or infinite
value. Integer
columns are accepted (cast to float); extra columns are ignored. The signature therefore
declares the input columns by name without MLflow types (``Any``, optional): MLflow's own
enforcement would reject ``int64`` columns and report a missing column after a dump of the
whole table. The outputs are declared as doubles: one column per target, then
``<target>_lower`` and ``<target>_upper`` per target when the fitted model has
``predict_interval``.

``predict_interval(X)`` is duck-typed; it may return a DataFrame with ``<target>_lower`` /
``<target>_upper`` columns, a pair ``(lower, upper)`` of arrays or frames of shape
``(n_rows, n_targets)``, or an array of shape ``(n_rows, n_targets, 2)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd
from mlflow.exceptions import MlflowException
from mlflow.models import ModelSignature
from mlflow.pyfunc import PythonModel  # not mlflow.pyfunc.PythonModel: mypy sees a LazyLoader
from mlflow.types import DataType
from mlflow.types.schema import AnyType, ColSpec, Schema

from .errors import shorten

__all__ = ["InputError", "WorkbenchModel", "check_inputs", "has_intervals",
           "interval_columns", "model_signature", "prediction_frame"]

LOWER, UPPER = "_lower", "_upper"


class InputError(ValueError):
    """An input table the model cannot use; the message is one line naming the column."""


def _default_row(labels) -> Callable[[int], str]:
    """``row <index label>`` (a text label quoted)."""
    values = list(labels.tolist() if hasattr(labels, "tolist") else labels)
    return lambda pos: (f"row {values[pos]!r}" if isinstance(values[pos], str)
                        else f"row {values[pos]}")


def _as_float(value) -> float:
    """One cell as a float (exact for numbers and for decimal text); ``ValueError`` if it is
    not a number. An empty cell or ``None`` is NaN (reported as missing)."""
    if value is None:
        return math.nan
    if isinstance(value, (bool, np.bool_)):
        raise ValueError("a boolean")
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    if isinstance(value, str):
        text = value.strip()
        return math.nan if text == "" else float(text)
    raise ValueError(type(value).__name__)


def check_inputs(frame: pd.DataFrame, columns: Sequence[str], *, where: str = "input",
                 row_name: Callable[[int], str] | None = None) -> pd.DataFrame:
    """The model's input ``columns`` of ``frame`` as a float frame (same index, the model's
    column order); extra columns are ignored, integer columns cast to float.

    Raises :class:`InputError` (one line, starting with ``where``) for a table without rows,
    missing columns, a non-numeric value, or a missing, NaN or infinite value, naming the
    column and the row (``row_name(position)``, default ``row <index label>``)."""
    if not isinstance(frame, pd.DataFrame):
        frame = pd.DataFrame(frame)
    if len(frame) == 0:  # the estimators' own message is a traceback's worth of text
        raise InputError(f"{where}: no rows to predict")
    columns = [str(c) for c in columns]
    names = [str(c) for c in frame.columns]
    dups = sorted({c for c in names if names.count(c) > 1} & set(columns))
    if dups:
        raise InputError(f"{where}: duplicated column(s) {dups}")
    missing = [c for c in columns if c not in names]
    if missing:
        raise InputError(f"{where}: missing column(s) {_listing(missing)} (the model reads "
                         f"{len(columns)} columns: {_listing(columns)})")
    frame = frame.set_axis(names, axis=1)
    row_name = row_name or _default_row(frame.index)
    out = {}
    for col in columns:
        values = frame[col]
        if values.dtype.kind in "iuf":
            out[col] = values.to_numpy(dtype=float)
            continue
        floats = np.empty(len(values))
        for pos, cell in enumerate(values.tolist()):
            try:
                floats[pos] = _as_float(cell)
            except (TypeError, ValueError):
                raise InputError(f"{where}: column {col!r} has a non-numeric value "
                                 f"{shorten(cell, 40)} at {row_name(pos)}") from None
        out[col] = floats
    X = pd.DataFrame(out, index=frame.index, columns=columns)
    finite = np.isfinite(X.to_numpy())
    if not finite.all():
        pos, j = (int(a[0]) for a in np.nonzero(~finite))
        value = X.iat[pos, j]
        what = "a missing or NaN value" if np.isnan(value) else f"an infinite value ({value})"
        more = int((~finite).sum()) - 1
        raise InputError(f"{where}: column {columns[j]!r} has {what} at {row_name(pos)}"
                         + (f" ({more} more such cells)" if more else ""))
    return X


def _listing(names: Sequence[str], limit: int = 8) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names) - limit} more)" if len(names) > limit else "")


def interval_columns(targets: Sequence[str]) -> list[str]:
    """``<target>_lower``, ``<target>_upper`` for each target, in target order."""
    return [f"{t}{s}" for t in targets for s in (LOWER, UPPER)]


def _intervals(raw, targets: list[str], index) -> pd.DataFrame:
    """``predict_interval``'s result as a frame of :func:`interval_columns`."""
    n, k = len(index), len(targets)
    wanted = interval_columns(targets)
    if isinstance(raw, pd.DataFrame) and set(wanted) <= set(map(str, raw.columns)):
        values = raw.set_axis(list(map(str, raw.columns)), axis=1)[wanted].to_numpy(float)
        return pd.DataFrame(values, index=index, columns=wanted)
    if isinstance(raw, (tuple, list)) and len(raw) == 2:
        lower, upper = (np.asarray(part, dtype=float).reshape(n, k) for part in raw)
    else:
        arr = np.asarray(raw, dtype=float)
        if arr.shape == (n, k, 2):
            lower, upper = arr[..., 0], arr[..., 1]
        elif k == 1 and arr.shape == (n, 2):
            lower, upper = arr[:, :1], arr[:, 1:]
        else:
            raise TypeError(f"predict_interval returned {type(raw).__name__} of shape "
                            f"{getattr(arr, 'shape', None)}; expected (lower, upper) of shape "
                            f"({n}, {k}), an array ({n}, {k}, 2) or a frame with {wanted[:2]}...")
    values = np.empty((n, 2 * k))
    values[:, 0::2], values[:, 1::2] = lower, upper
    return pd.DataFrame(values, index=index, columns=wanted)


def prediction_frame(model, X: pd.DataFrame, targets: Sequence[str]) -> pd.DataFrame:
    """``model``'s predictions on ``X`` (already checked) as a frame indexed like ``X``: one
    column per target, then :func:`interval_columns` when ``model`` has
    ``predict_interval``."""
    targets = [str(t) for t in targets]
    pred = model.predict(X)
    if isinstance(pred, pd.DataFrame) and set(targets) <= set(map(str, pred.columns)):
        pred = pred.set_axis(list(map(str, pred.columns)), axis=1)[targets]
    values = np.asarray(pred, dtype=float).reshape(len(X), len(targets))
    out = pd.DataFrame(values, index=X.index, columns=targets)
    if callable(getattr(model, "predict_interval", None)):
        out = pd.concat([out, _intervals(model.predict_interval(X), targets, X.index)], axis=1)
    return out


def has_intervals(model) -> bool:
    return callable(getattr(model, "predict_interval", None))


def model_signature(columns: Sequence[str], outputs: Sequence[str]):
    """Inputs by name (type ``Any``, optional: the model checks them itself, see the module
    docstring), outputs as doubles."""
    return ModelSignature(
        inputs=Schema([ColSpec(AnyType(), str(c), required=False) for c in columns]),
        outputs=Schema([ColSpec(DataType.double, str(c)) for c in outputs]))


class WorkbenchModel(PythonModel):
    """A fitted workbench model as an MLflow pyfunc model: checks the input table
    (:func:`check_inputs`) and returns :func:`prediction_frame`.

    Parameters
    ----------
    model : fitted estimator
        ``predict(X)`` -> one column per target; optionally ``predict_interval(X)``.
    columns : list of str
        The input columns ``model`` reads, in its order.
    targets : list of str
        The predicted targets, in the order of ``model.predict``'s columns.
    """

    def __init__(self, model, columns: Sequence[str], targets: Sequence[str]):
        self.model = model
        self.columns = [str(c) for c in columns]
        self.targets = [str(t) for t in targets]

    @property
    def outputs(self) -> list[str]:
        """The output columns: the targets, then the interval columns if any."""
        extra = interval_columns(self.targets) if has_intervals(self.model) else []
        return self.targets + extra

    def predict_checked(self, X: pd.DataFrame) -> pd.DataFrame:
        """Predictions for a frame already through :func:`check_inputs`."""
        return prediction_frame(self.model, X, self.targets)

    # A DataFrame type hint: MLflow neither infers a schema from it nor warns about a missing
    # hint; the logged signature names the inputs.
    def predict(self, context, model_input: pd.DataFrame,
                params: dict[str, Any] | None = None) -> pd.DataFrame:
        try:
            X = check_inputs(model_input, self.columns, where="model input")
        except InputError as exc:
            raise MlflowException.invalid_parameter_value(str(exc)) from None
        return self.predict_checked(X)
