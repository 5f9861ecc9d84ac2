"""What the parameter-space model (family hamiltonian) learned, as tables and figures.

* ``coefficients``: the selected covariates and coefficients per Hamiltonian parameter
  (MHz per standard deviation of the covariate, and that standard deviation);
* ``corrected_parameters``: per experiment, each parameter's control-model value, corrected
  value and correction, and whether the row is a training or a test row;
* ``selection_path``: the forward selection's CV MAE after each added covariate;

and the figures :func:`~workbench.experiment.figures.parameter_corrections` and
:func:`~workbench.experiment.figures.selection_path_figure`. ``workbench evaluate --out DIR``
writes them as CSV/PNG; MLflow runs of family hamiltonian log them as artifacts.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from ..datasets import Dataset
from ..fitted_prior import FittedPriorBoost
from .evaluate import physics_regressor
from .figures import parameter_corrections, save_figure, selection_path_figure

__all__ = ["hamiltonian_outputs", "write_hamiltonian_outputs", "write_tables"]


def hamiltonian_outputs(model: FittedPriorBoost, ds: Dataset, setting: str | None = None
                        ) -> tuple[dict[str, pd.DataFrame], dict[str, Figure]]:
    """The tables and figures of a fitted model, from one computation of the corrected
    parameters of every experiment. Every table is written without its index (the
    corrected parameters carry the experiment label in the column ``experiment``)."""
    regressor = physics_regressor(model)
    X = ds.X_physics
    names = regressor.parameter_names_
    control = regressor.control_parameters(X)
    corrected = regressor.corrected_parameters(X)
    split = pd.Series("test", index=X.index, name="split")
    split.loc[ds.train_index] = "train"
    columns = {"experiment": pd.Series(X.index, index=X.index), "split": split}
    for p in names:
        columns[f"{p}_control"] = control[p]
        columns[f"{p}_corrected"] = corrected[p]
        columns[f"{p}_correction"] = corrected[p] - control[p]
    tables = {"coefficients": regressor.coefficient_table(),
              "corrected_parameters": pd.DataFrame(columns)}
    figures = {"parameter_corrections": parameter_corrections(
        control, corrected, groups={"training rows": ds.train_index, "test rows": ds.test_index},
        setting=setting)}
    selection = getattr(model.physics_, "selection_", None)
    if selection is not None:
        tables["selection_path"] = selection.path
        figures["selection_path"] = selection_path_figure(
            selection.path, title=f"Forward covariate selection ({selection.n_rows} training "
                                  "rows, CV MAE over all targets)", setting=setting)
    return tables, figures


def write_tables(directory: str | Path, tables: dict[str, pd.DataFrame]) -> dict[str, Path]:
    """Each table as ``<directory>/<name>.csv`` (no index column); returns name -> path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = {}
    for name, table in tables.items():
        written[name] = directory / f"{name}.csv"
        table.to_csv(written[name], index=False)
    return written


def write_hamiltonian_outputs(out: str | Path, model: FittedPriorBoost, ds: Dataset,
                              setting: str | None = None) -> dict[str, Path]:
    """Write the tables as CSV and the figures as PNG under ``out``; returns name -> path."""
    tables, figures = hamiltonian_outputs(model, ds, setting)
    written = write_tables(out, tables)
    for name, fig in figures.items():
        written[name] = save_figure(fig, Path(out) / f"{name}.png")
    return written
