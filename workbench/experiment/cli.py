"""The ``workbench`` command: a thin shell over functions the tests call directly.

Each command imports what it needs when it runs: ``workbench --help`` and ``workbench
simulate`` never load MLflow, Optuna or SHAP (nor, for ``--help``, scikit-learn). Progress
and messages go through :mod:`logging` (logger ``workbench``, to standard error)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import subprocess
import sys
import time
from pathlib import Path

from .errors import ConfigError, StorageError, TrackingError, UsageError, redact, redact_urls
from .startup import setup_logging

log = logging.getLogger("workbench")


def _write_json(path: str, payload: dict) -> None:
    from .outputs import write_file

    write_file(path, json.dumps(payload, indent=2) + "\n", "--json")  # never half-written


def _check_outputs(args) -> None:
    """Every output location (``--json``, ``--out``) is writable, and ``--register`` has a
    store to register in, before anything is loaded or fitted."""
    from .outputs import check_dir, check_file

    name = getattr(args, "register", None)
    if name is not None:
        if args.no_track:
            raise UsageError("--register needs the tracking store; drop --no-track")
        if not name.strip() or name != name.strip() or any(c in name for c in "/:@") \
                or name in (".", ".."):
            raise UsageError(f"--register {name!r}: a registered model's name cannot be "
                             "empty, start or end with a space, or contain '/', ':' or '@'")
    if args.json:
        check_file(args.json, "--json")
    if getattr(args, "out", None) is not None:
        check_dir(args.out, "--out")


def _check_before_work(cfg, args, storage: str | None = None, hint: str | None = None):
    """Fail on bad data, an unusable Optuna ``storage`` or an unusable MLflow store before
    any fitting or searching; returns the tracker (``None`` with ``--no-track``). Nothing is
    written until every check has passed (then the tracking store is created)."""
    from .config import load_dataset

    load_dataset(cfg)
    tracker = None
    if not args.no_track:
        from .record import tracker_for
        from .tracking.uris import check_store_uri

        tracker = tracker_for(cfg, args.tracking_uri)
        check_store_uri(tracker.tracking_uri)  # writes nothing
    if storage is not None:
        _check_storage(storage, getattr(args, "repair", False), hint)
    if tracker is not None:
        from .lifecycle import prepare_store

        prepare_store(tracker)  # one process at a time creates a new store
    return tracker


def _check_storage(storage: str, repair: bool, hint: str | None) -> None:
    """The Optuna storage can be used (nothing written); with ``--repair``, a damaged journal
    file is repaired first (the one write of the checks)."""
    from .sweep.storage import check_storage, repair_journal

    if repair:
        done = repair_journal(storage, Path.cwd())
        log.info("%s", done if done is not None else
                 f"Optuna journal {storage} is not damaged: nothing to repair")
    check_storage(storage, Path.cwd(), hint=hint)


def _repair_hint(args) -> str:
    """What repairs a damaged journal: this command line with ``--repair`` (passwords
    hidden)."""
    import shlex
    from urllib.parse import urlsplit

    def hidden(word: str) -> str:
        try:
            if "://" in word and urlsplit(word).password:
                return "URI-WITH-PASSWORD"
        except ValueError:
            return "URI"
        return word

    return shlex.join(["workbench", *map(hidden, args.argv), "--repair"])


def _experiment_views(uri: str, port: int) -> list[tuple[str, str]]:
    """The UI's address of each experiment in the store that has the workbench's runs view
    (its runs' test MAE per target side by side); none if the store cannot be read now (the
    UI reports that itself)."""
    from .tracking.runs import RUNS_VIEW, SHARED_VIEW_PREFIX
    from .tracking.uris import sqlite_path, ui_url

    path = sqlite_path(uri)
    if uri.startswith("sqlite:") and (path is None or not path.is_file()):
        return []  # nothing stored yet; reading would create the database
    try:
        from mlflow import MlflowClient

        experiments = MlflowClient(uri).search_experiments()
    except Exception as exc:  # a locked or unreachable store: the UI shows the problem
        log.debug("could not list the experiments of %s: %s", redact(uri), exc)
        return []
    return [(e.name, ui_url(port, e.experiment_id, RUNS_VIEW)) for e in experiments
            if SHARED_VIEW_PREFIX + RUNS_VIEW in e.tags]


def _cmd_ui(args) -> int:
    from .tracking.uris import check_store_uri, resolve_tracking_uri, ui_url

    uri = resolve_tracking_uri(args.tracking_uri, None, Path.cwd())
    # the stores checked as every command checks them, before a server starts (which would
    # print a traceback, or sit on a store it cannot read)
    check_store_uri(uri)
    storage = args.storage or "mlruns/optuna.journal"
    serve_studies = args.storage is not None or (Path.cwd() / storage).is_file()
    if serve_studies:
        from .sweep.storage import check_storage

        check_storage(storage, Path.cwd())
    cmds = [ui_command(uri, args.port, args.workers)]
    print(f"MLflow UI for {redact(uri)} at {ui_url(args.port)}", flush=True)
    for name, url in _experiment_views(uri, args.port):
        print(f"  {name}: {url}", flush=True)
    print("  (a run's own page opens in MLflow's GenAI view until the sidebar's \"Model "
          "training\" switch is clicked once; the browser remembers it)", flush=True)
    if serve_studies:  # the studies beside the runs
        from .sweep.storage import dashboard_command

        cmds.append(dashboard_command(storage, args.dashboard_port, Path.cwd()))
        print(f"Optuna dashboard for {redact(storage)} at "
              f"http://127.0.0.1:{args.dashboard_port}", flush=True)
    print("Ctrl-C stops", "them" if len(cmds) > 1 else "it", flush=True)
    procs = [subprocess.Popen(cmd, env=ui_env()) for cmd in cmds]
    try:
        while all(p.poll() is None for p in procs):
            time.sleep(0.5)
        return max(p.returncode or 0 for p in procs)
    except KeyboardInterrupt:
        return 0
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


def ui_env() -> dict[str, str]:
    """The environment of the servers ``workbench ui`` starts: this one, with MLflow's server
    jobs off unless ``MLFLOW_SERVER_ENABLE_JOB_EXECUTION`` is set (they serve MLflow's GenAI
    features, which workbench does not use: a job runner and seven worker processes, each
    importing MLflow, started with every server)."""
    env = dict(os.environ)
    env.setdefault("MLFLOW_SERVER_ENABLE_JOB_EXECUTION", "false")
    return env


def ui_command(tracking_uri: str, port: int, workers: int = 1) -> list[str]:
    """The ``mlflow server`` command line serving ``tracking_uri`` on 127.0.0.1 with
    ``workers`` server processes (MLflow's default is 4; one serves a user's browser and
    starts in half the time on 2 cores: 17 s against 32 s to a new store's first answer)."""
    cmd = [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", tracking_uri,
           "--host", "127.0.0.1", "--port", str(port), "--workers", str(workers)]
    if tracking_uri.startswith("sqlite:///"):
        from .tracking.uris import sqlite_path

        path = sqlite_path(tracking_uri)  # None for an in-memory database: no folder
        if path is not None:
            root = path.parent / "artifacts"
            cmd += ["--default-artifact-root", root.resolve().as_uri()]
    return cmd


def _cmd_reproduce(args) -> int:
    from ..parallel import worker_pool
    from .outputs import check_dir
    from .paper import experiments_dir, reproduce

    configs = experiments_dir(args.experiments)  # its configs, before anything else
    check_dir(args.out, "--out")
    tracker = None
    if not args.no_track:  # every store checked before any work, nothing written until then
        from .tracking.runs import Tracker
        from .tracking.uris import check_store_uri, resolve_tracking_uri

        tracker = Tracker(resolve_tracking_uri(args.tracking_uri, None, Path.cwd()),
                          "paper-reproduction")
        check_store_uri(tracker.tracking_uri)
    storage = args.storage
    if storage is None:  # the search's own (relative to the working directory)
        from .config import load_config

        storage = load_config(configs / "paper_search.toml").study.storage
    _check_storage(storage, args.repair, _repair_hint(args))
    if tracker is not None:
        from .lifecycle import prepare_store

        prepare_store(tracker)
    with worker_pool(-1, eager=True):  # forked before any thread of this process
        res = reproduce(args.out, tracking_uri=args.tracking_uri, storage=args.storage,
                        quick=args.quick, track=not args.no_track, seed=args.seed,
                        experiments=configs)
    s = res.settings
    print(f"paper settings: average test MAE {s['paper'].model.avg('test_mae'):.3f} MHz "
          f"(control program {s['paper'].prior.avg('test_mae'):.3f}); improved "
          f"{s['improved'].model.avg('test_mae'):.3f}; nested-CV search "
          f"{s['search'].model.avg('test_mae'):.3f}")
    written = len({path for paths in res.figures.values() for path in paths})
    print(f"wrote {Path(args.out) / 'README.md'} and {written} figures (of {len(res.figures)} "
          f"numbered figures) in {res.wall_s:.0f} s")
    return 0


def _cmd_sweep(args) -> int:
    from .config import load_config
    from .evaluate import format_table
    from .sweep.search import run_sweep  # imports Optuna only for sweeps

    cfg = _without_intervals(load_config(args.config).with_study(
        trials=args.trials, workers=args.workers, storage=args.storage), args)
    _check_outputs(args)
    tracker = _check_before_work(cfg, args, cfg.study.storage, _repair_hint(args))
    from ..parallel import effective_n_jobs, worker_pool
    from .lifecycle import TrialRecorder, command_run

    # worker processes for the sweep's workers (--workers), the trials' fits, the refits,
    # the curves and the figures, forked before this process starts any thread (the run's
    # heartbeat); the run is visible while it searches and ends FINISHED only once every
    # output is written
    processes = max(effective_n_jobs(cfg.jobs), cfg.study.workers)
    with worker_pool(processes, eager=True), command_run(tracker, "sweep", cfg.name) as run_id:
        sweep = run_sweep(cfg, on_trial=TrialRecorder(tracker, run_id) if run_id else None)
        result = sweep.result
        if not args.no_track:
            from .record import record

            # logged with the chosen configuration (the family's chosen settings too)
            result.mlflow = record(sweep.config, result, sweep.model, sweep.dataset,
                                   kind="sweep", tracking_uri=args.tracking_uri, sweep=sweep,
                                   run_id=run_id, register=args.register)
        result.wall_s = _wall()
        if run_id is not None:  # the same figure in MLflow, the output and --json
            from .record import record_wall_time

            record_wall_time(sweep.config, result, tracking_uri=args.tracking_uri, run_id=run_id)
        if args.json:
            _write_json(args.json, result.to_json())
    print(format_table(result))
    _print_registered(result)
    if args.json:
        print(f"wrote {args.json}")
    return 0


#: Modules the MLflow records of a run import (SHAP's plots, MLflow's datasets and models).
RECORD_MODULES = ("shap", "mlflow.data.pandas_dataset", "mlflow.pyfunc", "mlflow.models",
                  "workbench.experiment.serving")


def _prefetch(modules) -> None:
    """Import ``modules`` in a background thread (errors ignored: the real import reports
    them); call it once the worker processes are forked (no fork while it runs)."""
    import importlib
    import threading

    def load():
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception:
                pass

    threading.Thread(target=load, name="workbench-prefetch", daemon=True).start()


def _print_registered(result) -> None:
    if "registered_model" in result.mlflow:
        m = result.mlflow
        print(f"registered {m['registered_model']} version {m['registered_version']} "
              f"({m['registered_uri']})")


def _cmd_evaluate(args) -> int:
    from .config import load_config
    from .evaluate import evaluate, format_table

    cfg = _without_intervals(load_config(args.config), args)
    if args.jobs is not None:
        cfg = dataclasses.replace(cfg, n_jobs=args.jobs)
    if args.nested is not None:
        cfg = dataclasses.replace(cfg, evaluation=cfg.evaluation.model_copy(
            update={"nested_folds": args.nested}))
    from .evaluate import has_outputs, outputs

    if args.out is not None and not has_outputs(cfg):
        raise UsageError(f"--out writes a model family's tables and figures and the "
                         f"prediction intervals'; family {cfg.family.name!r} has none and "
                         f"[intervals] is off ({args.config})")
    _check_outputs(args)
    tracker = _check_before_work(cfg, args)
    from ..parallel import worker_pool
    from .lifecycle import command_run

    # one set of worker processes for the fit, the curves and the figures, forked before
    # this process starts any thread (the run's heartbeat, the prefetch); the run ends
    # FINISHED only once every output is written
    with worker_pool(cfg.jobs, eager=True), \
            command_run(tracker, "evaluate", cfg.name) as run_id:
        if tracker is not None:  # what the records need, loaded while the model fits
            _prefetch(RECORD_MODULES)
        run = evaluate(cfg, return_model=True)
        result = run.result
        if args.out is not None:
            from .outputs import write_artifacts

            extra = outputs(cfg, run.model, run.dataset, f"evaluate of {cfg.name}")
            result.outputs = {k: str(v) for k, v in write_artifacts(extra, args.out).items()}
        if not args.no_track:
            from .record import record

            result.mlflow = record(cfg, result, run.model, run.dataset, kind="evaluate",
                                   tracking_uri=args.tracking_uri, run_id=run_id,
                                   register=args.register)
        result.wall_s = _wall()
        if run_id is not None:  # the same figure in MLflow, the output and --json
            from .record import record_wall_time

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


def _cmd_init(args) -> int:
    import shlex

    from .init import init_config

    done = init_config(args.data, prior=args.prior, targets=args.target, features=args.features,
                       split_column=args.split_column, test_fraction=args.test_fraction,
                       split_seed=args.split_seed, name=args.name, out=args.out,
                       force=args.force, group_column=args.group_column)
    if done.defaulted:
        left = "; not taken: " + ", ".join(f"{c!r} ({why})" for c, why in done.skipped.items())
        print(f"features: {', '.join(done.features) or '(none)'} (every other numeric column"
              f"{left if done.skipped else ''}; --features chooses)")
    print(f"wrote {done.path} ({done.n_train} training rows, {done.n_test} test rows)")
    for column, n in done.group_hints.items():
        print(f"note: column {column!r} repeats {n} values over the rows; if rows that share "
              f"one are alike (a device, a date), --group-column {shlex.quote(column)} keeps "
              f"each whole in one CV fold (plain folds reward what only repeats within it)")
    print(f"next: workbench evaluate {shlex.quote(str(done.path))}\n      workbench ui")
    return 0


def _cmd_predict(args) -> int:
    from .predict import predict_csv
    from .tracking.uris import resolve_tracking_uri

    uri = resolve_tracking_uri(args.tracking_uri, None, Path.cwd())
    done = predict_csv(args.model, args.data, args.out, tracking_uri=uri)
    print(f"wrote {done.path} ({done.rows} rows: {', '.join(done.targets)}"
          f"{' with intervals' if done.intervals else ''})")
    return 0


def _cmd_design(args) -> int:
    from .config import load_config
    from .design import design_csv

    cfg = load_config(args.config)
    if args.jobs is not None:
        cfg = dataclasses.replace(cfg, n_jobs=args.jobs)
    from ..parallel import worker_pool

    with worker_pool(cfg.jobs, eager=True):
        done = design_csv(cfg, args.candidates, args.n, args.out, args.criterion)
    print(f"wrote {args.out}: {len(done.chosen)} of {done.n_candidates} candidates "
          f"({'I' if args.criterion == 'i' else 'D'}-optimal for {done.problem.what}; model "
          f"fitted on {done.n_rows} training rows; {_wall():.1f} s)")
    return 0


_START = [0.0]


def _wall() -> float:
    """The whole command's wall time so far."""
    import time

    return time.perf_counter() - _START[0]


def _cmd_simulate(args) -> int:
    from ..simulate import Mismatch, measure, simulate, write_simulation

    if args.settings is not None and args.experiments is not None:
        raise UsageError("--settings measures the rows of its CSV; drop --experiments")
    if args.noise_seed is not None and args.settings is None:
        raise UsageError("--noise-seed needs --settings (simulate's noise follows --seed)")
    try:
        if args.mismatch is None:
            mismatch = Mismatch.default()
        elif args.mismatch == ["none"]:
            mismatch = Mismatch.none()
        else:
            mismatch = Mismatch.only(*args.mismatch)
        shape = None
        if args.shape is not None:
            rows, sep, cols = args.shape.lower().partition("x")
            if not (sep and rows.isdigit() and cols.isdigit()):
                raise ValueError(f"--shape must be RxC (e.g. 3x3), got {args.shape!r}")
            shape = (int(rows), int(cols))
        if args.settings is None:
            sites = args.sites if args.sites is not None or args.topology == "grid" else 5
            sim = simulate(sites, 136 if args.experiments is None else args.experiments,
                           seed=args.seed, mismatch=mismatch, topology=args.topology,
                           shape=shape, parasitic=args.parasitic)
        else:
            import re

            from ..datasets.csv import _numeric, _read

            # the CSV checks of every data file (empty, not a CSV, wrong delimiter, ragged
            # rows), then the bias columns as numbers; measure() says which are missing
            path = Path(args.settings)
            frame = _read(path, min_columns=2)
            bias = [c for c in frame.columns if re.fullmatch(r"v_[qc][1-9][0-9]*", c)]
            settings = _numeric(frame, bias, path)
            sim = measure(settings, seed=args.seed, mismatch=mismatch, topology=args.topology,
                          n_sites=args.sites, shape=shape, parasitic=args.parasitic,
                          noise_seed=args.noise_seed)
        csv_path, truth_path = write_simulation(sim, args.out)
    except (ValueError, OSError) as exc:
        raise UsageError(str(exc)) from None
    prior = sim.data.filter(like="model_E").to_numpy()
    measured = sim.data.filter(like="measured_E").to_numpy()
    rows = (f"{len(sim.data)} experiments" if args.settings is None
            else f"measured {len(sim.data)} settings")
    print(f"wrote {csv_path} ({rows}, {sim.truth['n_sites']} sites, "
          f"{sim.truth['graph']['topology']}; prior MAE "
          f"{abs(prior - measured).mean():.3f} MHz) and {truth_path}")
    return 0


def _without_intervals(cfg, args):
    """``cfg`` with ``[intervals]`` switched off when ``--no-intervals`` was given."""
    if not args.no_intervals:
        return cfg
    return dataclasses.replace(cfg, intervals=cfg.intervals.model_copy(
        update={"enabled": False}))


def _model_args(parser: argparse.ArgumentParser) -> None:
    """Options of the commands that fit a config's model (evaluate, sweep)."""
    parser.add_argument("--no-intervals", action="store_true",
                        help="no prediction intervals (overrides [intervals] enabled; "
                        "the default method 'oof' fits nothing more, 'cv_plus' refits the "
                        "model once per fold)")
    _tracking_args(parser, register=True)


def _tracking_args(parser: argparse.ArgumentParser, register: bool = False) -> None:
    parser.add_argument("--tracking-uri", default=None,
                        help="MLflow store (default: $MLFLOW_TRACKING_URI, then the config's "
                        "[tracking], then sqlite:///mlruns/mlflow.db)")
    parser.add_argument("--no-track", action="store_true", help="do not log to MLflow")
    if register:
        parser.add_argument("--register", metavar="NAME", default=None,
                            help="register the model in the store's Model Registry as NAME; "
                            "the new version gets the alias 'champion' "
                            "(then: workbench predict models:/NAME@champion ...)")


def _repair_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repair", action="store_true",
                        help="first repair a damaged Optuna journal file: every complete "
                        "record is kept (the original stays as FILE.damaged), then the "
                        "command goes on")


class _Parser(argparse.ArgumentParser):
    """Bad arguments end in one line, ``workbench: error: ...`` (exit code 2), without the
    usage block (``--help`` shows it); the command's subparsers are of this class too."""

    def error(self, message: str):
        if "required: command" in message:
            message += f" ({', '.join(COMMANDS)}; see workbench --help)"
        self.exit(2, f"workbench: error: {message}\n")


COMMANDS = ("init", "evaluate", "sweep", "predict", "reproduce", "ui", "simulate")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="workbench", description="Base boosting workbench.")
    sub = parser.add_subparsers(dest="command", required=True)
    ini = sub.add_parser("init", help="write a first config for a CSV of your own (then: "
                         "workbench evaluate CONFIG)")
    ini.add_argument("data", metavar="DATA.csv",
                     help="the CSV: one row per experiment, a header naming the columns")
    ini.add_argument("--prior", nargs="+", required=True, metavar="COL",
                     help="the physics model's prediction of each target, in the targets' order")
    ini.add_argument("--target", nargs="+", required=True, metavar="COL",
                     help="the measured values to predict")
    ini.add_argument("--features", nargs="*", default=None, metavar="COL",
                     help="the basis' inputs besides the prior (default: every other numeric "
                     "column but the split column; --features alone: none)")
    ini.add_argument("--group-column", metavar="COL", default=None,
                     help="a column naming each row's group (e.g. its device): CV folds keep "
                     "each group whole")
    split = ini.add_mutually_exclusive_group()
    split.add_argument("--split-column", metavar="COL", default=None,
                       help="a column saying 'train' or 'test' for each row")
    split.add_argument("--test-fraction", type=_fraction, default=None, metavar="F",
                       help="the share of rows held out for testing, drawn at random "
                       "(default: 0.3 when there is no --split-column)")
    ini.add_argument("--split-seed", type=_seed, default=None, metavar="N",
                     help="the seed of the random split (default: 0)")
    ini.add_argument("--name", default=None,
                     help="the config's name (its MLflow experiment; default: the CSV's name "
                     "without .csv)")
    ini.add_argument("--out", default=None, metavar="PATH",
                     help="the config file to write (default: NAME.toml here)")
    ini.add_argument("--force", action="store_true", help="overwrite an existing --out")
    ini.set_defaults(func=_cmd_init)

    ev = sub.add_parser("evaluate", help="fit a config's model on the training rows and score "
                        "prior and model on the test rows")
    ev.add_argument("config",
                    help="experiment config (TOML), e.g. experiments/paper_main_body.toml")
    ev.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ev.add_argument("--jobs", type=_count, default=None, metavar="N",
                    help="processes for independent work: targets, folds, curve points "
                    "(overrides the config's n_jobs; default: every core; the results do "
                    "not depend on it)")
    ev.add_argument("--nested", type=_nested_folds, default=None, metavar="K",
                    help="also a nested CV over all rows with K outer folds, every choice "
                    "remade in each (K more fits of the whole model; overrides [evaluation] "
                    "nested_folds; 0: none)")
    ev.add_argument("--out", metavar="DIR", default=None,
                    help="write the model family's tables (CSV) and figures (PNG) to DIR "
                    "(family hamiltonian: coefficients, corrected parameters, selection)")
    _model_args(ev)
    ev.set_defaults(func=_cmd_evaluate)

    sw = sub.add_parser("sweep", help="nested-CV hyperparameter search (Optuna), then one "
                        "evaluation of the chosen configuration on the test rows")
    sw.add_argument("config", help="experiment config (TOML) with [search], [cv], [study]")
    sw.add_argument("--trials", type=_count, default=None, help="trials per study")
    sw.add_argument("--workers", type=_count, default=None,
                    help="processes working on the shared storage")
    sw.add_argument("--storage", default=None,
                    help="Optuna storage: a journal file path or an RDB URL")
    _repair_arg(sw)
    sw.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    _model_args(sw)
    sw.set_defaults(func=_cmd_sweep)

    pr = sub.add_parser("predict", help="predict the rows of a CSV with a logged or "
                        "registered model (targets, and intervals when the model has them)")
    pr.add_argument("model", help="a run id, runs:/<run_id>/model, models:/NAME/VERSION, "
                    "models:/NAME@ALIAS (e.g. models:/device@champion) or models:/<model_id>")
    pr.add_argument("data", help="CSV with the model's input columns by name (other columns "
                    "are copied to the output)")
    pr.add_argument("--out", required=True, metavar="PATH", help="CSV file to write")
    pr.add_argument("--tracking-uri", default=None,
                    help="MLflow store holding the model (default: $MLFLOW_TRACKING_URI, "
                    "then sqlite:///mlruns/mlflow.db)")
    pr.set_defaults(func=_cmd_predict)

    rep = sub.add_parser("reproduce", help="compute the paper's results and figures into a "
                         "report folder and the MLflow experiment paper-reproduction")
    rep.add_argument("--out", default="reports", help="output folder (default: reports)")
    rep.add_argument("--quick", action="store_true",
                     help="fewer curve points, SHAP rows, search trials and folds (for tests)")
    rep.add_argument("--seed", type=int, default=0)
    rep.add_argument("--experiments", metavar="DIR", default=None,
                     help="folder with the configs it runs (paper_main_body.toml, "
                     "paper_improved.toml, paper_search.toml, hamiltonian.toml; default: the "
                     "checkout's experiments/, else ./experiments)")
    rep.add_argument("--storage", default=None,
                     help="Optuna storage of the search (a journal file path or an RDB URL)")
    _repair_arg(rep)
    _tracking_args(rep)
    rep.set_defaults(func=_cmd_reproduce)

    ui = sub.add_parser("ui", help="start the MLflow UI (and optuna-dashboard on the studies) "
                        "at 127.0.0.1")
    ui.add_argument("--tracking-uri", default=None,
                    help="store to serve (default: $MLFLOW_TRACKING_URI or mlruns/mlflow.db)")
    ui.add_argument("--port", type=int, default=5000)
    ui.add_argument("--workers", type=_count, default=1,
                    help="MLflow server processes (default 1: one user's browser)")
    ui.add_argument("--storage", default=None,
                    help="also serve the Optuna studies of this storage (journal file or RDB "
                    "URL) with optuna-dashboard (default: mlruns/optuna.journal if present)")
    ui.add_argument("--dashboard-port", type=int, default=8080)
    ui.set_defaults(func=_cmd_ui)

    des = sub.add_parser("design", help="choose the settings to measure next: the candidates "
                         "whose measurement would most lower the model's uncertainty")
    des.add_argument("config", help="experiment config (TOML); its model is fitted on the "
                     "config's training rows")
    des.add_argument("--candidates", required=True, metavar="CANDIDATES.csv",
                     help="settings that could be measured: the model's input columns (features, "
                     "the control model's prediction, Hamiltonian parameters), no measurement")
    des.add_argument("--n", type=_count, required=True, help="how many to choose (a batch)")
    des.add_argument("--out", required=True, metavar="NEXT.csv",
                     help="the chosen rows, in the order chosen, with the reason for each")
    des.add_argument("--criterion", choices=("i", "d"), default="i",
                     help="i: lower the average predictive variance over the candidates "
                     "(default); d: most information about the model's coefficients (log det)")
    des.add_argument("--jobs", type=_count, default=None, help="worker processes (default: "
                     "the config's n_jobs)")
    des.set_defaults(func=_cmd_design)

    sim = sub.add_parser("simulate", help="simulate a device of coupled qubits and write a CSV "
                         "(plus a .truth.json sidecar with the graph and injected mismatches); "
                         "with --settings, measure given bias settings on the seed's device")
    sim.add_argument("--sites", type=int, default=None,
                     help="qubits in the chain or ring (>= 2; default 5, with --settings the "
                     "number of v_q columns; grid: rows x cols)")
    sim.add_argument("--topology", choices=("chain", "ring", "grid"), default="chain")
    sim.add_argument("--shape", default=None, metavar="RxC", help="grid rows x columns")
    sim.add_argument("--parasitic", choices=("next_nearest", "diagonal", "none"), default=None,
                     help="where parasitic couplings go (default: grid diagonal, else "
                     "next-nearest)")
    sim.add_argument("--experiments", type=int, default=None,
                     help="random bias settings to simulate (default 136; not with --settings)")
    sim.add_argument("--settings", metavar="SETTINGS.csv", default=None,
                     help="measure these rows instead (columns v_q1..v_qN, v_c1..v_cE, others "
                     "ignored) on the device --seed and the options above make; voltages "
                     "outside the simulated ranges are allowed")
    sim.add_argument("--noise-seed", type=int, default=None,
                     help="with --settings: seed of the noise and misidentified peaks (default: "
                     "derived from --seed and the settings, so the same settings measure the "
                     "same)")
    sim.add_argument("--seed", type=int, default=0, help="the device (and, without --settings, "
                     "the settings and noise)")
    sim.add_argument("--mismatch", nargs="+", metavar="NAME", default=None,
                     help="mechanisms to switch on (default: all at realistic sizes; 'none': "
                     "the control model is exact)")
    sim.add_argument("--out", required=True, help="CSV file to write")
    sim.set_defaults(func=_cmd_simulate)
    return parser


def _count(value: str) -> int:
    """A command-line count: an integer >= 1."""
    try:
        number = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value[:40]!r}") from None
    if number < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {number}")
    return number


def _fraction(value: str) -> float:
    """``--test-fraction``: a number strictly between 0 and 1."""
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not 0.0 < number < 1.0:
        raise argparse.ArgumentTypeError(f"expected a number between 0 and 1 (exclusive), got "
                                         f"{value[:40]!r}")
    return number


def _seed(value: str) -> int:
    """``--split-seed``: an integer >= 0."""
    try:
        number = int(value)
    except ValueError:
        number = -1
    if number < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value[:40]!r}")
    return number


def _nested_folds(value: str) -> int:
    """``--nested``: 0 (none) or a number of outer folds >= 2."""
    try:
        number = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 0 or an integer >= 2, got "
                                         f"{value[:40]!r}") from None
    if number < 0 or number == 1:
        raise argparse.ArgumentTypeError(f"expected 0 (none) or an integer >= 2 outer folds, "
                                         f"got {number}")
    return number


def main(argv: list[str] | None = None) -> int:
    import time

    _START[0] = time.perf_counter()
    args = build_parser().parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    setup_logging()
    from ..datasets import DatasetError, DataUnavailableError
    from .signals import MESSAGE, handle_signals

    try:
        with handle_signals():  # SIGINT/SIGTERM: runs end KILLED, one line, exit 130/143
            return args.func(args)
    except DataUnavailableError as exc:  # the benchmark's manual download steps, as written
        print(f"workbench: error: {exc}", file=sys.stderr)
        return 2
    except (ConfigError, DatasetError, TrackingError, UsageError, StorageError) as exc:
        print(error_line(exc), file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"workbench: {MESSAGE}", file=sys.stderr)
        return getattr(exc, "code", 130)


#: Most characters of the error line ``workbench: error: ...``.
MAX_ERROR_LINE = 299


def error_line(exc: BaseException) -> str:
    """``workbench: error: <message>`` as one line of at most :data:`MAX_ERROR_LINE`
    characters (messages are written short; this is the last guard), passwords redacted."""
    text = redact_urls(" ".join(str(exc).split()))
    line = f"workbench: error: {text}"
    return line if len(line) <= MAX_ERROR_LINE else line[:MAX_ERROR_LINE - 3] + "..."


if __name__ == "__main__":
    raise SystemExit(main())
