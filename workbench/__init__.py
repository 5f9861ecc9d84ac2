"""workbench: base boosting, gradient boosting that starts from a scientific model.

The core (this package's top-level modules and :mod:`workbench.datasets`) imports only
numpy, scipy, pandas, scikit-learn and LightGBM. The experiment layer
(:mod:`workbench.experiment`: configs, model families, search, tracking, figures, CLI)
depends on the core, never the reverse.

The names below are imported on first use (PEP 562), so ``import workbench`` and the
``workbench`` command start without loading scikit-learn or LightGBM.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: Public name -> the core module that defines it.
_EXPORTS = {
    "BASES": "bases", "TRANSFORMS": "bases", "make_basis": "bases", "register_basis": "bases",
    "make_transform": "bases", "paper_basis": "bases",
    "BaseBoostRegressor": "boosting", "PriorModel": "boosting",
    "line_search": "line_search",
    "LOSSES": "losses", "get_loss": "losses",
    "MultiTargetBaseBoost": "multitarget",
    "PriorDerivedInputs": "derived",
    "ARDGaussianProcess": "gp",
    "BaseBoostCV": "selection",
    "HalvingChoiceCV": "halving",
    "StageChoiceCV": "stagewise",
    "ParametricModel": "parametric", "ModelError": "parametric", "load_model": "parametric",
    "ParametricRegressor": "param_regressor", "ParametricBoostRegressor": "parametric_boost",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
