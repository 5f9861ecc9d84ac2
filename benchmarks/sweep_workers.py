"""A fixed sweep with 1 and 2 workers: the whole command and the trial phase (prints a table;
no assertions).

    python benchmarks/sweep_workers.py [--config experiments/smoke.toml] [--trials 6]
                                       [--repeats 3] [--only command|trials]

* ``command``: ``workbench sweep CONFIG --no-track --workers N`` as whole processes (start-up,
  search, outer-fold refits, final fit), paired and alternating (1 then 2 workers, then 2
  then 1, ...), each into a fresh temporary journal storage, one BLAS/OpenMP thread per
  process.
* ``trials``: the search phase alone in this process (``sweep.workers.search_in_workers``):
  trials per minute.

Prints every run, the medians, the 2-vs-1 ratio and ``uptime``'s load before and after (the
machine is shared: read the ratios beside the load).
* ``storages``: trials per minute of 1, 2 and 4 sweep processes on one storage (journal
  file, SQLite, PostgreSQL), each process running
  :func:`workbench.experiment.sweep.scheduler.run_study` (heartbeats, stale checks, exact
  budgets) on one shared study; a trial is three "inner folds" of ``--fold-s`` seconds of
  sleep, so the numbers show the scheduler and the storage, not the cores. PostgreSQL
  (pgserver) and ``mlflow server`` start as in tests/services.py; then the median time to
  log one trial as a child run against local SQLite and the server. Not part of the default
  run: ``--only storages``.
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
THREADS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def _commands(args) -> None:
    env = {**os.environ, **THREADS, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    walls: dict[int, list[float]] = {1: [], 2: []}
    for rep in range(args.repeats):
        for workers in ((1, 2) if rep % 2 == 0 else (2, 1)):
            with tempfile.TemporaryDirectory() as tmp:
                argv = [sys.executable, "-m", "workbench.experiment.cli", "sweep", args.config,
                        "--no-track", "--workers", str(workers), "--trials", str(args.trials),
                        "--storage", str(Path(tmp) / "bench.journal")]
                start = time.perf_counter()
                out = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=ROOT)
                wall = time.perf_counter() - start
            if out.returncode != 0:
                sys.exit(f"failed: {' '.join(argv)}\n{out.stderr[-2000:]}")
            walls[workers].append(wall)
            print(f"command run {rep}: {workers} worker(s) {wall:6.1f} s", flush=True)
    m1, m2 = statistics.median(walls[1]), statistics.median(walls[2])
    print(f"whole command, median wall: 1 worker {m1:.1f} s, 2 workers {m2:.1f} s; "
          f"1 / 2 = {m1 / m2:.2f}")


def _trials(args) -> None:
    from workbench.experiment.runs.prepare import load_config
    from workbench.experiment.sweep.search import run_search, study_names
    from workbench.experiment.sweep.workers import search_in_workers

    cfg = load_config(args.config).with_study(trials=args.trials)
    specs = study_names(cfg, [f"eeig{j}" for j in range(1, 6)])
    n_trials = len(specs) * args.trials
    rates: dict[int, list[float]] = {1: [], 2: []}
    for rep in range(args.repeats):
        for workers in ((1, 2) if rep % 2 == 0 else (2, 1)):
            with tempfile.TemporaryDirectory() as tmp:
                storage = str(Path(tmp) / "bench.journal")
                start = time.perf_counter()
                search_in_workers(run_search, cfg, storage, workers, None,
                                  [s.name for s in specs], Path.cwd())
                wall = time.perf_counter() - start
            rates[workers].append(n_trials / wall * 60)
            print(f"trials run {rep}: {workers} worker(s): {n_trials} trials in {wall:.1f} s "
                  f"({rates[workers][-1]:.0f} trials/min)", flush=True)
    m1, m2 = statistics.median(rates[1]), statistics.median(rates[2])
    print(f"trial phase, median trials/min: 1 worker {m1:.0f}, 2 workers {m2:.0f}; "
          f"ratio {m2 / m1:.2f}")


STORAGE_WORKER = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    import optuna
    from workbench.experiment.sweep.scheduler import run_study
    from workbench.experiment.storage import open_storage
    url, trials, fold_s, go = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), Path(sys.argv[4])
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.load_study(study_name="bench", sampler=optuna.samplers.RandomSampler(),
                              storage=open_storage(url, Path("."), stale_after_s=60))
    def objective(trial):
        x = trial.suggest_float("x", 0, 1)
        for i in range(3):
            time.sleep(fold_s)
            trial.report(x, i)
        return x
    while not go.exists():
        time.sleep(0.01)
    run_study(study, objective, trials, stale_after_s=60)
""")


def trials_per_minute(url: str, processes: int, trials: int, fold_s: float, tmp: Path) -> float:
    import optuna

    from workbench.experiment.sweep import storage

    optuna.create_study(study_name="bench", storage=storage.open_storage(url, tmp))
    go = tmp / f"go-{processes}-{time.monotonic_ns()}"
    procs = [subprocess.Popen([sys.executable, "-c", STORAGE_WORKER, url, str(trials),
                               str(fold_s), str(go)], cwd=tmp) for _ in range(processes)]
    time.sleep(5)  # every process has imported and connected
    start = time.perf_counter()
    go.touch()
    codes = [p.wait() for p in procs]
    wall = time.perf_counter() - start
    if codes != [0] * processes:
        raise SystemExit(f"a benchmark process failed: exit codes {codes}")
    return 60 * trials / wall


def run_overhead(uri: str, runs: int) -> float:
    """Median seconds to log one finished trial as a child run (create, one batch, end)."""
    import optuna

    from workbench.experiment.tracking.lifecycle import TrialRecorder
    from workbench.experiment.tracking.runs import Tracker

    tracker = Tracker(uri, "bench")
    parent = tracker.start_run("parent")
    study = optuna.create_study(study_name="r")
    study.optimize(lambda t: t.suggest_float("x", 0, 1), n_trials=1)
    record = TrialRecorder(tracker, parent)
    record(study, study.trials[0])  # warm up the client
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        record(study, study.trials[0])
        times.append(time.perf_counter() - t0)
    tracker.end_run(parent)
    return statistics.median(times)


def storages(args) -> None:
    import logging

    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    logging.getLogger("mlflow").setLevel(logging.WARNING)
    sys.path.insert(0, str(ROOT / "tests"))
    from services import MlflowServer, Postgres

    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        pg = Postgres(tmp / "pg")
        try:
            n = iter(range(100))
            urls = {"journal": lambda: str(tmp / f"s{next(n)}.journal"),
                    "sqlite": lambda: f"sqlite:///{tmp}/s{next(n)}.db",
                    "postgresql": lambda: pg.database(f"s{next(n)}")}
            print(f"trials per minute, {args.trials} trials of 3 x {args.fold_s} s "
                  f"(one process without any overhead: {60 / (3 * args.fold_s):.0f})")
            print(f"{'storage':<12}" + "".join(f"{p:>4} proc" for p in (1, 2, 4)))
            for name, make in urls.items():
                rates = [trials_per_minute(make(), p, args.trials, args.fold_s, tmp)
                         for p in (1, 2, 4)]
                print(f"{name:<12}" + "".join(f"{r:>9.0f}" for r in rates), flush=True)
            server = MlflowServer(pg.database("mlflow"), tmp / "artifacts", tmp / "mlflow.log")
            try:
                local = run_overhead(f"sqlite:///{tmp}/mlflow.db", args.runs)
                remote = run_overhead(server.uri, args.runs)
            finally:
                server.stop()
        finally:
            pg.stop()
    print(f"logging one trial as a child run (median of {args.runs}): local sqlite "
          f"{1000 * local:.0f} ms, tracking server on PostgreSQL {1000 * remote:.0f} ms "
          f"({remote / local:.1f}x)")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", default="experiments/smoke.toml")
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", choices=("command", "trials", "storages"), default=None)
    parser.add_argument("--fold-s", type=float, default=0.05)
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args()
    if args.only == "storages":
        args.trials = 32 if args.trials == parser.get_default("trials") else args.trials
        return storages(args)
    print(f"load before: {_uptime()}", flush=True)
    if args.only in (None, "command"):
        _commands(args)
    if args.only in (None, "trials"):
        os.environ.update(THREADS)
        _trials(args)
    print(f"load after:  {_uptime()}")


if __name__ == "__main__":
    main()
