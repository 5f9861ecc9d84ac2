"""A fixed sweep with 1 and 2 workers: the whole command and the trial phase (prints a table;
no assertions).

    python benchmarks/sweep_workers.py [--config experiments/smoke.toml] [--trials 6]
                                       [--repeats 3] [--only command|trials]

* ``command``: ``workbench sweep CONFIG --no-track --workers N`` as whole processes (start-up,
  search, outer-fold refits, final fit), paired and alternating (1 then 2 workers, then 2
  then 1, ...), each into a fresh temporary journal storage, one BLAS/OpenMP thread per
  process.
* ``trials``: the search phase alone in this process (``studies._search_in_workers``):
  trials per minute.

Prints every run, the medians, the 2-vs-1 ratio and ``uptime``'s load before and after (the
machine is shared: read the ratios beside the load).
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
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
    from workbench.experiment import studies
    from workbench.experiment.config import load_config
    from workbench.experiment.search import run_search, study_names

    cfg = load_config(args.config).with_study(trials=args.trials)
    specs = study_names(cfg, [f"eeig{j}" for j in range(1, 6)])
    n_trials = len(specs) * args.trials
    rates: dict[int, list[float]] = {1: [], 2: []}
    for rep in range(args.repeats):
        for workers in ((1, 2) if rep % 2 == 0 else (2, 1)):
            with tempfile.TemporaryDirectory() as tmp:
                storage = str(Path(tmp) / "bench.journal")
                start = time.perf_counter()
                studies._search_in_workers(run_search, cfg, storage, workers, None,
                                           [s.name for s in specs], Path.cwd())
                wall = time.perf_counter() - start
            rates[workers].append(n_trials / wall * 60)
            print(f"trials run {rep}: {workers} worker(s): {n_trials} trials in {wall:.1f} s "
                  f"({rates[workers][-1]:.0f} trials/min)", flush=True)
    m1, m2 = statistics.median(rates[1]), statistics.median(rates[2])
    print(f"trial phase, median trials/min: 1 worker {m1:.0f}, 2 workers {m2:.0f}; "
          f"ratio {m2 / m1:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", default="experiments/smoke.toml")
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", choices=("command", "trials"), default=None)
    args = parser.parse_args()
    print(f"load before: {_uptime()}", flush=True)
    if args.only in (None, "command"):
        _commands(args)
    if args.only in (None, "trials"):
        os.environ.update(THREADS)
        _trials(args)
    print(f"load after:  {_uptime()}")


if __name__ == "__main__":
    main()
