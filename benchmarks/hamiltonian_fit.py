"""Cost of the parameter-space model on the benchmark's training rows (prints; no assertions).

    python benchmarks/hamiltonian_fit.py [--repeats 30] [--jobs 1 2]

Prints the median time of one Gauss-Newton fit (default covariates, 76 rows: one CV fold),
cold and warm-started, and the wall time of one forward covariate selection
(experiments/hamiltonian.toml's pool) per number of jobs, all measured in this run.
"""

import argparse
import statistics
import time

from workbench.datasets import load_google_5q
from workbench.param_boost import default_library
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.param_select import candidate_pool, forward_select


def _median_seconds(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    ds = load_google_5q()
    ham = ds.hamiltonian
    X = ds.X_physics.loc[ds.train_index]
    y = ds.targets.loc[ds.train_index].to_numpy()
    on, co = list(ham.onsite.columns), list(ham.couplings.columns)
    common = dict(onsite=on, couplings=co, sign=ham.sign, loss="huber", huber_delta=0.5)
    fold, yf = X.iloc[:76], y[:76]
    model = HamiltonianParameterRegressor(**common)
    fitted = model.fit(fold, yf)
    cold = _median_seconds(lambda: model.fit(fold, yf), args.repeats)
    warm = _median_seconds(lambda: model.fit(fold, yf, coef_init=fitted.coef_dict()),
                           args.repeats)
    print(f"one fit, 76 rows, default covariates: cold {cold * 1e3:.1f} ms "
          f"({fitted.n_iter_} iterations), warm start {warm * 1e3:.1f} ms "
          f"(median of {args.repeats})", flush=True)
    pool = candidate_pool(on, co, ham.qubit_features, ham.coupler_features, base=None)
    print(f"forward selection, {sum(map(len, pool.values()))} candidate terms, 5-fold CV:",
          flush=True)
    for jobs in args.jobs:
        res = forward_select(X, y, candidates=pool, start=default_library(on, co), n_jobs=jobs,
                             max_steps=20, **common)
        print(f"  n_jobs={jobs}: {res.seconds:.1f} s, {len(res.selected)} steps, "
              f"CV MAE {res.cv_mae:.4f}", flush=True)


if __name__ == "__main__":
    main()
