"""A run's figures, tables and predictions, computed once before anything records them.

``evaluate`` and ``sweep`` make everything a run shows here, in one call,
:func:`compute_outputs`: the MAE/MSE bars, the intervals' figure and table
(:func:`~.intervals.interval_artifacts`), the family's tables and figures
(:meth:`~.families.base.ModelFamily.outputs`, and what
:meth:`~.families.base.ModelFamily.begin_artifacts` adds for a run: the eigenvalue family's
learning curves and SHAP summaries) and the test rows' predictions
(:func:`~.serving.prediction_frame`). The figures are written as PNG files there. The result,
a :class:`RunOutputs`, is handed down: the MLflow record (:func:`.record.record`) logs its
files and values and computes nothing, and ``evaluate --out DIR`` writes every figure, table
and data file the run logs (all but the test rows' predictions) in the same call, with or
without tracking.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from ...datasets import Dataset
from ..config import ExperimentConfig
from ..families.artifacts import Artifacts
from ..figures import error_bars
from ..figures.style import PNG_DPI
from ..process.errors import TrackingError
from ..process.outputs import write_artifacts
from ..scoring.results import Result
from .intervals import family_model, interval_artifacts

__all__ = ["RunOutputs", "compute_outputs", "computed_outputs"]

#: The run's directory of figures (``plots/<name>.png``).
PLOTS = "plots"


@dataclass
class RunOutputs:
    """What a run records and ``evaluate --out`` writes, all of it computed already.

    Attributes
    ----------
    rows : tuple of DataFrame
        ``X_train, X_test, y_train, y_test``: the rows as the family's model saw them.
    figures : dict of str to Figure
        Artifact path (``plots/<name>.png``) -> the figure drawn.
    files : dict of str to Path
        Artifact path -> the figure's PNG file (a tracked run's; what the record logs).
    tables : dict of str to DataFrame
        Artifact path (``intervals/<name>.csv``, ``<family>/<name>.csv``) -> the table,
        logged as CSV without the index.
    data : dict of str to object
        Artifact file (``<name>.json``) -> JSON-ready data.
    predictions : DataFrame or None
        The test rows' predictions as ``workbench predict`` gives them (a tracked run's).
    written : dict of str to Path
        ``evaluate --out``: name -> the file written in the directory.
    """

    rows: tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, pd.DataFrame]
    figures: dict[str, Any] = field(default_factory=dict)
    files: dict[str, Path] = field(default_factory=dict)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)
    predictions: pd.DataFrame | None = None
    written: dict[str, Path] = field(default_factory=dict)


def _run_bars(result: Result, ds: Dataset, setting: str) -> dict[str, Any]:
    """Draw the run's test MAE and MSE bars (``mae_bars``, ``mse_bars``).

    The prior is named as the data set names it (:attr:`Dataset.prior_label`).
    """
    return {f"{metric.lower()}_bars": error_bars(result, metric, unit=ds.unit, setting=setting,
                                                 labels=(ds.prior_label, "base boosting"),
                                                 title=f"Test {metric} per target")
            for metric in ("MAE", "MSE")}


def _merged(*parts: Artifacts) -> Artifacts:
    """Join artifacts, a later part's name replacing an earlier one's."""
    out = Artifacts()
    for part in parts:
        out.figures.update(part.figures)
        out.tables.update(part.tables)
        out.data.update(part.data)
    return out


def _png(fig: Any, path: Path) -> Path:
    """Render ``fig`` as the PNG ``path`` (a scratch file: written directly, not atomically).

    At the resolution of :func:`~.figures.save_figure`, so a figure's PNG is the same bytes
    here and in ``evaluate --out``.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=PNG_DPI, format="png")
    return path


def _tracked(computed: RunOutputs, family: str, shown: Artifacts, own: Artifacts,
             extra: Artifacts, bars: dict[str, Any], scratch: Path) -> None:
    """Fill a tracked run's figures (as PNG files in ``scratch``), tables and data.

    A figure ``evaluate --out`` wrote already is its file in the directory (not rendered again).
    """
    logged = _merged(own, extra)
    for name, fig in {**bars, **shown.figures, **logged.figures}.items():
        artifact = f"{PLOTS}/{name}.png"
        computed.figures[artifact] = fig
        try:
            done = computed.written.get(name)
            computed.files[artifact] = (done if done is not None and done.suffix == ".png"
                                        else _png(fig, scratch / PLOTS / f"{name}.png"))
        except OSError as exc:
            raise TrackingError(f"cannot write the run's figure {name}.png in {scratch}: "
                                f"{exc.strerror or type(exc).__name__}") from None
    computed.tables.update({f"intervals/{k}.csv": t for k, t in shown.tables.items()})
    computed.tables.update({f"{family}/{k}.csv": t for k, t in logged.tables.items()})
    computed.data.update({f"{k}.json": d for k, d in logged.data.items()})


def compute_outputs(cfg: ExperimentConfig, result: Result, model: Any, ds: Dataset, *,
                    setting: str, scratch: Path | None = None,
                    out: str | Path | None = None) -> RunOutputs:
    """Compute a run's figures, tables and predictions; write ``--out``'s part.

    With ``scratch`` (a tracked run), everything the record logs: the MAE/MSE bars, the
    intervals' figure and table, the family's outputs and its run figures (started on the
    worker processes while the bars and predictions are made here), the test rows'
    predictions, the figures rendered as PNG files in ``scratch``.
    With ``out``, the same figures, tables and data, for every family, written all or
    nothing (flat: ``<name>.png``, ``<name>.csv``, ``<name>.json``); the predictions only
    when tracked.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run.
    result : Result
        Its result.
    model : estimator
        The fitted model (with intervals, the conformal wrapper).
    ds : Dataset
        The data it was fitted on.
    setting : str
        The run's label, in the figures' titles.
    scratch : Path, optional
        A directory for a tracked run's PNG files (``None``: not tracked).
    out : str or Path, optional
        ``evaluate --out DIR``.

    Returns
    -------
    RunOutputs
        What was computed, the figures' files and the files written in ``out``.

    Raises
    ------
    OutputError
        ``out`` cannot be written (none of its files is left then).
    TrackingError
        ``scratch`` cannot take a figure.
    """
    family = cfg.family
    fitted = family_model(model)
    computed = RunOutputs(rows=ds.split(family.inputs(cfg, ds)))
    if out is None and scratch is None:
        return computed
    shown = interval_artifacts(cfg, ds, model, setting)
    own = (family.outputs(fitted, ds, setting) if family.writes_outputs else None) or Artifacts()
    # the family's run figures start on the worker processes while the rest is drawn here
    finish = family.begin_artifacts(cfg, ds, fitted, setting)
    bars = _run_bars(result, ds, setting)
    if scratch is not None:
        from ..tracking.serving import prediction_frame  # (MLflow's types): a tracked run only

        computed.predictions = prediction_frame(model, computed.rows[1], result.targets)
    extra = finish()
    if out is not None:
        computed.written = write_artifacts(
            _merged(Artifacts(figures=bars), shown, own, extra), out)
    if scratch is not None:
        _tracked(computed, family.name, shown, own, extra, bars, scratch)
    return computed


@contextlib.contextmanager
def computed_outputs(cfg: ExperimentConfig, result: Result, model: Any, ds: Dataset, *,
                     setting: str, track: bool = True,
                     out: str | Path | None = None) -> Iterator[RunOutputs]:
    """Compute a run's outputs (:func:`compute_outputs`), its PNG files kept while in use.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config run.
    result : Result
        Its result.
    model : estimator
        The fitted model.
    ds : Dataset
        The data it was fitted on.
    setting : str
        The run's label, in the figures' titles.
    track : bool, default=True
        Compute what the MLflow record logs, its figures written in a temporary directory
        removed on exit.
    out : str or Path, optional
        ``evaluate --out DIR``.

    Yields
    ------
    RunOutputs
        What was computed.
    """
    with contextlib.ExitStack() as stack:
        scratch = (Path(stack.enter_context(tempfile.TemporaryDirectory(
            prefix="workbench-outputs-"))) if track else None)
        yield compute_outputs(cfg, result, model, ds, setting=setting, scratch=scratch,
                              out=out)
