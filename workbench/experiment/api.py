"""The experiment layer's Python API, for notebooks and scripts.

What the commands do, returning the typed results instead of printing them::

    from workbench.experiment.api import evaluate, load_config

    cfg = load_config("experiments/generic.toml", overrides={"selection.cv": 3})
    result = evaluate(cfg)                 # a Result: per-target test MAE, CV scores, ...
    print(result.model.avg("test_mae"))

The names here are the promised ones; the modules they come from may move.
"""

from __future__ import annotations

from .compare import Comparison, compare_runs
from .config import ExperimentConfig, load_dataset
from .design import Design, design
from .evaluate import Evaluation, evaluate
from .overrides import apply_overrides, parse_overrides
from .prepare import PreparedRun, load_config, parse_config, prepare
from .results import ModelScores, Result, Scores
from .sweep.search import Sweep, run_sweep

__all__ = ["Comparison", "Design", "Evaluation", "ExperimentConfig", "ModelScores",
           "PreparedRun", "Result", "Scores", "Sweep", "apply_overrides", "compare_runs",
           "design", "evaluate", "load_config", "load_dataset", "parse_config",
           "parse_overrides", "prepare", "run_sweep"]
