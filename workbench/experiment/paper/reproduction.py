"""What ``workbench reproduce`` computed, and the reference results it is read against.

One dataclass with one ``to_json`` (``results.json``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..scoring.results import Result
from .compute import SHORT
from .gates import Gates

__all__ = ["REFERENCE", "Reproduction"]

#: Reference results measured on this kind of machine (``method.md``): per-target test MAE
#: and the documented average (MHz).
REFERENCE = {
    "control program (prior)": ([2.417, 1.400, 0.819, 0.972, 1.098], 1.341),
    "scikit-physlearn, paper settings (mean of 8 runs)":
        ([1.750, 1.036, 0.802, 0.801, 1.004], 1.081),
    "scikit-physlearn, improved settings (4 runs)": ([1.702, 1.008, 0.768, 0.800, 0.981], 1.057),
}


@dataclass
class Reproduction:
    """What ``workbench reproduce`` computed.

    Parameters
    ----------
    targets : list of str
        The Google benchmark's targets.
    random_state : int
        Every system's ``random_state``.
    quick : bool
        Whether ``--quick`` reduced the work.
    settings : dict of str to Result
        A result per setting: "paper", "improved", "hamiltonian" and, with ``--all``,
        "search".
    tabula_rasa : dict
        The tabula rasa MLPs' test errors (:func:`.phases.tabula_rasa_system`).
    correlation : dict
        The training rows' correlation matrix.
    learning_curves : dict
        The paper settings' learning curves (:func:`.compute.draw_learning_curves`).
    figures : dict of str to list of str
        Figure id -> its files, relative to the report folder.
    hamiltonian_tables : dict of str to str
        The parameter-space model's tables: name -> file, relative to the report folder.
    gates : Gates, optional
        The IBM benchmark's results (``--all``).
    mlflow : dict of str to str
        The tracking URI and run ids (empty without tracking).
    wall_s : float
        The whole command's seconds.
    unit : str, optional
        The Google benchmark's unit (its dataset's).
    all_systems : bool
        Whether ``--all`` ran the nested-CV search and the IBM benchmark too.
    """

    targets: list[str]
    random_state: int
    quick: bool
    settings: dict[str, Result]
    tabula_rasa: dict[str, Any]
    correlation: dict[str, Any]
    learning_curves: dict[str, Any]
    figures: dict[str, list[str]]
    hamiltonian_tables: dict[str, str] = field(default_factory=dict)
    gates: Gates | None = None
    mlflow: dict[str, str] = field(default_factory=dict)
    wall_s: float = float("nan")
    unit: str | None = None
    all_systems: bool = False

    def to_json(self) -> dict[str, Any]:
        """Write the reproduction as JSON (``results.json``).

        Returns
        -------
        dict
            Every field, the reference results and the tabula rasa MLPs' averages; the IBM
            benchmark's under ``ibm_gates``.
        """
        out = {"targets": self.targets, "short": SHORT, "unit": self.unit,
               "random_state": self.random_state,
               "quick": self.quick, "all": self.all_systems,
               "settings": {k: r.to_json() for k, r in self.settings.items()},
               "reference": REFERENCE,
               "tabula_rasa": {**self.tabula_rasa,
                               "test_mae_avg": float(np.mean(self.tabula_rasa["test_mae"])),
                               "test_mse_avg": float(np.mean(self.tabula_rasa["test_mse"]))},
               "correlation": self.correlation, "learning_curves": self.learning_curves,
               "figures": self.figures, "hamiltonian_tables": self.hamiltonian_tables,
               "wall_s": self.wall_s}
        if self.gates is not None:
            out["ibm_gates"] = self.gates.to_json()
        if self.mlflow:
            out["mlflow"] = self.mlflow
        return out
