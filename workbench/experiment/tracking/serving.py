"""The logged model: an MLflow pyfunc ``PythonModel`` that checks its input table by name.

It returns a table of predictions (and prediction intervals when the fitted model has
them). Used three ways, all with the same numbers:

* ``workbench predict MODEL DATA.csv --out predictions.csv`` (:mod:`.predict`);
* ``mlflow.pyfunc.load_model(uri).predict(frame)`` in Python;
* ``mlflow models serve -m <uri> --env-manager local`` (REST, ``dataframe_split``).

Inputs are checked by the model itself, so each problem is one short line naming the column
(and the row): no rows at all, a missing column, a non-numeric value, a NaN or infinite
value. Integer columns are accepted (cast to float); extra columns are ignored. The
signature therefore declares the input columns by name without MLflow types (``Any``,
optional): MLflow's own enforcement would reject ``int64`` columns and report a missing
column after a dump of the whole table. The outputs are declared as doubles: one column per
target, then ``<target>_lower`` and ``<target>_upper`` per target when the fitted model has
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

from ..process.errors import shorten

__all__ = ["InputError", "WorkbenchModel", "check_inputs", "has_intervals",
           "interval_columns", "model_signature", "prediction_frame"]

LOWER, UPPER = "_lower", "_upper"


class InputError(ValueError):
    """An input table the model cannot use; the message is one line naming the column."""


def _default_row(labels: Any) -> Callable[[int], str]:
    """Name a row as ``row <index label>`` (a text label quoted), by position."""
    values = list(labels.tolist() if hasattr(labels, "tolist") else labels)
    return lambda pos: (f"row {values[pos]!r}" if isinstance(values[pos], str)
                        else f"row {values[pos]}")


def _as_float(value: object) -> float:
    """Read one cell as a float (exact for numbers and for decimal text).

    An empty cell or ``None`` is NaN (reported as missing); anything else that is not a number
    raises ``ValueError``.
    """
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
    """Check the model's input columns of ``frame`` and return them as floats.

    Extra columns are ignored, integer columns cast to float.

    Parameters
    ----------
    frame : DataFrame
        The input table (anything ``pd.DataFrame`` accepts).
    columns : sequence of str
        The columns the model reads, in its order.
    where : str, default="input"
        What the messages start with.
    row_name : callable, default=None
        Names a row by position in messages; ``None``: ``row <index label>``.

    Returns
    -------
    DataFrame
        ``columns`` of ``frame`` as floats, same index.

    Raises
    ------
    InputError
        One line, naming the column and the row: no rows, duplicated or missing columns, a
        non-numeric value, or a missing, NaN or infinite value.
    """
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
    """Name the interval columns of ``targets``.

    Parameters
    ----------
    targets : sequence of str
        The predicted targets.

    Returns
    -------
    list of str
        ``<target>_lower``, ``<target>_upper`` for each target, in target order.
    """
    return [f"{t}{s}" for t in targets for s in (LOWER, UPPER)]


def _intervals(raw: Any, targets: list[str], index: pd.Index) -> pd.DataFrame:
    """Turn ``predict_interval``'s result into a frame of :func:`interval_columns`."""
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


def prediction_frame(model: Any, X: pd.DataFrame, targets: Sequence[str]) -> pd.DataFrame:
    """Predict ``X`` with ``model`` as a frame indexed like ``X``.

    Parameters
    ----------
    model : fitted estimator
        ``predict(X)`` gives one column per target; optionally ``predict_interval(X)``.
    X : DataFrame
        Inputs already through :func:`check_inputs`.
    targets : sequence of str
        The targets, in the order of ``model.predict``'s columns.

    Returns
    -------
    DataFrame
        One column per target, then :func:`interval_columns` when ``model`` has
        ``predict_interval``.

    Raises
    ------
    TypeError
        ``predict_interval`` returned a shape it cannot be read from.
    """
    targets = [str(t) for t in targets]
    pred = model.predict(X)
    if isinstance(pred, pd.DataFrame) and set(targets) <= set(map(str, pred.columns)):
        pred = pred.set_axis(list(map(str, pred.columns)), axis=1)[targets]
    values = np.asarray(pred, dtype=float).reshape(len(X), len(targets))
    out = pd.DataFrame(values, index=X.index, columns=targets)
    if callable(getattr(model, "predict_interval", None)):
        out = pd.concat([out, _intervals(model.predict_interval(X), targets, X.index)], axis=1)
    return out


def has_intervals(model: object) -> bool:
    """Tell whether ``model`` predicts intervals (has a callable ``predict_interval``).

    Parameters
    ----------
    model : object
        A fitted model.

    Returns
    -------
    bool
        Whether it has ``predict_interval``.
    """
    return callable(getattr(model, "predict_interval", None))


def model_signature(columns: Sequence[str], outputs: Sequence[str]) -> ModelSignature:
    """Build the logged model's MLflow signature.

    Parameters
    ----------
    columns : sequence of str
        Input columns, declared by name with type ``Any`` and optional: the model checks them
        itself (see the module docstring).
    outputs : sequence of str
        Output columns, declared as doubles.

    Returns
    -------
    mlflow.models.ModelSignature
        The inputs and outputs.
    """
    return ModelSignature(
        inputs=Schema([ColSpec(AnyType(), str(c), required=False) for c in columns]),
        outputs=Schema([ColSpec(DataType.double, str(c)) for c in outputs]))


class WorkbenchModel(PythonModel):
    """A fitted workbench model as an MLflow pyfunc model.

    It checks the input table (:func:`check_inputs`) and returns :func:`prediction_frame`.

    Parameters
    ----------
    model : fitted estimator
        ``predict(X)`` -> one column per target; optionally ``predict_interval(X)``.
    columns : list of str
        The input columns ``model`` reads, in its order.
    targets : list of str
        The predicted targets, in the order of ``model.predict``'s columns.
    """

    def __init__(self, model: Any, columns: Sequence[str], targets: Sequence[str]) -> None:
        self.model = model
        self.columns = [str(c) for c in columns]
        self.targets = [str(t) for t in targets]

    @property
    def outputs(self) -> list[str]:
        """Name the output columns.

        Returns
        -------
        list of str
            The targets, then the interval columns if the model has them.
        """
        extra = interval_columns(self.targets) if has_intervals(self.model) else []
        return self.targets + extra

    def predict_checked(self, X: pd.DataFrame) -> pd.DataFrame:
        """Predict a frame already through :func:`check_inputs`.

        Parameters
        ----------
        X : DataFrame
            The checked inputs.

        Returns
        -------
        DataFrame
            :func:`prediction_frame` of the model.
        """
        return prediction_frame(self.model, X, self.targets)

    # A DataFrame type hint: MLflow neither infers a schema from it nor warns about a missing
    # hint; the logged signature names the inputs.
    def predict(self, context: Any, model_input: pd.DataFrame,
                params: dict[str, Any] | None = None) -> pd.DataFrame:
        """Check ``model_input`` and predict it (MLflow's pyfunc entry point).

        Parameters
        ----------
        context : PythonModelContext or None
            MLflow's context (unused).
        model_input : DataFrame
            The input table.
        params : dict, default=None
            MLflow's inference parameters (unused).

        Returns
        -------
        DataFrame
            :func:`prediction_frame` of the model.

        Raises
        ------
        mlflow.exceptions.MlflowException
            An input table the model cannot use (its message is :class:`InputError`'s line).
        """
        try:
            X = check_inputs(model_input, self.columns, where="model input")
        except InputError as exc:
            raise MlflowException.invalid_parameter_value(str(exc)) from None
        return self.predict_checked(X)
