"""How the parameter-space model scales with the device: fit and covariate-selection times.

Prints, per case, wall time, peak traced memory (tracemalloc: numpy arrays) and the process's
peak RSS (resource.getrusage), plus test MAE against the prior (30 % test rows):

* fit with fixed covariates (the default library): 6x6 grid, 2,000 experiments; 10x10 grid,
  1,000 experiments; with the default IRLS solver and with ``solver="newton"``;
* covariate selection (forward, 5-fold CV, huber loss, candidate pool with neighbours):
  ``--selection`` cases: the 5-site chain with 300 experiments by both methods ("refit":
  a full refit per candidate, "linearised": one Gauss-Newton step per candidate, exact refit
  of a batch or shortlist), the 3x3 grid with 600 experiments and the 6x6 grid with 2,000
  experiments (linearised);
* ``--only chain5acc``: accuracy of the linearised against the refit selection, 5-site
  chain with 300 and 400 experiments, seeds 0-2 (test MAE of each, ~6 min).

    python benchmarks/device_scale.py                 # fits only (~3 min)
    python benchmarks/device_scale.py --selection     # + selections (~9 min, light load)
    python benchmarks/device_scale.py --only chain5   # one case

One BLAS thread unless OMP_NUM_THREADS says otherwise; the "refit" selection scores
candidates in 2 worker processes, the "linearised" one folds and fits in 2 threads of this
process. Each line gives wall and CPU seconds (this process and its finished children: the
refit selection's live worker processes are not counted) and ends with the 1-minute load
average at its end (the machine is shared: compare CPU seconds across loads).
"""

from __future__ import annotations

import argparse
import os
import resource
import time
import tracemalloc

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from workbench.param_boost import HamiltonianParameterRegressor, default_library  # noqa: E402
from workbench.param_select import candidate_pool, forward_select  # noqa: E402
from workbench.simulate import simulate  # noqa: E402


def device(topology, shape, n_sites, m, seed=0):
    sim = simulate(n_sites, m, device_seed=seed, topology=topology, shape=shape)
    d, g = sim.data, sim.truth["graph"]
    N, E = g["n_sites"], len(g["edges"])
    cols = dict(onsite=[f"model_f{k}" for k in range(1, N + 1)],
                couplings=[f"model_g{k}" for k in range(1, E + 1)],
                qubit=[f"v_q{k}" for k in range(1, N + 1)],
                coupler=[f"v_c{k}" for k in range(1, E + 1)],
                prior=[f"model_E{k}" for k in range(1, N + 1)],
                targets=[f"measured_E{k}" for k in range(1, N + 1)],
                edges=None if topology == "chain" else g["edges"])
    perm = np.random.default_rng(seed).permutation(m)
    n_test = int(round(0.3 * m))
    return d, cols, np.sort(perm[n_test:]), np.sort(perm[:n_test])


def cpu_seconds() -> float:
    """User + system CPU time of this process and its finished children (all threads)."""
    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF,
                                                  resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def measure(func):
    """``func()``, wall seconds, traced peak MB, max RSS MB and CPU seconds (the CPU time
    is less sensitive than the wall time to other work on a shared machine)."""
    tracemalloc.start()
    t0, c0 = time.perf_counter(), cpu_seconds()
    out = func()
    seconds, cpu = time.perf_counter() - t0, cpu_seconds() - c0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB -> MB on Linux
    return out, seconds, peak / 2**20, rss, cpu


def load() -> str:
    return f"load {os.getloadavg()[0]:.1f}"


def maes(est, d, c, test):
    y = d.iloc[test][c["targets"]].to_numpy()
    return (np.abs(est.predict(d.iloc[test]) - y).mean(),
            np.abs(d.iloc[test][c["prior"]].to_numpy() - y).mean())


def fit_case(label, topology, shape, n_sites, m, solvers=("irls", "newton")):
    d, c, train, test = device(topology, shape, n_sites, m)
    y = d.iloc[train][c["targets"]].to_numpy()
    for solver in solvers:
        est = HamiltonianParameterRegressor(onsite=c["onsite"], couplings=c["couplings"],
                                            edges=c["edges"], loss="huber", huber_delta=0.5,
                                            solver=solver)
        _, sec, peak, rss, cpu = measure(lambda est=est: est.fit(d.iloc[train], y))
        mae, prior = maes(est, d, c, test)
        n_coef = len(est.coef_)
        print(f"fit   {label:<22} {solver:<6} {len(train):>5} train rows  {n_coef:>5} "
              f"coefficients  {est.n_iter_:>2} GN iterations  {sec:7.1f} s (cpu {cpu:6.1f} s)  "
              f"traced peak "
              f"{peak:7.0f} MB  max RSS {rss:6.0f} MB  test MAE {mae:.3f} (prior {prior:.3f})  "
              f"{load()}", flush=True)


def selection_case(label, topology, shape, n_sites, m, method, max_steps=20, seed=0):
    d, c, train, test = device(topology, shape, n_sites, m, seed=seed)
    common = dict(onsite=c["onsite"], couplings=c["couplings"], edges=c["edges"],
                  loss="huber", huber_delta=0.5)
    pool = candidate_pool(c["onsite"], c["couplings"], c["qubit"], c["coupler"], base=None,
                          edges=c["edges"])
    start = default_library(c["onsite"], c["couplings"], c["edges"])
    y = d.iloc[train][c["targets"]].to_numpy()
    res, sec, peak, rss, cpu = measure(lambda: forward_select(
        d.iloc[train], y, candidates=pool, start=start, cv=5, max_steps=max_steps,
        random_state=0, n_jobs=2, method=method, **common))
    est = res.estimator().fit(d.iloc[train], y)
    mae, prior = maes(est, d, c, test)
    steps = int(res.path["step"].max())
    print(f"select {label:<21} {method:<10} {len(train):>5} train rows  {steps:>2} steps  "
          f"{len(res.selected):>3} pairs added  {sec:7.1f} s (cpu {cpu:6.1f} s)  "
          f"traced peak {peak:7.0f} MB  "
          f"max RSS {rss:6.0f} MB  CV MAE {res.cv_mae:.3f}  test MAE {mae:.3f} "
          f"(prior {prior:.3f})  {load()}", flush=True)
    return mae, sec


def accuracy_case(sizes=(300, 400), seeds=(0, 1, 2)):
    """Linearised against refit selection on the simulated 5-site chain, several data sets."""
    out = {"refit": [], "linearised": []}
    for m in sizes:
        for seed in seeds:
            for method in out:
                out[method].append(selection_case(f"chain 5, {m} exp, seed {seed}", "chain",
                                                  None, 5, m, method, seed=seed))
    (ref, ref_s), (lin, lin_s) = (np.asarray(out[k]).T for k in ("refit", "linearised"))
    print(f"chain 5, {len(ref)} data sets: median test MAE refit {np.median(ref):.3f}, "
          f"linearised {np.median(lin):.3f}; linearised - refit: mean {np.mean(lin - ref):+.4f}, "
          f"worst {np.max(lin - ref):+.4f}; median time refit {np.median(ref_s):.1f} s, "
          f"linearised {np.median(lin_s):.1f} s", flush=True)


CASES = {
    "fit6x6": lambda: fit_case("grid 6x6, 2000 exp", "grid", (6, 6), None, 2000),
    "fit10x10": lambda: fit_case("grid 10x10, 1000 exp", "grid", (10, 10), None, 1000),
    "chain5": lambda: [selection_case("chain 5, 300 exp", "chain", None, 5, 300, m)
                       for m in ("refit", "linearised")],
    "grid3x3": lambda: selection_case("grid 3x3, 600 exp", "grid", (3, 3), None, 600,
                                      "linearised"),
    "grid6x6": lambda: selection_case("grid 6x6, 2000 exp", "grid", (6, 6), None, 2000,
                                      "linearised"),
    "chain5acc": accuracy_case,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--selection", action="store_true", help="also time the selections")
    parser.add_argument("--only", choices=list(CASES), default=None)
    args = parser.parse_args()
    names = [args.only] if args.only else (
        [n for n in CASES if n != "chain5acc"] if args.selection else ["fit6x6", "fit10x10"])
    print(f"OMP_NUM_THREADS={os.environ['OMP_NUM_THREADS']}, {os.cpu_count()} CPUs")
    for name in names:
        CASES[name]()


if __name__ == "__main__":
    main()
