"""The experiment layer's Python API, for notebooks and scripts.

What the commands do, returning the typed results instead of printing them::

    from workbench.experiment.api import evaluate, evaluate_seeds, load_config

    cfg = load_config("experiments/generic.toml", overrides={"selection.cv": 3})
    result = evaluate(cfg)                 # a Result: per-target test MAE, CV scores, ...
    print(result.model.avg("test_mae"))
    spread = evaluate_seeds(cfg, [0, 1, 2])   # a SeedsResult: a Result per seed, and
    print(spread.summary.test_mae_sd)          # per target the mean and sd over the seeds

The names here are the promised ones; the modules they come from may move.
"""

from __future__ import annotations

from .config import ExperimentConfig, load_dataset
from .config.overrides import apply_overrides, parse_overrides
from .runs.design import Design, design
from .runs.evaluate import Evaluation, evaluate
from .runs.prepare import PreparedRun, load_config, parse_config, prepare
from .runs.seeds import SeedsResult, SeedSummary, evaluate_seeds
from .scoring.results import Result
from .scoring.scores import ModelScores, Scores
from .sweep.search import Sweep, run_sweep
from .tracking.compare import Comparison, compare_runs

__all__ = ["Comparison", "Design", "Evaluation", "ExperimentConfig", "ModelScores",
           "PreparedRun", "Result", "Scores", "SeedSummary", "SeedsResult", "Sweep",
           "apply_overrides", "compare_runs", "design", "evaluate", "evaluate_seeds",
           "load_config", "load_dataset", "parse_config", "parse_overrides", "prepare",
           "run_sweep"]
