"""How closely the test errors' Cornish-Fisher intervals agree with the percentile bootstrap,
and what each costs (prints a table; no assertions).

    python benchmarks/bootstrap.py            # simulated and IBM gate errors, 500 ... 9,000 rows
    python benchmarks/bootstrap.py --json F   # the rows as JSON too (make bench)

Above ``bootstrap.BOOTSTRAP_EXACT_ROWS`` test rows, ``evaluate`` computes the bootstrap
intervals of the test errors without resampling: the Cornish-Fisher expansion (to second
order) of the resampled mean's distribution, whose variance, skewness and kurtosis follow
exactly from the rows. This script computes both for every statistic ``evaluate`` reports
(per target and average MAE and MSE of two systems, and their paired MAE difference) on:

* ``chain``: a simulated 5-site device (``workbench simulate``), the prior's errors and a
  ridge correction's, the scaling benchmark's data;
* ``t3``: Student-t errors with 3 degrees of freedom (their squares have no variance: the
  hardest case for any interval of the MSE);
* ``ibm``: the IBM two-qubit gates' test rows (4,713 gates; the prior's errors and those of
  an affine recalibration of the prior fitted on the training rows), subsampled to each size.

For each it prints the largest difference between the two intervals' ends, as a fraction of
the percentile interval's half-width, beside the percentile bootstrap's own Monte Carlo error
(the largest difference between two seeds of 10,000 resamples), both methods' time and
which one ``evaluate`` uses (``bootstrap.bootstrap_method``: resampling where a resampled
mean's skewness or excess kurtosis exceeds ``bootstrap.CORNISH_FISHER_LIMIT``).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scaling import write_json  # noqa: E402

from workbench.experiment.scoring.bootstrap import (  # noqa: E402
    BOOTSTRAP_EXACT_ROWS,
    BOOTSTRAP_LEVEL,
    BOOTSTRAP_RESAMPLES,
    _intervals,
    bootstrap_method,
)

SIZES = [500, 1000, 2000, 4000, 9000]


def _stats(prior_err: np.ndarray, model_err: np.ndarray) -> np.ndarray:
    """The columns ``bootstrap_test_scores`` bootstraps, each with its average over targets."""
    parts = [np.abs(prior_err), prior_err ** 2, np.abs(model_err), model_err ** 2,
             np.abs(model_err) - np.abs(prior_err)]
    return np.column_stack([c for v in parts for c in (v, v.mean(axis=1))])


def _chain(n: int) -> tuple[np.ndarray, np.ndarray]:
    from sklearn.linear_model import Ridge

    from workbench.simulate import simulate

    sim = simulate(5, 2 * n, device_seed=0).data
    prior = sim[[f"model_E{i}" for i in range(1, 6)]].to_numpy()
    y = sim[[f"measured_E{i}" for i in range(1, 6)]].to_numpy()
    X = sim[[c for c in sim.columns if c.startswith("v_")]].to_numpy()
    fit = Ridge(1.0).fit(np.column_stack([X, prior])[:n], (y - prior)[:n])
    pred = prior + fit.predict(np.column_stack([X, prior]))
    return (y - prior)[n:], (y - pred)[n:]


def _t3(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(n)
    return rng.standard_t(3, size=(n, 5)), 0.7 * rng.standard_t(3, size=(n, 5))


def _ibm() -> tuple[np.ndarray, np.ndarray] | None:
    try:
        from workbench.datasets import load_ibm_gates

        ds = load_ibm_gates()
    except Exception as exc:  # data not fetchable here: the other cases still run
        print(f"ibm: skipped ({exc})")
        return None
    X_train, X_test, y_train, y_test = ds.split()
    p_train = X_train[ds.prior_names].to_numpy(float)[:, 0]
    p_test = X_test[ds.prior_names].to_numpy(float)[:, 0]
    y_tr, y_te = y_train.to_numpy(float)[:, 0], y_test.to_numpy(float)[:, 0]
    b, a = np.polyfit(p_train, y_tr, 1)
    return (y_te - p_test)[:, None], (y_te - (a + b * p_test))[:, None]


def _compare(name: str, prior_err: np.ndarray, model_err: np.ndarray) -> dict:
    stats = _stats(prior_err, model_err)
    args = (BOOTSTRAP_LEVEL, BOOTSTRAP_RESAMPLES)
    t0 = time.perf_counter()
    pct, _ = _intervals(stats, *args, 0, method="percentile")
    t1 = time.perf_counter()
    cf, _ = _intervals(stats, *args, 0, method="cornish_fisher")
    t2 = time.perf_counter()
    other_seed, _ = _intervals(stats, *args, 1, method="percentile")
    half = (pct[:, 1] - pct[:, 0]) / 2
    return {"data": name, "rows": len(stats), "statistics": stats.shape[1],
            "cf_vs_percentile": float(np.max(np.abs(cf - pct) / half[:, None])),
            "seed_vs_seed": float(np.max(np.abs(other_seed - pct) / half[:, None])),
            "largest_abs_difference": float(np.max(np.abs(cf - pct))),
            "percentile_s": t1 - t0, "cornish_fisher_s": t2 - t1,
            "evaluate_uses": bootstrap_method(stats)}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--sizes", nargs="+", type=int, default=SIZES)
    parser.add_argument("--json", type=Path, help="also write the rows as JSON here")
    args = parser.parse_args()
    before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"load before: {before}")
    print(f"{BOOTSTRAP_RESAMPLES:,} resamples, level {BOOTSTRAP_LEVEL}; evaluate resamples up "
          f"to {BOOTSTRAP_EXACT_ROWS:,} rows. Differences of the intervals' ends in units of "
          "the percentile interval's half-width (largest over all statistics).")
    print(f"{'data':<6}{'rows':>7}{'stats':>7}{'CF - pct':>10}{'seed 0 - 1':>12}"
          f"{'largest |CF - pct|':>20}{'pct s':>8}{'CF s':>8}  evaluate uses")
    ibm = _ibm()
    rows = []
    for n in args.sizes:
        cases = [("chain", *_chain(n)), ("t3", *_t3(n))]
        if ibm is not None and n <= len(ibm[0]):
            pick = np.random.default_rng(n).choice(len(ibm[0]), n, replace=False)
            cases.append(("ibm", ibm[0][pick], ibm[1][pick]))
        for name, prior_err, model_err in cases:
            r = _compare(name, prior_err, model_err)
            rows.append(r)
            print(f"{r['data']:<6}{r['rows']:>7,}{r['statistics']:>7}{r['cf_vs_percentile']:>10.3f}"
                  f"{r['seed_vs_seed']:>12.3f}{r['largest_abs_difference']:>20.2e}"
                  f"{r['percentile_s']:>8.2f}{r['cornish_fisher_s']:>8.4f}  {r['evaluate_uses']}",
                  flush=True)
    after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"load after:  {after}")
    if args.json:
        write_json(args.json, {"rows": rows}, before, after)


if __name__ == "__main__":
    main()
