"""Two tracked runs side by side: per-target test MAE and the paired interval of the gap.

A run of ``evaluate`` (or a reproduction system) logs its test rows' predictions
(``predictions/test.csv``) and measured targets (``predictions/test_measured.csv``). Two runs
on the same test rows are compared row by row: each target's MAE in both, and the paired
bootstrap interval of ``MAE(a) - MAE(b)`` (the same resampled rows for both, as
:func:`~workbench.experiment.scoring.bootstrap.bootstrap_error_interval` draws them), so whether a
difference such as 1.064 against 1.074 is more than the rows' luck can be read off.
Nothing is logged.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..process.errors import UsageError
from ..scoring.bootstrap import BOOTSTRAP_LEVEL, bootstrap_error_interval

if TYPE_CHECKING:
    from mlflow import MlflowClient

__all__ = ["MEASURED", "PREDICTIONS", "Comparison", "compare_runs", "find_run",
           "format_comparison", "run_errors"]

#: The artifacts a comparison reads: the test rows' predictions and measured targets.
PREDICTIONS, MEASURED = "predictions/test.csv", "predictions/test_measured.csv"


@dataclass
class Comparison:
    """Per-target test MAE of two runs and the paired interval of their difference.

    Parameters
    ----------
    runs : tuple of str
        The two runs' names (or ids where they have none).
    run_ids : tuple of str
        Their ids.
    targets : list of str
        The targets both runs predict.
    n_rows : int
        The test rows both runs were scored on.
    mae_a, mae_b : list of float
        Per target, each run's test MAE.
    diff_ci : list of list of float
        Per target, then for the average over targets, the ``level`` interval of
        ``MAE(a) - MAE(b)`` (below zero: run a's errors are the smaller).
    level : float
        The intervals' central probability.
    """

    runs: tuple[str, str]
    run_ids: tuple[str, str]
    targets: list[str]
    n_rows: int
    mae_a: list[float]
    mae_b: list[float]
    diff_ci: list[list[float]]
    level: float


def find_run(client: MlflowClient, ref: str) -> Any:
    """Find a run by its id or its name, in any experiment of the store.

    Parameters
    ----------
    client : MlflowClient
        A client of the tracking store.
    ref : str
        A run id, or a run name that exactly one run has.

    Returns
    -------
    mlflow.entities.Run
        The run.

    Raises
    ------
    UsageError
        No run has that id or name, or several runs have that name (their ids listed).
    """
    from mlflow.exceptions import MlflowException

    try:
        return client.get_run(ref)
    except MlflowException:
        pass
    ids = [e.experiment_id for e in client.search_experiments()]
    quoted = ref.replace("'", "\\'")
    runs = client.search_runs(ids, f"attributes.run_name = '{quoted}'", max_results=50)
    if not runs:
        raise UsageError(f"no run with the id or name {ref!r} in the tracking store")
    if len(runs) > 1:
        listed = ", ".join(r.info.run_id for r in runs[:5])
        raise UsageError(f"{len(runs)} runs are named {ref!r} ({listed}"
                         f"{', ...' if len(runs) > 5 else ''}): give a run id")
    return runs[0]


def _artifact_frame(client: MlflowClient, run: Any, path: str) -> pd.DataFrame:
    """Read one of a run's CSV artifacts (indexed by its ``row`` column)."""
    import mlflow.artifacts

    try:
        text = mlflow.artifacts.load_text(f"{run.info.artifact_uri.rstrip('/')}/{path}")
    except Exception:  # noqa: BLE001 - MLflow raises several kinds for a missing artifact
        raise UsageError(f"run {run.info.run_name or run.info.run_id} has no {path} (runs "
                         "log it from this release on: run it again to compare it)") from None
    return pd.read_csv(io.StringIO(text), index_col="row")


def run_errors(client: MlflowClient, run: Any) -> pd.DataFrame:
    """Return a run's test errors, measured minus predicted, one column per target.

    Parameters
    ----------
    client : MlflowClient
        A client of the tracking store.
    run : mlflow.entities.Run
        A run that logged :data:`PREDICTIONS` and :data:`MEASURED`.

    Returns
    -------
    DataFrame
        Indexed by test row.

    Raises
    ------
    UsageError
        A missing artifact.
    """
    measured = _artifact_frame(client, run, MEASURED)
    predicted = _artifact_frame(client, run, PREDICTIONS)[measured.columns]
    return measured - predicted


def compare_runs(client: MlflowClient | str, ref_a: str, ref_b: str, *,
                 level: float = BOOTSTRAP_LEVEL) -> Comparison:
    """Compare two runs on the test rows and targets they share.

    Parameters
    ----------
    client : MlflowClient or str
        A client of the tracking store, or the store's tracking URI.
    ref_a, ref_b : str
        Run ids or names.
    level : float, default=BOOTSTRAP_LEVEL
        Central probability of the paired intervals.

    Returns
    -------
    Comparison
        Per shared target the two runs' test MAE and their paired difference's interval.

    Raises
    ------
    UsageError
        A run not found, without its predictions, or runs with no target or no test row in
        common (different data sets or splits).
    """
    if isinstance(client, str):
        from mlflow import MlflowClient  # (b) MLflow: the API imports this module

        client = MlflowClient(client)
    runs = [find_run(client, ref) for ref in (ref_a, ref_b)]
    errors = [run_errors(client, run) for run in runs]
    names = tuple(r.info.run_name or r.info.run_id for r in runs)
    targets = [t for t in errors[0].columns if t in errors[1].columns]
    if not targets:
        raise UsageError(f"runs {names[0]} and {names[1]} share no target "
                         f"({list(errors[0].columns)} against {list(errors[1].columns)})")
    a, b = errors
    if not a.index.equals(b.index):
        raise UsageError(f"runs {names[0]} and {names[1]} were scored on different test rows "
                         f"({len(a)} and {len(b)} rows; not the same data set and split)")
    ea, eb = a[targets].to_numpy(dtype=float), b[targets].to_numpy(dtype=float)
    ci = bootstrap_error_interval(ea, baseline=eb, level=level)
    return Comparison(runs=(names[0], names[1]),
                      run_ids=(runs[0].info.run_id, runs[1].info.run_id),
                      targets=[str(t) for t in targets], n_rows=len(a),
                      mae_a=np.abs(ea).mean(axis=0).tolist(),
                      mae_b=np.abs(eb).mean(axis=0).tolist(),
                      diff_ci=[*ci.per_target, ci.average], level=level)


def format_comparison(c: Comparison, unit: str | None = None) -> str:
    """Write a comparison as a table, one line per target and one for the average.

    Parameters
    ----------
    c : Comparison
        What :func:`compare_runs` returned.
    unit : str, optional
        The targets' unit, named in the header.

    Returns
    -------
    str
        The table's lines.
    """
    unit_text = f", {unit}" if unit else ""
    width = max(len("average"), *(len(t) for t in c.targets))
    lines = [f"test MAE on {c.n_rows} rows{unit_text}: a = {c.runs[0]}, b = {c.runs[1]}; "
             f"{c.level:.0%} paired bootstrap interval of a - b",
             f"{'target':<{width}}  {'a':>8}  {'b':>8}  {'a - b':>8}  interval"]
    rows = list(zip(c.targets, c.mae_a, c.mae_b, c.diff_ci))
    rows.append(("average", float(np.mean(c.mae_a)), float(np.mean(c.mae_b)), c.diff_ci[-1]))
    for target, ma, mb, (low, high) in rows:
        verdict = "a lower" if high < 0 else "b lower" if low > 0 else "no clear difference"
        lines.append(f"{target:<{width}}  {ma:8.3f}  {mb:8.3f}  {ma - mb:+8.3f}  "
                     f"[{low:+.3f}, {high:+.3f}] {verdict}")
    return "\n".join(lines)
