"""Handlers of the commands that run a config: ``evaluate``, ``sweep``, ``design``, ``reproduce``.

Each checks everything first (:mod:`.preflight`), loads the config's data once
(:func:`~workbench.experiment.runs.prepare.prepare`) and hands that run down.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..process.errors import UsageError
from ..scoring.units import unit_suffix
from .preflight import check_before_work, check_outputs, check_stores, repair_hint

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import ExperimentConfig
    from ..runs.evaluate import Evaluation
    from ..tracking.runs import Tracker

__all__ = ["design", "evaluate", "mark_start", "reproduce", "sweep", "wall"]

_START = [0.0]


def mark_start() -> None:
    """Start the command's clock (:func:`wall`)."""
    _START[0] = time.perf_counter()


def wall() -> float:
    """Return the whole command's wall time so far.

    Returns
    -------
    float
        Seconds since :func:`mark_start`.
    """
    return time.perf_counter() - _START[0]


def _write_json(path: str, payload: dict[str, Any]) -> None:
    from ..process.outputs import write_file

    write_file(path, json.dumps(payload, indent=2) + "\n", "--json")  # never half-written


def _prefetch(modules: Iterable[str]) -> None:
    """Import ``modules`` in a background thread.

    Errors are ignored: the real import reports them. Call it once the worker processes are
    forked (no fork while it runs).
    """
    def load() -> None:
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception:
                pass

    threading.Thread(target=load, name="workbench-prefetch", daemon=True).start()


def _print_registered(result: Any) -> None:
    if "registered_model" in result.mlflow:
        m = result.mlflow
        print(f"registered {m['registered_model']} version {m['registered_version']} "
              f"({m['registered_uri']})")


def reproduce(args: argparse.Namespace) -> int:
    """``workbench reproduce``: the paper's results and figures.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).
    """
    from ...parallel import worker_pool
    from ..paper import experiments_dir
    from ..paper import reproduce as run
    from ..process.outputs import check_dir

    configs = experiments_dir(args.experiments)  # its configs, before anything else
    check_dir(args.out, "--out")
    tracker = None
    if not args.no_track:  # every store checked before any work, nothing written until then
        from ..tracking.runs import Tracker
        from ..tracking.uris import resolve_tracking_uri

        tracker = Tracker(resolve_tracking_uri(args.tracking_uri, None, Path.cwd()),
                          "paper-reproduction")
    storage = args.storage
    if storage is None and args.all:  # the search's own (relative to the working directory)
        from ..runs.prepare import load_config

        storage = load_config(configs / "paper_search.toml").study.storage
    check_stores(tracker, storage, args.repair, repair_hint(args))
    with worker_pool(-1, eager=True):  # forked before any thread of this process
        res = run(args.out, tracking_uri=args.tracking_uri, storage=args.storage,
                  quick=args.quick, track=not args.no_track, random_state=args.random_state,
                  experiments=configs, all_systems=args.all)
    s = res.settings
    search = (f"; nested-CV search {s['search'].model.avg('test_mae'):.3f}" if "search" in s
              else "")
    print(f"paper settings: average test MAE {s['paper'].model.avg('test_mae'):.3f}"
          f"{unit_suffix(s['paper'].unit)} "
          f"(control program {s['paper'].prior.avg('test_mae'):.3f}); improved "
          f"{s['improved'].model.avg('test_mae'):.3f}{search}")
    written = len({path for paths in res.figures.values() for path in paths})
    print(f"wrote {Path(args.out) / 'README.md'} and {written} figures (of {len(res.figures)} "
          f"numbered figures) in {res.wall_s:.0f} s")
    return 0


def sweep(args: argparse.Namespace) -> int:
    """``workbench sweep``: the nested-CV search, then the chosen model's evaluation.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..config import without_intervals
    from ..runs.evaluate import format_table
    from ..runs.prepare import load_config, prepare
    from ..sweep.search import run_sweep  # imports Optuna only for sweeps

    cfg = without_intervals(load_config(args.config, dict(args.overrides)).with_study(
        trials=args.trials, workers=args.workers, storage=args.storage, timeout=args.timeout),
        args.no_intervals)
    check_outputs(args)
    prepared = prepare(cfg)
    tracker = check_before_work(cfg, args, cfg.study.storage, repair_hint(args))
    from ...parallel import effective_n_jobs, worker_pool
    from ..tracking.lifecycle import TrialRecorder, command_run

    # worker processes for the sweep's workers (--workers), the trials' fits, the refits,
    # the curves and the figures, forked before this process starts any thread (the run's
    # heartbeat); the run is visible while it searches and ends FINISHED only once every
    # output is written
    processes = max(effective_n_jobs(cfg.jobs), cfg.study.workers)
    with worker_pool(processes, eager=True), command_run(tracker, "sweep", cfg.name) as run_id:
        recorder = TrialRecorder(tracker, run_id) if tracker is not None and run_id else None
        done = run_sweep(cfg, on_trial=recorder,
                         dataset=prepared.dataset)
        result = done.result
        if not args.no_track:
            from ..runs.record import record
            from ..runs.run_outputs import computed_outputs

            # computed, then logged, with the chosen configuration (the family's chosen
            # settings too)
            with computed_outputs(done.config, result, done.model, done.dataset,
                                  setting=f"sweep of {done.config.name}") as computed:
                result.mlflow = record(done.config, result, done.model, done.dataset,
                                       computed, kind="sweep", tracking_uri=args.tracking_uri,
                                       sweep=done, run_id=run_id, register=args.register)
        from ..sweep.report import figures_of_sweep

        figures_of_sweep(done, args.out, tracker, run_id)
        result.wall_s = wall()
        if run_id is not None:  # the same figure in MLflow, the output and --json
            from ..runs.record import record_wall_time

            record_wall_time(done.config, result, tracking_uri=args.tracking_uri,
                             run_id=run_id)
        if args.json:
            _write_json(args.json, result.to_json())
    print(format_table(result))
    _print_registered(result)
    if args.out is not None:
        print(f"wrote the studies' figures and importances to {args.out}")
    if args.json:
        print(f"wrote {args.json}")
    return 0


def _evaluate_config(args: argparse.Namespace) -> Any:
    """Load the config ``evaluate`` runs: the file's, with the command line's overrides."""
    from ..config import without_intervals
    from ..runs.prepare import load_config

    cfg = without_intervals(load_config(args.config, dict(args.overrides)), args.no_intervals)
    if args.jobs is not None:
        cfg = dataclasses.replace(cfg, n_jobs=args.jobs)
    if args.nested is not None:
        cfg = dataclasses.replace(cfg, evaluation=cfg.evaluation.model_copy(
            update={"nested_folds": args.nested}))
    if args.random_states is not None:
        cfg = dataclasses.replace(cfg, evaluation=cfg.evaluation.model_copy(
            update={"random_states": args.random_states}))
    if cfg.evaluation.random_states and args.register is not None:
        raise UsageError("--register registers one model; with random_states there is one "
                         "per seed (register one: --set random_state=N, without "
                         "random_states)")
    return cfg


def _evaluate_outputs(args: argparse.Namespace, cfg: Any, run: Any, run_id: str | None) -> None:
    """Compute an evaluate's figures, tables and predictions once; write ``--out``, record.

    Sets the result's ``outputs`` (``--out``) and ``mlflow`` (tracked).
    """
    if args.out is None and args.no_track:
        return
    from ..runs.run_outputs import computed_outputs

    result = run.result
    with computed_outputs(cfg, result, run.model, run.dataset,
                          setting=f"evaluate of {cfg.name}", track=not args.no_track,
                          out=args.out) as computed:
        if args.out is not None:
            result.outputs = {k: str(v) for k, v in computed.written.items()}
        if not args.no_track:
            from ..runs.record import record

            result.mlflow = record(cfg, result, run.model, run.dataset, computed,
                                   kind="evaluate", tracking_uri=args.tracking_uri,
                                   run_id=run_id, register=args.register)


def evaluate(args: argparse.Namespace) -> int:
    """``workbench evaluate``: fit a config's model, score it on the test rows.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..runs.evaluate import evaluate as run_evaluate
    from ..runs.evaluate import format_table
    from ..runs.prepare import prepare

    cfg = _evaluate_config(args)
    check_outputs(args)
    prepared = prepare(cfg)
    tracker = check_before_work(cfg, args)
    from ...parallel import worker_pool
    from ..tracking import RECORD_MODULES
    from ..tracking.lifecycle import command_run

    if cfg.evaluation.random_states:
        return _evaluate_seeds(args, cfg, prepared.dataset, tracker)

    # one set of worker processes for the fit, the curves and the figures, forked before
    # this process starts any thread (the run's heartbeat, the prefetch); the run ends
    # FINISHED only once every output is written
    with worker_pool(cfg.jobs, eager=True), \
            command_run(tracker, "evaluate", cfg.name) as run_id:
        if tracker is not None:  # what the records need, loaded while the model fits
            _prefetch(RECORD_MODULES)
        run = run_evaluate(cfg, return_model=True, dataset=prepared.dataset)
        result = run.result
        _evaluate_outputs(args, cfg, run, run_id)
        result.wall_s = wall()
        if run_id is not None:  # the same figure in MLflow, the output and --json
            from ..runs.record import record_wall_time

            record_wall_time(cfg, result, tracking_uri=args.tracking_uri, run_id=run_id)
        if args.json:
            _write_json(args.json, result.to_json())
    print(format_table(result))
    _print_registered(result)
    if args.out is not None:
        print(f"wrote {', '.join(sorted(Path(p).name for p in result.outputs.values()))} "
              f"to {args.out}")
    if args.json:
        print(f"wrote {args.json}")
    return 0


def _evaluate_seeds(args: argparse.Namespace, cfg: ExperimentConfig, dataset: Dataset,
                    tracker: Tracker | None) -> int:
    """``workbench evaluate`` with random_states: a fit per seed, a child run each, a summary."""
    from ...parallel import worker_pool
    from ..runs.seeds import evaluate_seeds, format_seeds_table, seed_artifacts
    from ..tracking.lifecycle import command_run

    def runner(one: ExperimentConfig, fit: Callable[[], Evaluation]) -> Evaluation:
        """Run one seed's fit inside its child run (KILLED with the parent on an interrupt)."""
        if tracker is None:
            return fit()
        from ..runs.record import record_seed
        from ..tracking.serving import prediction_frame

        with tracker.run(f"evaluate {cfg.name} seed {one.random_state}",
                         parent_run_id=run_id, tags={"workbench.kind": "seed"}) as child:
            run = fit()
            X_test = run.dataset.split(one.family.inputs(one, run.dataset))[1]
            predictions = prediction_frame(run.model, X_test, run.result.targets)
            run.result.mlflow = record_seed(one, run, predictions,
                                            tracking_uri=args.tracking_uri, run_id=child)
        return run

    with worker_pool(cfg.jobs, eager=True), \
            command_run(tracker, "evaluate", cfg.name,
                        tags={"workbench.random_states":
                              ",".join(map(str, cfg.evaluation.random_states))}
                        ) as run_id:
        done = evaluate_seeds(cfg, dataset=dataset, runner=runner)
        extra = seed_artifacts(done, f"evaluate of {cfg.name}")
        if args.out is not None:
            from ..process.outputs import write_artifacts

            done.outputs = {k: str(v) for k, v in write_artifacts(extra, args.out).items()}
        done.wall_s = wall()
        if run_id is not None:
            from ..runs.record import record_seeds

            record_seeds(cfg, done, dataset, tracking_uri=args.tracking_uri, run_id=run_id,
                         artifacts=extra)
        if args.json:
            _write_json(args.json, done.to_json())
    print(format_seeds_table(done))
    if done.mlflow:
        print(f"tracked: parent run {done.mlflow['run_id']} with "
              f"{len(done.random_states)} child runs")
    if args.out is not None:
        print(f"wrote {', '.join(sorted(Path(p).name for p in done.outputs.values()))} "
              f"to {args.out}")
    if args.json:
        print(f"wrote {args.json}")
    return 0


def design(args: argparse.Namespace) -> int:
    """``workbench design``: the candidates to measure next.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).
    """
    from ...parallel import worker_pool
    from ..runs.design import design_csv
    from ..runs.prepare import load_config

    cfg = load_config(args.config, dict(args.overrides))
    if args.jobs is not None:
        cfg = dataclasses.replace(cfg, n_jobs=args.jobs)
    with worker_pool(cfg.jobs, eager=True):
        done = design_csv(cfg, args.candidates, args.n, args.out, args.criterion)
    print(f"wrote {args.out}: {len(done.chosen)} of {done.n_candidates} candidates "
          f"({'I' if args.criterion == 'i' else 'D'}-optimal for {done.problem.what}; model "
          f"fitted on {done.n_rows} training rows; {wall():.1f} s)")
    return 0
