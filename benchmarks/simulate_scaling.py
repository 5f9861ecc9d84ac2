"""Wall time and peak memory of :func:`workbench.simulate.simulate` as the problem grows.

Run: ``.venv/bin/python benchmarks/simulate_scaling.py``. Prints, per (sites, experiments), the
median wall time over 3 runs and the Python-allocated peak (``tracemalloc``, which counts
numpy buffers) of one further run, next to the size of the output DataFrame.
"""

from __future__ import annotations

import statistics
import time
import tracemalloc

from workbench.simulate import simulate

CASES = [(5, 1_000), (5, 10_000), (5, 100_000), (50, 1_000)]
REPEATS = 3


def measure(n_sites: int, n_experiments: int) -> tuple[float, float, float]:
    """(median seconds, peak MiB, output MiB)."""
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        simulate(n_sites, n_experiments, device_seed=0)
        times.append(time.perf_counter() - start)
    tracemalloc.start()
    sim = simulate(n_sites, n_experiments, device_seed=0)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    output = sim.data.memory_usage(index=True, deep=True).sum()
    return statistics.median(times), peak / 2**20, output / 2**20


def main() -> None:
    simulate(5, 10, device_seed=0)  # warm up imports and BLAS
    print(f"{'sites':>5} {'experiments':>11} {'median s':>9} {'peak MiB':>9} "
          f"{'output MiB':>10} {'peak/output':>11}")
    for n_sites, n_experiments in CASES:
        seconds, peak, output = measure(n_sites, n_experiments)
        print(f"{n_sites:>5} {n_experiments:>11,} {seconds:>9.3f} {peak:>9.1f} "
              f"{output:>10.1f} {peak / output:>11.1f}")


if __name__ == "__main__":
    main()
