"""What a model family reports of a fitted model beyond its scores.

:class:`Artifacts` holds a fitted model's figures, tables and data, and writes them
(``evaluate --out``); a family makes them in
:meth:`~workbench.experiment.families.base.ModelFamily.outputs` and
:meth:`~workbench.experiment.families.base.ModelFamily.begin_artifacts`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from ..._io import atomic_write
from ..figures import save_figure

__all__ = ["Artifacts"]


@dataclass
class Artifacts:
    """A fitted model's extra outputs.

    Parameters
    ----------
    figures : dict
        Name -> matplotlib Figure.
    tables : dict
        Name -> DataFrame, written as CSV without the index.
    data : dict
        JSON-ready data.
    """

    figures: dict[str, Any] = field(default_factory=dict)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)

    def write(self, directory: str | Path, *, tables: bool = True, figures: bool = True,
              data: bool = True) -> dict[str, Any]:
        """Write the tables as CSV (no index column), the figures as PNG, the data as JSON.

        As ``<directory>/<name>.csv``, ``<name>.png`` and ``<name>.json``.

        Parameters
        ----------
        directory : str or Path
            Created if missing.
        tables, figures, data : bool, default=True
            Whether to write the tables, the figures, the data.

        Returns
        -------
        dict
            Name -> path written (a figure's, where a table or data share its name).
        """
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        written: dict[str, Any] = {}
        for name, value in (self.data.items() if data else ()):
            written[name] = atomic_write(directory / f"{name}.json",
                                         json.dumps(value, indent=2, default=str))
        for name, table in (self.tables.items() if tables else ()):
            written[name] = atomic_write(directory / f"{name}.csv", table.to_csv(index=False))
        for name, fig in (self.figures.items() if figures else ()):
            written[name] = save_figure(fig, directory / f"{name}.png")
        return written
