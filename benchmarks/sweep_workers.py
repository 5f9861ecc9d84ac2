"""Trials per minute of a fixed sweep with 1 and 2 workers (prints a table; no assertions).

    python benchmarks/sweep_workers.py [--config experiments/smoke.toml] [--trials 10] [--repeats 3]

Each run searches into a fresh temporary journal storage (no MLflow tracking), so every run
does the same number of trials. Reports the median over repeats and the 2-vs-1 ratio, all
measured in this one run.
"""

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from workbench.experiment.config import load_config
from workbench.experiment import studies
from workbench.experiment.search import run_search, study_names


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", default="experiments/smoke.toml")
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    cfg = load_config(args.config).with_study(trials=args.trials)
    specs = study_names(cfg, [f"eeig{j}" for j in range(1, 6)])
    n_trials = len(specs) * args.trials
    rates: dict[int, list[float]] = {1: [], 2: []}
    for rep in range(args.repeats):
        for workers in (1, 2):
            with tempfile.TemporaryDirectory() as tmp:
                storage = str(Path(tmp) / "bench.journal")
                start = time.perf_counter()
                studies._search_in_workers(run_search, cfg, storage, workers, None,
                                           [s.name for s in specs], Path.cwd())
                wall = time.perf_counter() - start
            rates[workers].append(n_trials / wall * 60)
            print(f"repeat {rep}: {workers} worker(s): {n_trials} trials in {wall:.1f} s "
                  f"({rates[workers][-1]:.0f} trials/min)", flush=True)
    m1, m2 = statistics.median(rates[1]), statistics.median(rates[2])
    print(f"median trials/min: 1 worker {m1:.0f}, 2 workers {m2:.0f}; ratio {m2 / m1:.2f}")


if __name__ == "__main__":
    main()
