"""The ``workbench`` command: a thin shell over functions the tests call directly."""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import subprocess
import sys
import time
from pathlib import Path

from ..datasets import DatasetError, DataUnavailableError
from ..simulate import Mismatch, simulate, write_simulation
from .config import ConfigError, load_config, load_dataset
from .evaluate import evaluate, format_table
from .tracking import TrackingError


def _write_json(path: str, payload: dict) -> None:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(payload, indent=2) + "\n")
    tmp.replace(out)  # never leave a half-written result


def _check_before_work(cfg, args):
    """Fail on bad data or an unusable MLflow store before any fitting or searching; returns
    the tracker (``None`` with ``--no-track``)."""
    load_dataset(cfg)
    if not args.no_track:
        from .lifecycle import prepare_store
        from .record import tracker_for

        tracker = tracker_for(cfg, args.tracking_uri)
        prepare_store(tracker)  # one process at a time creates a new store
        return tracker
    return None


def _cmd_ui(args) -> int:
    from .tracking import _redact, resolve_tracking_uri

    uri = resolve_tracking_uri(args.tracking_uri, None, Path.cwd())
    cmds = [ui_command(uri, args.port)]
    print(f"MLflow UI for {_redact(uri)} at http://127.0.0.1:{args.port}", flush=True)
    storage = args.storage or "mlruns/optuna.journal"
    if args.storage or (Path.cwd() / storage).is_file():  # the studies beside the runs
        from .studies import dashboard_command, redact

        cmds.append(dashboard_command(storage, args.dashboard_port, Path.cwd()))
        print(f"Optuna dashboard for {redact(storage)} at "
              f"http://127.0.0.1:{args.dashboard_port}", flush=True)
    print("Ctrl-C stops", "them" if len(cmds) > 1 else "it", flush=True)
    procs = [subprocess.Popen(cmd) for cmd in cmds]
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


def ui_command(tracking_uri: str, port: int) -> list[str]:
    """The ``mlflow server`` command line serving ``tracking_uri`` on 127.0.0.1."""
    cmd = [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", tracking_uri,
           "--host", "127.0.0.1", "--port", str(port)]
    if tracking_uri.startswith("sqlite:///"):
        from .tracking import _sqlite_path

        root = _sqlite_path(tracking_uri).parent / "artifacts"
        cmd += ["--default-artifact-root", root.resolve().as_uri()]
    return cmd


def _cmd_reproduce(args) -> int:
    from .reproduce import reproduce

    res = reproduce(args.out, tracking_uri=args.tracking_uri, storage=args.storage,
                    quick=args.quick,
                    track=not args.no_track, seed=args.seed)
    print(f"paper settings: average test MAE {res['settings']['paper']['model']['test_mae_avg']:.3f}"
          f" MHz (control program {res['settings']['paper']['prior']['test_mae_avg']:.3f}); "
          f"improved {res['settings']['improved']['model']['test_mae_avg']:.3f}; nested-CV "
          f"search {res['settings']['search']['model']['test_mae_avg']:.3f}")
    print(f"wrote {Path(args.out) / 'README.md'} and {len(res['figures'])} figure entries "
          f"in {res['wall_s']:.0f} s")
    return 0


def _cmd_sweep(args) -> int:
    from .search import run_sweep, with_overrides  # imports Optuna only for sweeps

    from .search import settings_for

    cfg = with_overrides(load_config(args.config), trials=args.trials, workers=args.workers,
                         storage=args.storage)
    tracker = _check_before_work(cfg, args)
    from .lifecycle import TrialRecorder, command_run

    with command_run(tracker, "sweep", cfg.name) as run_id:  # visible while it searches
        result, details = run_sweep(cfg, on_trial=run_id and TrialRecorder(tracker, run_id))
        if not args.no_track:
            from .record import record

            best = {t: settings_for(cfg, t, p) for t, p in zip(result["targets"],
                                                              result["best_params"]) if p}
            # the chosen configuration (family hamiltonian: its [model.hamiltonian] settings)
            result["mlflow"] = record(details["config"], result, details["model"],
                                      details["dataset"], kind="sweep", run_id=run_id,
                                      tracking_uri=args.tracking_uri, details=details,
                                      settings=best)
    print(format_table(result))
    print(f"nested-CV MAE: model {result['nested_cv_mae_avg']:.3f}, prior "
          f"{result['nested_cv_prior_mae_avg']:.3f} (average over targets)")
    if args.json:
        _write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0


def _cmd_evaluate(args) -> int:
    cfg = load_config(args.config)
    if args.jobs is not None:
        cfg = dataclasses.replace(cfg, n_jobs=args.jobs)
    tracker = _check_before_work(cfg, args)
    if args.out is not None and cfg.family != "hamiltonian":
        raise UsageError("--out writes the parameter-space model's tables and figures: it "
                         f"needs a config with [model] family = \"hamiltonian\" ({args.config} "
                         f"has family {cfg.family!r})")
    from .lifecycle import command_run

    with command_run(tracker, "evaluate", cfg.name) as run_id:
        result, model, ds = evaluate(cfg, return_model=True)
        if args.out is not None:
            from .parameters import write_hamiltonian_outputs

            written = write_hamiltonian_outputs(args.out, model, ds, setting=f"evaluate of "
                                                                            f"{cfg.name}")
            result["outputs"] = {k: str(v) for k, v in written.items()}
        if not args.no_track:
            from .record import record

            result["mlflow"] = record(cfg, result, model, ds, kind="evaluate", run_id=run_id,
                                      tracking_uri=args.tracking_uri)
    print(format_table(result))
    if args.out is not None:
        print(f"wrote {', '.join(sorted(Path(p).name for p in result['outputs'].values()))} "
              f"to {args.out}")
    if args.json:
        _write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0


class UsageError(ValueError):
    """Bad command-line values: reported as one line, exit code 2."""


def _cmd_simulate(args) -> int:
    try:
        if args.mismatch is None:
            mismatch = Mismatch.default()
        elif args.mismatch == ["none"]:
            mismatch = Mismatch.none()
        else:
            mismatch = Mismatch.only(*args.mismatch)
        sim = simulate(args.sites, args.experiments, seed=args.seed, mismatch=mismatch)
        csv_path, truth_path = write_simulation(sim, args.out)
    except (ValueError, OSError) as exc:
        raise UsageError(str(exc)) from None
    prior = sim.data.filter(like="model_E").to_numpy()
    measured = sim.data.filter(like="measured_E").to_numpy()
    print(f"wrote {csv_path} ({len(sim.data)} experiments, {args.sites} sites; prior MAE "
          f"{abs(prior - measured).mean():.3f} MHz) and {truth_path}")
    return 0


def _tracking_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--tracking-uri", default=None,
                        help="MLflow store (default: $MLFLOW_TRACKING_URI, then the config's "
                        "[tracking], then sqlite:///mlruns/mlflow.db)")
    parser.add_argument("--no-track", action="store_true", help="do not log to MLflow")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="workbench", description="Base boosting workbench.")
    sub = parser.add_subparsers(dest="command", required=True)
    ev = sub.add_parser("evaluate", help="fit a config's model on the training rows and score "
                        "prior and model on the test rows")
    ev.add_argument("config", help="experiment config (TOML), e.g. experiments/paper_main_body.toml")
    ev.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ev.add_argument("--jobs", type=int, default=None, metavar="N",
                    help="targets fitted in parallel (overrides the config's n_jobs)")
    ev.add_argument("--out", metavar="DIR", default=None,
                    help="family hamiltonian: write the coefficient, corrected-parameter and "
                    "selection tables (CSV) and figures (PNG) to DIR")
    _tracking_args(ev)
    ev.set_defaults(func=_cmd_evaluate)

    sw = sub.add_parser("sweep", help="nested-CV hyperparameter search (Optuna), then one "
                        "evaluation of the chosen configuration on the test rows")
    sw.add_argument("config", help="experiment config (TOML) with [search], [cv], [study]")
    sw.add_argument("--trials", type=int, default=None, help="trials per study")
    sw.add_argument("--workers", type=int, default=None,
                    help="processes working on the shared storage")
    sw.add_argument("--storage", default=None,
                    help="Optuna storage: a journal file path or an RDB URL")
    sw.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    _tracking_args(sw)
    sw.set_defaults(func=_cmd_sweep)

    rep = sub.add_parser("reproduce", help="compute the paper's results and figures into a "
                         "report folder and the MLflow experiment paper-reproduction")
    rep.add_argument("--out", default="reports", help="output folder (default: reports)")
    rep.add_argument("--quick", action="store_true",
                     help="fewer curve points, SHAP rows and search trials (for tests)")
    rep.add_argument("--seed", type=int, default=0)
    rep.add_argument("--storage", default=None,
                     help="Optuna storage of the search (a journal file path or an RDB URL)")
    _tracking_args(rep)
    rep.set_defaults(func=_cmd_reproduce)

    ui = sub.add_parser("ui", help="start the MLflow UI (and optuna-dashboard on the studies) "
                        "at 127.0.0.1")
    ui.add_argument("--tracking-uri", default=None,
                    help="store to serve (default: $MLFLOW_TRACKING_URI or mlruns/mlflow.db)")
    ui.add_argument("--port", type=int, default=5000)
    ui.add_argument("--storage", default=None,
                    help="also serve the Optuna studies of this storage (journal file or RDB "
                    "URL) with optuna-dashboard (default: mlruns/optuna.journal if present)")
    ui.add_argument("--dashboard-port", type=int, default=8080)
    ui.set_defaults(func=_cmd_ui)

    sim = sub.add_parser("simulate", help="simulate a chain of coupled qubits and write a CSV "
                         "(plus a .truth.json sidecar with the injected mismatches)")
    sim.add_argument("--sites", type=int, default=5, help="qubits in the chain (>= 2)")
    sim.add_argument("--experiments", type=int, default=136, help="rows to simulate")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--mismatch", nargs="+", metavar="NAME", default=None,
                     help="mechanisms to switch on (default: all at realistic sizes; 'none': "
                     "the control model is exact)")
    sim.add_argument("--out", required=True, help="CSV file to write")
    sim.set_defaults(func=_cmd_simulate)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.getLogger("mlflow").setLevel(logging.WARNING)  # keep the per-trial lines readable
    from .lifecycle import MESSAGE, handle_signals

    try:
        with handle_signals():  # SIGINT/SIGTERM: runs end KILLED, one line, exit 130/143
            return args.func(args)
    except (ConfigError, DatasetError, DataUnavailableError, TrackingError, UsageError,
            _storage_error()) as exc:
        print(f"workbench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"workbench: {MESSAGE}", file=sys.stderr)
        return getattr(exc, "code", 130)


def _storage_error() -> type:
    """The Optuna storage's error class, once the storage module is loaded (no Optuna import
    for commands that do not use it)."""
    studies = sys.modules.get("workbench.experiment.studies")
    return studies.StorageError if studies else UsageError


if __name__ == "__main__":
    raise SystemExit(main())
