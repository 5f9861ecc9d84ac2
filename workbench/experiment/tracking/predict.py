"""Apply a logged or registered model to new settings (``workbench predict``).

``workbench predict MODEL DATA.csv --out predictions.csv``. ``MODEL`` is a run id (the
run's model), ``runs:/<run_id>/<name>``, ``models:/<model_id>``, ``models:/NAME/VERSION``,
``models:/NAME@ALIAS`` (e.g. ``models:/device@champion``) or the path of a model directory.
Names are looked up in the tracking store given like the other commands'
(``--tracking-uri``, then ``$MLFLOW_TRACKING_URI``, then ``sqlite:///mlruns/mlflow.db``);
the store is never created or changed.

Order of work: the output location is checked, the CSV is read, the model is found and
loaded, the CSV's columns are checked by name against the model's inputs (missing columns, a
non-numeric value, a missing/NaN/infinite value: one line naming the column and the line of
the file), then the model predicts and the output is written atomically. The output holds
the input's columns that the model does not read (an id column stays with its row; their
text is copied unchanged), then one column per target, then ``<target>_lower`` /
``<target>_upper`` when the model has prediction intervals. An input column whose name is an
output column is passed through as ``<name>_input``.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import mlflow.pyfunc
import pandas as pd
from mlflow.exceptions import MlflowException

from ..._text import clip
from ...datasets.csv import _read
from ..process.errors import UsageError
from ..process.outputs import check_file, write_file
from .runs import Tracker
from .serving import InputError, check_inputs
from .uris import describe_store, sqlite_path

if TYPE_CHECKING:
    from mlflow import MlflowClient
    from mlflow.entities import Run
    from mlflow.pyfunc import PyFuncModel

__all__ = ["Prediction", "load_predictor", "predict_csv", "resolve_model"]

log = logging.getLogger("workbench")

_RUN_ID = re.compile(r"^[0-9a-f]{32}$")
_NOT_FOUND = ("RESOURCE_DOES_NOT_EXIST", "NOT_FOUND", "INVALID_PARAMETER_VALUE")


@dataclass
class Prediction:
    """What :func:`predict_csv` wrote.

    Parameters
    ----------
    path : Path
        The output file.
    rows : int
        Rows predicted.
    targets : list of str
        The predicted targets.
    intervals : bool
        Whether interval columns were written.
    model : str
        The model as given.
    """

    path: Path
    rows: int
    targets: list[str]
    intervals: bool
    model: str


def _short(exc: BaseException) -> str:
    """Return the first line of an error's message, at most 200 characters."""
    text = str(getattr(exc, "message", None) or exc).strip().splitlines()
    line = text[0] if text else type(exc).__name__
    return clip(line, 200)


def resolve_model(spec: str, tracking_uri: str) -> str:
    """Find the location ``mlflow.pyfunc.load_model`` can read for ``spec``.

    Parameters
    ----------
    spec : str
        The model as given (see the module docstring).
    tracking_uri : str
        The tracking store names are looked up in.

    Returns
    -------
    str
        A model directory or artifact location.

    Raises
    ------
    UsageError
        One line, when ``spec`` names nothing (or the store does not exist).
    """
    if Path(spec).is_dir():
        return str(Path(spec).resolve())
    if not (_RUN_ID.match(spec) or spec.startswith(("runs:/", "models:/"))):
        raise UsageError(f"model {spec!r}: expected a run id, runs:/<run_id>/<name>, "
                         "models:/NAME/VERSION, models:/NAME@ALIAS, models:/<model_id> or "
                         "a model directory")

    db = sqlite_path(tracking_uri)
    if db is not None and not db.is_file():
        raise UsageError(f"model {spec!r}: no MLflow store at {db} (give --tracking-uri or "
                         "set MLFLOW_TRACKING_URI)")
    tracker = Tracker(tracking_uri, "Default")
    client = tracker.client
    where = describe_store(tracking_uri)
    try:
        with tracker._errors():
            model_id = _model_id(client, spec)
            if isinstance(model_id, _Location):
                return str(model_id)
            if model_id is None:  # a run's own artifact directory
                run_id, _, path = spec.removeprefix("runs:/").partition("/")
                return client.get_run(run_id).info.artifact_uri.rstrip("/") + "/" + path
            return client.get_logged_model(model_id).artifact_location
    except MlflowException as exc:
        if exc.error_code in _NOT_FOUND:
            raise UsageError(f"model {spec!r} not found in {where}: {_short(exc)}") from None
        raise


class _Location(str):
    """A model's artifact location (not a logged model's id)."""


def _model_id(client: MlflowClient, spec: str) -> str | None:
    """Look up the logged model's id for ``spec``.

    ``None``: ``runs:/`` naming a run artifact; a :class:`_Location`: a registered version's
    artifact location.
    """
    if _RUN_ID.match(spec):
        run = client.get_run(spec)
        tagged = run.data.tags.get("model_uri", "")
        if tagged.startswith("models:/"):
            return tagged.removeprefix("models:/")
        return _run_model(client, run, None, spec)
    if spec.startswith("runs:/"):
        run_id, _, name = spec.removeprefix("runs:/").partition("/")
        run = client.get_run(run_id)
        if not _logged_models(client, run, name):
            return None  # a model saved among the run's own artifacts
        return _run_model(client, run, name, spec)
    rest = spec.removeprefix("models:/")
    if "@" in rest:
        name, alias = rest.split("@", 1)
        version = client.get_model_version_by_alias(name, alias)
    elif "/" in rest:
        name, number = rest.rsplit("/", 1)
        version = client.get_model_version(name, number)
    else:
        return rest  # models:/<model_id>
    if version.model_id:
        return version.model_id
    source = str(version.source)
    if source.startswith("models:/"):
        return source.removeprefix("models:/").split("/")[0]
    if source.startswith("runs:/"):
        return _model_id(client, source)
    return _Location(source)  # the version's own artifact location


def _logged_models(client: MlflowClient, run: Run, name: str | None) -> list:
    return [m for m in client.search_logged_models(
        experiment_ids=[run.info.experiment_id],
        filter_string=f"source_run_id = '{run.info.run_id}'") if name is None or m.name == name]


def _run_model(client: MlflowClient, run: Run, name: str | None, spec: str) -> str:
    run_id = run.info.run_id
    found = _logged_models(client, run, name)
    if len(found) != 1:
        what = "no logged model" if not found else f"{len(found)} logged models"
        raise UsageError(f"model {spec!r}: run {run_id} has {what}"
                         + (f" named {name!r}" if name else "")
                         + ("; name one with models:/<model_id>" if found else ""))
    return found[0].model_id


class _Predictor:
    """A loaded model: its input columns, targets and a ``predict(checked frame)``."""

    def __init__(self, pyfunc: PyFuncModel, spec: str) -> None:
        self.spec = spec
        impl = None
        try:
            impl = pyfunc.unwrap_python_model()
        except Exception:  # not a PythonModel
            pass
        if impl is not None and hasattr(impl, "predict_checked") and hasattr(impl, "columns"):
            self.columns, self.targets = list(impl.columns), list(impl.targets)
            self.outputs = list(impl.outputs)
            self._predict = impl.predict_checked
        else:  # another pyfunc model: its typed signature names the columns
            schema = pyfunc.metadata.get_input_schema()
            if schema is None or not schema.has_input_names():
                raise UsageError(f"model {spec!r} has no signature naming its input columns")
            self.columns = list(schema.input_names())
            out = pyfunc.metadata.get_output_schema()
            self.targets = list(out.input_names()) if out is not None else []
            self.outputs = list(self.targets)
            self._predict = lambda X: pd.DataFrame(pyfunc.predict(X), index=X.index)

    def predict(self, X: pd.DataFrame) -> pd.DataFrame:
        out = self._predict(X)
        if isinstance(out, pd.DataFrame) and not self.targets:
            self.targets = self.outputs = [str(c) for c in out.columns]
        return out


def load_predictor(spec: str, tracking_uri: str) -> _Predictor:
    """Resolve and load the model ``spec``.

    Parameters
    ----------
    spec : str
        The model as given (see the module docstring).
    tracking_uri : str
        The tracking store names are looked up in.

    Returns
    -------
    _Predictor
        The loaded model with its input columns and targets.

    Raises
    ------
    UsageError
        One line, when the model is not found or cannot be loaded.
    """
    location = resolve_model(spec, tracking_uri)
    try:
        pyfunc = mlflow.pyfunc.load_model(location)
    except (MlflowException, OSError) as exc:
        raise UsageError(f"cannot load model {spec!r} from {location}: {_short(exc)}") from None
    return _Predictor(pyfunc, spec)


def _read_csv(path: Path) -> pd.DataFrame:
    return _read(path)  # every cell as text: a passed-through id keeps its exact form


def predict_csv(spec: str, data: str | Path, out: str | Path, *,
                tracking_uri: str) -> Prediction:
    """Predict the rows of the CSV ``data`` with the model ``spec`` and write ``out``.

    Parameters
    ----------
    spec : str
        The model (see the module docstring).
    data : str or Path
        The CSV of settings, one row per experiment.
    out : str or Path
        The CSV to write (atomically).
    tracking_uri : str
        The tracking store names are looked up in.

    Returns
    -------
    Prediction
        What was written.

    Raises
    ------
    UsageError
        One line: an unwritable ``out``, a model not found, or an input column missing or
        not numeric (naming the column and the file's line).
    """
    check_file(out, "--out")
    data = Path(data)
    frame = _read_csv(data)
    predictor = load_predictor(spec, tracking_uri)
    try:
        X = check_inputs(frame, predictor.columns, where=str(data),
                         row_name=lambda pos: f"line {pos + 2}")
    except InputError as exc:
        raise UsageError(str(exc)) from None
    log.info("predicting %d rows of %s with %s", len(X), data, spec)
    pred = predictor.predict(X)
    keep = [c for c in frame.columns if c not in set(predictor.columns)]
    passed = frame[keep].rename(columns={c: f"{c}_input" for c in keep if c in set(pred.columns)})
    table = pd.concat([passed, pred], axis=1)
    write_file(out, table.to_csv(index=False), "--out")
    intervals = len(pred.columns) > len(predictor.targets)
    return Prediction(Path(out), len(table), list(predictor.targets), intervals, spec)
