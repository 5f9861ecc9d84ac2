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

__all__ = ["hamiltonian_figures", "hamiltonian_tables", "write_hamiltonian_outputs"]


def hamiltonian_tables(model: FittedPriorBoost, ds: Dataset) -> dict[str, pd.DataFrame]:
    """The coefficient, corrected-parameter and selection-path tables of a fitted model."""
    regressor = physics_regressor(model)
    X = ds.X_physics
    names = regressor.parameter_names_
    control = X[names]
    corrected = regressor.corrected_parameters(X)
    split = pd.Series("test", index=X.index, name="split")
    split.loc[ds.train_index] = "train"
    columns = {"split": split}
    for p in names:
        columns[f"{p}_control"] = control[p]
        columns[f"{p}_corrected"] = corrected[p]
        columns[f"{p}_correction"] = corrected[p] - control[p]
    tables = {"coefficients": regressor.coefficient_table(),
              "corrected_parameters": pd.DataFrame(columns)}
    selection = getattr(model.physics_, "selection_", None)
    if selection is not None:
        tables["selection_path"] = selection.path
    return tables


def hamiltonian_figures(model: FittedPriorBoost, ds: Dataset, setting: str | None = None
                        ) -> dict[str, Figure]:
    """``parameter_corrections`` (every experiment, training and test rows marked) and, when
    the covariates were selected, ``selection_path``."""
    regressor = physics_regressor(model)
    X = ds.X_physics
    names = regressor.parameter_names_
    figs = {"parameter_corrections": parameter_corrections(
        X[names], regressor.corrected_parameters(X),
        groups={"training rows": ds.train_index, "test rows": ds.test_index}, setting=setting)}
    selection = getattr(model.physics_, "selection_", None)
    if selection is not None:
        figs["selection_path"] = selection_path_figure(
            selection.path, title=f"Forward covariate selection ({selection.n_rows} training "
                                  "rows, CV MAE over all targets)", setting=setting)
    return figs


def write_hamiltonian_outputs(out: str | Path, model: FittedPriorBoost, ds: Dataset,
                              setting: str | None = None) -> dict[str, Path]:
    """Write the tables as CSV and the figures as PNG under ``out``; returns name -> path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = {}
    for name, table in hamiltonian_tables(model, ds).items():
        path = out / f"{name}.csv"
        table.to_csv(path, index=name == "corrected_parameters")
        written[name] = path
    for name, fig in hamiltonian_figures(model, ds, setting).items():
        written[name] = save_figure(fig, out / f"{name}.png")
    return written
