"""How far can any batch design beat random choice? The design loop's goals against an oracle.

    python benchmarks/design_bound.py [--datasets chain grid google] [--seeds 0 1 2 3 4]
                                      [--google-seeds 0 1 ... 9] [--draws 5]

``benchmarks/design.py`` measures the closed loop. This script asks what the best greedy
design could reach if it knew the model's coefficients: the loop's model
(experiments/design_loop.toml) is fitted on many rows (simulated devices: 2,600 settings of
the seed's device; Google: all 95 training rows), and its Gauss-Newton linearisation there
(``ModelFamily.design_problem``: the Hellmann-Feynman blocks of every correction coefficient
and the ridge prior) gives every row set ``S`` its average predictive variance over the test
settings, ``V(S) = tr(F(S)^-1 M)`` (``F(S)``: the prior plus the rows' information; ``M``:
the mean information of the test settings; noise-variance units, summed over the targets).
For a linear model with Gaussian noise this is exactly the expected squared test error
beyond the noise, and no outcome can help a design: the oracle greedy I-optimal batch
(``workbench.design.greedy_design`` with the test settings as the reference) from the same
20 random starting rows is what the loop's design would choose with a perfect guess of the
coefficients.

Printed per dataset and seed: V of random rows (the median of ``--draws`` draws; the same
20 starting rows) and of the oracle design at each size, the size at which the oracle
design's V reaches random choice's V at the largest size, and the predicted test MAE,
``sqrt(2/pi) sigma sqrt(1 + V / q)`` for ``q`` targets (Gaussian errors, no bias, no
misidentified peaks), design against random.

Simulated devices: the candidates are the first 600 of the 2,600 settings (the loop's pool
size), the reference the 400 test settings. Google: the 95 training rows are the candidates,
the 41 test rows the reference; the model on all 95 rows is also scored on the test rows, and
the gap between its MAE and the prediction at 95 is taken as a floor no choice of rows
removes (squared errors add): the floored prediction is printed beside the plain one.

``--exchange K``: after the greedy batch at ``--exchange-at`` rows, ``K`` random swaps of a
chosen row against an unchosen one, each kept if it lowers V (a Fedorov-style exchange); the
fall of V says how far greedy is from a better batch.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

BIG, POOL, START = 2600, 600, 20
SIZES = {"simulated": [30, 40, 60, 100, 150, 200], "google": [30, 40, 60, 95]}


def oracle(config: str):
    """The loop's model fitted on every training row, its design problem for the training
    rows (candidates) and the test rows (reference), and the prior's information."""
    from threadpoolctl import threadpool_limits

    from workbench.experiment.config import load_dataset
    from workbench.experiment.families.fitting import quiet_fit
    from workbench.experiment.runs.prepare import load_config

    with threadpool_limits(1):
        cfg = load_config(config)
        ds = load_dataset(cfg)
        family = cfg.family
        X, Y = family.inputs(cfg, ds), ds.targets
        train, test = list(ds.train_index), list(ds.test_index)
        model = quiet_fit(family.build(cfg, ds), X.loc[train], Y.loc[train])
        problem = family.design_problem(model, X.loc[train], Y.loc[train],
                                        X.loc[train + test])
        pred = np.asarray(model.predict(X.loc[test]), dtype=float)
    mae = float(np.mean(np.abs(Y.loc[test].to_numpy(dtype=float) - pred.reshape(len(test), -1))))
    blocks = problem.blocks[:len(train)]
    prior = problem.information - np.einsum("rqd,rqe->de", blocks, blocks)
    return blocks, problem.blocks[len(train):], prior, float(problem.noise_sd[0]), mae


def average_variance(blocks, prior, reference) -> float:
    """V of the rows ``blocks``: ``tr(F^-1 M)``, ``F`` the prior plus their information,
    ``M`` the mean information of the ``reference`` blocks."""
    F = prior + np.einsum("rqd,rqe->de", blocks, blocks)
    M = np.einsum("rqd,rqe->de", reference, reference) / len(reference)
    return float(np.trace(np.linalg.solve(F, M)))


def curves(blocks, reference, prior, n_candidates: int, sizes: list[int], seed: int,
           draws: int, exchange: int = 0, exchange_at: int = 100) -> dict:
    """V of random rows (median of ``draws``) and of the oracle greedy I-optimal design at
    each size, both from the same ``START`` random rows of the first ``n_candidates``."""
    from workbench.design import greedy_design

    B = blocks[:n_candidates]
    M = np.einsum("rqd,rqe->de", reference, reference) / len(reference)

    def V(rows) -> float:
        F = prior + np.einsum("rqd,rqe->de", B[rows], B[rows])
        return float(np.trace(np.linalg.solve(F, M)))

    rng = np.random.default_rng(seed)
    start = rng.choice(n_candidates, START, replace=False)
    rest = np.setdiff1d(np.arange(n_candidates), start)
    F0 = prior + np.einsum("rqd,rqe->de", B[start], B[start])
    picks = greedy_design(B[rest], F0, max(sizes) - START, criterion="i",
                          reference=reference).index
    design = [V(np.concatenate([start, rest[picks[:n - START]]])) for n in sizes]
    random = [statistics.median(
        V(np.concatenate([start, rng.permutation(rest)[:n - START]])) for _ in range(draws))
        for n in sizes]
    out = {"n": sizes, "design": design, "random": random}
    if exchange:
        chosen = list(np.concatenate([start, rest[picks[:exchange_at - START]]]))
        free = list(np.setdiff1d(rest, chosen))
        info = np.einsum("rqd,rqe->rde", B, B)
        F = prior + info[chosen].sum(axis=0)
        v = before = float(np.trace(np.linalg.solve(F, M)))
        for _ in range(exchange):
            a, b = START + rng.integers(len(chosen) - START), rng.integers(len(free))
            F2 = F - info[chosen[a]] + info[free[b]]
            v2 = float(np.trace(np.linalg.solve(F2, M)))
            if v2 < v:
                F, v = F2, v2
                chosen[a], free[b] = free[b], chosen[a]
        out["exchange"] = {"at": exchange_at, "swaps": exchange, "greedy": before, "after": v}
    return out


def predicted_mae(V: float, sigma: float, q: int) -> float:
    return math.sqrt(2 / math.pi) * sigma * math.sqrt(1 + V / q)


def floored_mae(V: float, sigma: float, q: int, floor: float) -> float:
    """:func:`predicted_mae` with ``floor`` (an MAE) added in squares."""
    return math.sqrt(predicted_mae(V, sigma, q) ** 2 + floor ** 2)


def report(name: str, seed: int, c: dict, sigma: float, q: int, floor: float = 0.0) -> dict:
    target = c["random"][-1]
    reached = [n for n, v in zip(c["n"], c["design"]) if v <= target]
    c["design_reaches_random_final_at"] = reached[0] if reached else None
    c["sigma"], c["q"], c["floor"] = sigma, q, floor
    print(f"{name} seed {seed}: V design/random "
          + " ".join(f"{n}:{d:.3f}/{r:.3f}" for n, d, r in zip(c["n"], c["design"], c["random"]))
          + f"; the oracle design reaches random's V at {c['n'][-1]} ({target:.3f}) at "
          f"{c['design_reaches_random_final_at'] or 'none of the sizes'}; predicted test MAE "
          "design/random " + " ".join(
              f"{n}:{predicted_mae(d, sigma, q):.3f}/{predicted_mae(r, sigma, q):.3f}"
              for n, d, r in zip(c["n"], c["design"], c["random"]))
          + ("" if not floor else "; with the floor " + " ".join(
              f"{n}:{floored_mae(d, sigma, q, floor):.3f}/{floored_mae(r, sigma, q, floor):.3f}"
              for n, d, r in zip(c["n"], c["design"], c["random"])))
          + ("" if "exchange" not in c else
             f"; {c['exchange']['swaps']} swaps at {c['exchange']['at']} rows: V "
             f"{c['exchange']['greedy']:.3f} -> {c['exchange']['after']:.3f}"), flush=True)
    return c


def main() -> None:
    from design import dataset_arguments, simulated_config

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    dataset_arguments(parser)
    parser.add_argument("--draws", type=int, default=5)
    parser.add_argument("--exchange", type=int, default=0)
    parser.add_argument("--exchange-at", type=int, default=None,
                        help="rows of the exchanged batch (default 100; Google 40)")
    parser.add_argument("--config", default=str(ROOT / "experiments" / "design_loop.toml"))
    parser.add_argument("--out", default=str(ROOT / "reports" / "design"))
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets:
            runs = []
            if name == "google":
                blocks, reference, prior, sigma, mae = oracle(args.config)
                q = reference.shape[1]
                full = predicted_mae(average_variance(blocks, prior, reference), sigma, q)
                floor = math.sqrt(max(mae ** 2 - full ** 2, 0.0))
                print(f"google: the model on all {len(blocks)} training rows scores {mae:.3f} "
                      f"on the test rows, predicted {full:.3f}: floor {floor:.3f}", flush=True)
                for seed in args.google_seeds:
                    runs.append(report(name, seed, curves(
                        blocks, reference, prior, len(blocks), SIZES["google"], seed,
                        args.draws, args.exchange, args.exchange_at or 40), sigma, q, floor))
            else:
                for seed in args.seeds:
                    config = simulated_config(name, seed, Path(args.config), Path(tmp), BIG)
                    blocks, reference, prior, sigma, _ = oracle(str(config))
                    runs.append(report(name, seed, curves(
                        blocks, reference, prior, POOL, SIZES["simulated"], seed, args.draws,
                        args.exchange, args.exchange_at or 100), sigma, reference.shape[1]))
            reach = [r["design_reaches_random_final_at"] for r in runs]
            ratio = {n: statistics.median(
                predicted_mae(r["design"][j], r["sigma"], r["q"])
                / predicted_mae(r["random"][j], r["sigma"], r["q"]) for r in runs)
                for j, n in enumerate(runs[0]["n"])}
            if name == "google":
                floored = {n: statistics.median(
                    floored_mae(r["design"][j], r["sigma"], r["q"], r["floor"])
                    / floored_mae(r["random"][j], r["sigma"], r["q"], r["floor"]) for r in runs)
                    for j, n in enumerate(runs[0]["n"])}
                print("google: median floored predicted-MAE ratio design/random "
                      + " ".join(f"{n}:{v:.3f}" for n, v in floored.items()), flush=True)
            print(f"{name}: the oracle design reaches random's V at {runs[0]['n'][-1]} at "
                  f"{reach} (seeds); median predicted-MAE ratio design/random "
                  + " ".join(f"{n}:{v:.3f}" for n, v in ratio.items()), flush=True)
            (out / f"bound_{name}.json").write_text(
                json.dumps({"runs": runs, "median_predicted_mae_ratio": ratio}, indent=1) + "\n")


if __name__ == "__main__":
    main()
