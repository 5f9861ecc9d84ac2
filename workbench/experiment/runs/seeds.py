"""``workbench evaluate --random-states``: one config fitted once per seed, side by side.

Each seed is one value of the config's ``random_state`` (reaching every random component, as
in one ``evaluate``), listed in ``[evaluation] random_states``; the data are loaded once and
keep their split (``[data] split_seed``), and the CV folds their own fixed draws
(``[evaluation] cv_seed``, ``nested_seed``): what changes between seeds is the model's
own randomness (and the bootstrap's resamples). Each seed runs the one evaluate code path
(:func:`~workbench.experiment.runs.evaluate.evaluate`), one after another; the
:class:`SeedSummary` holds per target the mean and the sample standard deviation of the test
MAE over the seeds. Tracked, the command makes a parent run with the summary and a child run
per seed (:func:`~workbench.experiment.runs.record.record_seeds`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..config import ExperimentConfig, load_dataset
from ..families.artifacts import Artifacts
from ..figures import seed_spread
from ..scoring.results import Result
from ..scoring.units import unit_name
from .evaluate import Evaluation, evaluate

if TYPE_CHECKING:
    from ...datasets import Dataset

__all__ = ["SeedRunner", "SeedSummary", "SeedsResult", "check_seeds", "evaluate_seeds",
           "format_seeds_table", "seed_artifacts"]

log = logging.getLogger("workbench")

#: Runs one seed's fit: called with the seed's config and the fit itself, it returns the fit's
#: :class:`~workbench.experiment.runs.evaluate.Evaluation` (the command keeps the seed's MLflow run
#: open around it).
SeedRunner = Callable[[ExperimentConfig, Callable[[], Evaluation]], Evaluation]


def _sd(values: Any, axis: int | None = None) -> Any:
    """Return the sample standard deviation (``n - 1``) of two or more values."""
    return np.std(np.asarray(values, dtype=float), axis=axis, ddof=1)


@dataclass
class SeedSummary:
    """The model's test MAE over seeds: per seed, and its mean and sample sd per target.

    Parameters
    ----------
    random_states : list of int
        The ``random_state`` values (the seeds), in the order run.
    targets : list of str
        The targets.
    test_mae : list of list of float
        Per seed, the model's test MAE per target.
    test_mae_mean, test_mae_sd : list of float
        Per target, the mean and the sample standard deviation (``n - 1``) over the seeds.
    test_mae_avg : list of float
        Per seed, the average over targets.
    test_mae_avg_mean, test_mae_avg_sd : float
        The mean and sample standard deviation over the seeds of that average.
    prior_test_mae : list of float
        The prior's test MAE per target (no seed changes it).
    prior_test_mae_avg : float
        Its average over targets.
    unit : str or None
        The targets' unit.
    """

    random_states: list[int]
    targets: list[str]
    test_mae: list[list[float]]
    test_mae_mean: list[float]
    test_mae_sd: list[float]
    test_mae_avg: list[float]
    test_mae_avg_mean: float
    test_mae_avg_sd: float
    prior_test_mae: list[float]
    prior_test_mae_avg: float
    unit: str | None = None

    @classmethod
    def of(cls, random_states: Sequence[int], results: Sequence[Result]) -> SeedSummary:
        """Summarize the results of the seeds.

        Parameters
        ----------
        random_states : sequence of int
            Two or more ``random_state`` values.
        results : sequence of Result
            Each seed's result, in the seeds' order, all of the same targets.

        Returns
        -------
        SeedSummary
            The summary.
        """
        mae = np.array([r.model.test_mae for r in results], dtype=float)
        avg = mae.mean(axis=1)
        first = results[0]
        return cls(random_states=[int(s) for s in random_states], targets=list(first.targets),
                   test_mae=mae.tolist(), test_mae_mean=mae.mean(axis=0).tolist(),
                   test_mae_sd=_sd(mae, axis=0).tolist(), test_mae_avg=avg.tolist(),
                   test_mae_avg_mean=float(avg.mean()), test_mae_avg_sd=float(_sd(avg)),
                   prior_test_mae=list(first.prior.test_mae),
                   prior_test_mae_avg=first.prior.avg("test_mae"), unit=first.unit)

    def metrics(self) -> dict[str, float]:
        """Write the summary as MLflow metrics.

        Returns
        -------
        dict of str to float
            ``test_mae_mean/<target>``, ``test_mae_sd/<target>``, ``test_mae_avg_mean``,
            ``test_mae_avg_sd``, the prior's ``prior_test_mae/<target>`` and
            ``prior_test_mae_avg``, and ``n_seeds``.
        """
        m: dict[str, float] = {"test_mae_avg_mean": self.test_mae_avg_mean,
                               "test_mae_avg_sd": self.test_mae_avg_sd,
                               "prior_test_mae_avg": self.prior_test_mae_avg,
                               "n_seeds": len(self.random_states)}
        for t, mean, sd, prior in zip(self.targets, self.test_mae_mean, self.test_mae_sd,
                                      self.prior_test_mae):
            m.update({f"test_mae_mean/{t}": mean, f"test_mae_sd/{t}": sd,
                      f"prior_test_mae/{t}": prior})
        return m

    def table(self) -> pd.DataFrame:
        """Tabulate each seed's test MAE.

        Returns
        -------
        pandas.DataFrame
            One row per seed: ``random_state``, a column per target and ``average``.
        """
        frame = pd.DataFrame(self.test_mae, columns=self.targets)
        frame.insert(0, "random_state", self.random_states)
        frame["average"] = self.test_mae_avg
        return frame

    def to_json(self) -> dict[str, Any]:
        """Write the summary as JSON-ready data.

        Returns
        -------
        dict
            Every field by name.
        """
        return asdict(self)


@dataclass
class SeedsResult:
    """One config evaluated once per seed.

    Parameters
    ----------
    name : str
        The config's name.
    config : str or None
        Its file.
    results : list of Result
        Each seed's result, in the seeds' order (its ``mlflow``: the seed's child run).
    summary : SeedSummary
        The test MAE over the seeds.
    outputs : dict of str to str
        Files written by ``--out``.
    mlflow : dict of str to str
        The parent run's ids.
    wall_s : float
        The whole command's wall time.
    """

    name: str
    config: str | None
    results: list[Result]
    summary: SeedSummary
    outputs: dict[str, str] = field(default_factory=dict)
    mlflow: dict[str, str] = field(default_factory=dict)
    wall_s: float = math.nan

    @property
    def random_states(self) -> list[int]:
        """The ``random_state`` values (the seeds), in the order run."""
        return self.summary.random_states

    def to_json(self) -> dict[str, Any]:
        """Write the result as the JSON ``evaluate --random-states --json`` writes.

        Returns
        -------
        dict
            ``name``, ``config``, ``random_states``, ``targets``, ``unit``, ``summary``
            (:meth:`SeedSummary.to_json`), ``runs`` (each seed's :meth:`Result.to_json`
            with its ``random_state``), ``outputs`` and ``mlflow`` when present, and
            ``wall_s``.
        """
        out: dict[str, Any] = {
            "name": self.name, "config": self.config, "random_states": self.random_states,
            "targets": self.summary.targets, "unit": self.summary.unit,
            "summary": self.summary.to_json(),
            "runs": [{"random_state": s, **r.to_json()}
                     for s, r in zip(self.random_states, self.results)]}
        if self.outputs:
            out["outputs"] = self.outputs
        if self.mlflow:
            out["mlflow"] = self.mlflow
        out["wall_s"] = self.wall_s
        return out


def check_seeds(random_states: Sequence[int]) -> list[int]:
    """Check the ``random_state`` values of :func:`evaluate_seeds`.

    Parameters
    ----------
    random_states : sequence of int
        The values.

    Returns
    -------
    list of int
        The values, as a list.

    Raises
    ------
    ValueError
        Unless they are two or more distinct integers >= 0.
    """
    out = list(random_states)
    if any(isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0 for s in out):
        raise ValueError(f"random_states must be integers >= 0, got {out[:10]}")
    if len(out) < 2 or len(set(out)) != len(out):
        raise ValueError(f"random_states must be two or more distinct values, got {out[:10]}")
    return [int(s) for s in out]


def evaluate_seeds(cfg: ExperimentConfig, random_states: Sequence[int] | None = None, *,
                   dataset: Dataset | None = None,
                   runner: SeedRunner | None = None) -> SeedsResult:
    """Evaluate a config once per seed, one seed after another, and summarize.

    Each seed is the config's ``random_state`` for one
    :func:`~workbench.experiment.runs.evaluate.evaluate`; the data are loaded once for all.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    random_states : sequence of int, optional
        Two or more distinct ``random_state`` values; default: the config's
        ``[evaluation] random_states``.
    dataset : Dataset, optional
        The config's dataset, already loaded and checked; loaded here when not given.
    runner : SeedRunner, optional
        Runs each seed's fit (e.g. inside its MLflow run); default: the fit alone.

    Returns
    -------
    SeedsResult
        Each seed's result and the summary; ``wall_s`` the time of the seeds' fits.

    Raises
    ------
    ValueError
        If the values are not two or more distinct integers >= 0.
    """
    chosen = check_seeds(cfg.evaluation.random_states if random_states is None
                         else random_states)
    start = time.perf_counter()
    ds = dataset if dataset is not None else load_dataset(cfg)
    results = []
    for i, seed in enumerate(chosen):
        log.info("[%s] seed %d (%d of %d)", cfg.name, seed, i + 1, len(chosen))
        one = dataclasses.replace(cfg, random_state=seed)

        def fit(one: ExperimentConfig = one) -> Evaluation:
            return evaluate(one, return_model=True, dataset=ds)

        results.append((runner(one, fit) if runner is not None else fit()).result)
    return SeedsResult(name=cfg.name, config=str(cfg.path) if cfg.path else None,
                       results=results, summary=SeedSummary.of(chosen, results),
                       wall_s=time.perf_counter() - start)


def _rows(s: SeedSummary) -> list[tuple[str, float, float, float, float, float]]:
    """Per target, then the average: prior, mean, sd, lowest and highest over seeds."""
    mae = np.asarray(s.test_mae, dtype=float)
    rows = [(t, s.prior_test_mae[j], s.test_mae_mean[j], s.test_mae_sd[j],
             float(mae[:, j].min()), float(mae[:, j].max())) for j, t in enumerate(s.targets)]
    rows.append(("average", s.prior_test_mae_avg, s.test_mae_avg_mean, s.test_mae_avg_sd,
                 min(s.test_mae_avg), max(s.test_mae_avg)))
    return rows


def format_seeds_table(done: SeedsResult, markdown: bool = False) -> str:
    """Format the per-target table of a seeds result.

    Prior test MAE, the model's mean and sample sd over the seeds, its lowest and highest;
    below it each seed's average.

    Parameters
    ----------
    done : SeedsResult
        The result.
    markdown : bool, default=False
        A Markdown table (the MLflow run's description) instead of text columns.

    Returns
    -------
    str
        The table, lines joined.
    """
    s = done.summary
    seeds = ", ".join(str(x) for x in s.random_states)
    head = (f"test MAE over {len(s.random_states)} seeds ({seeds}) in {unit_name(s.unit)}; sd: "
            "the sample standard deviation over the seeds")
    if markdown:
        lines = [head + ".", "", "| target | prior | model mean | model sd | lowest | highest |",
                 "|---|---:|---:|---:|---:|---:|"]
        lines += [f"| {t} | {p:.4g} | {m:.4g} | {sd:.2g} | {lo:.4g} | {hi:.4g} |"
                  for t, p, m, sd, lo, hi in _rows(s)]
        return "\n".join(lines)
    w = max(10, *(len(t) + 2 for t in s.targets))
    rule = "-" * (w + 55)
    lines = [f"{'target':<{w}}{'prior MAE':>11}{'model mean':>12}{'sd':>10}{'lowest':>11}"
             f"{'highest':>11}", rule]
    for t, p, m, sd, lo, hi in _rows(s):
        if t == "average":
            lines.append(rule)
        lines.append(f"{t:<{w}}{p:>11.3f}{m:>12.3f}{sd:>10.3f}{lo:>11.3f}{hi:>11.3f}")
    lines.append(head)
    lines.append("average per seed: " + ", ".join(
        f"{seed}: {v:.3f}" for seed, v in zip(s.random_states, s.test_mae_avg)))
    lines.append(f"wall time {done.wall_s:.1f} s")
    if done.results and done.results[0].folds:  # the same folds for every seed's choices
        lines.append(f"folds: {done.results[0].folds}")
    return "\n".join(lines)


def seed_artifacts(done: SeedsResult, setting: str) -> Artifacts:
    """Make what ``evaluate --random-states --out DIR`` writes and its parent run logs.

    Parameters
    ----------
    done : SeedsResult
        The result.
    setting : str
        The run's label, in the figure's title.

    Returns
    -------
    Artifacts
        The figure ``seed_spread`` (:func:`~workbench.experiment.figures.seed_spread`) and
        the table ``seed_test_mae`` (:meth:`SeedSummary.table`).
    """
    s = done.summary
    fig = seed_spread(s.targets, s.test_mae, random_states=s.random_states, prior=s.prior_test_mae,
                      unit=s.unit, setting=setting)
    return Artifacts(figures={"seed_spread": fig}, tables={"seed_test_mae": s.table()})
