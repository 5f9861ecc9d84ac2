"""workbench: base boosting, gradient boosting that starts from a scientific model.

The core (this package's top-level modules and :mod:`workbench.datasets`) imports only
numpy, scipy, pandas, scikit-learn and LightGBM. The experiment layer
(:mod:`workbench.experiment`: configs, evaluation, CLI, later search/tracking/figures)
depends on the core, never the reverse.
"""

from .bases import BASES, TRANSFORMS, make_basis, make_transform, paper_basis
from .boosting import BaseBoostRegressor, PriorModel
from .line_search import line_search
from .losses import LOSSES, get_loss
from .multitarget import MultiTargetBaseBoost
from .selection import BaseBoostCV

__version__ = "0.1.0"

__all__ = [
    "BASES",
    "LOSSES",
    "TRANSFORMS",
    "BaseBoostCV",
    "BaseBoostRegressor",
    "MultiTargetBaseBoost",
    "PriorModel",
    "get_loss",
    "line_search",
    "make_basis",
    "make_transform",
    "paper_basis",
]
