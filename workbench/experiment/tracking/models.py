"""A logged model's directory: a fitted model saved as an MLflow pyfunc model.

The ``workbench`` package travels with it (its code), its requirements are pinned from the
installed versions; :meth:`~.runs.Tracker.log_model` uploads it, and a version
:meth:`~.runs.Tracker.register_model` registers gets the alias :data:`CHAMPION`.
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import logging
import shutil
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import mlflow
import pandas as pd

import workbench

from .serving import WorkbenchModel

if TYPE_CHECKING:
    from mlflow.models import ModelSignature

__all__ = ["CHAMPION", "MODEL_REQUIREMENTS", "save_pyfunc_model"]

#: The alias the newest registered version gets (aliases, not the deprecated stages).
CHAMPION = "champion"
#: Distributions pinned in a logged model's requirements (those installed).
MODEL_REQUIREMENTS = ("mlflow", "cloudpickle", "numpy", "pandas", "scipy", "scikit-learn",
                      "lightgbm", "joblib")


def _requirements() -> list[str]:
    reqs = []
    for dist in MODEL_REQUIREMENTS:
        try:
            reqs.append(f"{dist}=={importlib.metadata.version(dist)}")
        except importlib.metadata.PackageNotFoundError:
            pass
    return reqs


class _DropMessages(logging.Filter):
    """Drop log records containing one of ``texts`` (MLflow's notices for deliberate choices)."""

    def __init__(self, *texts: str) -> None:
        super().__init__()
        self.texts = texts

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        return not any(t in message for t in self.texts)


@contextlib.contextmanager
def _quiet(logger_name: str, *texts: str) -> Iterator[None]:
    log, flt = logging.getLogger(logger_name), _DropMessages(*texts)
    log.addFilter(flt)
    try:
        yield
    finally:
        log.removeFilter(flt)


def save_pyfunc_model(tmp: Path, wrapped: WorkbenchModel, meta: mlflow.models.Model,
                      signature: ModelSignature, example: pd.DataFrame,
                      texts: Mapping[str, str] | None) -> Path:
    """Save ``wrapped`` as a pyfunc model directory in ``tmp``, the package as its code.

    Parameters
    ----------
    tmp : Path
        A scratch directory; the model directory is made inside it.
    wrapped : WorkbenchModel
        The fitted model, wrapped.
    meta : mlflow.models.Model
        The logged model's metadata (its id, run and artifact location).
    signature : mlflow.models.ModelSignature
        The input columns and the outputs.
    example : DataFrame
        Input rows; the first 5 are the input example.
    texts : mapping or None
        File name -> text, written beside ``MLmodel``.

    Returns
    -------
    Path
        The model directory.
    """
    code = tmp / "code" / "workbench"
    shutil.copytree(Path(workbench.__file__).parent, code,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    local = tmp / "model"
    # cloudpickle is the deliberate choice here (the docs' "models from code" would need a
    # script per model): silence MLflow's notice about it for this call.
    with _quiet("mlflow.pyfunc", "serialized using CloudPickle", "Validating input example"):
        mlflow.pyfunc.save_model(
            str(local), python_model=wrapped, mlflow_model=meta,
            signature=signature, input_example=example.head(5),
            metadata={"workbench": {"inputs": wrapped.columns,
                                    "targets": wrapped.targets,
                                    "outputs": wrapped.outputs}},
            pip_requirements=_requirements(), code_paths=[str(code)])
    for file_name, text in (texts or {}).items():  # config.toml beside MLmodel
        (local / file_name).write_text(text, encoding="utf-8")
    return local
