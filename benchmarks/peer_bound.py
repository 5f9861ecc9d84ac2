"""How far ahead of the peer can any choice among the generic config's candidates get? An oracle.

    python benchmarks/peer_bound.py [--datasets google ibm ibm_devices chain] [--seeds 0 1 2]
                                    [--config experiments/generic.toml]
                                    [--peers benchmarks/results/peers.json] [--json OUT]

``benchmarks/peers.py`` measures the config (candidates chosen by CV on the training rows)
against the peer (LightGBM from the prior, tuned by CV, its objective searched). This script
asks what a perfect chooser could do with the same candidates: per target, every candidate of
the config (each basis draw, link and transform) is refitted on the training rows and scored
on the test rows, and two oracles pick with the test scores, which no honest method may see:

* **best single**: the candidate with the lowest test MAE;
* **best mean**: the mean of the ``k`` candidates with the lowest test MAEs, ``k`` from 1
  to 10 chosen on the test rows too (CV's "mean of 5" is one of these).

Two more choosers see only the training rows (honest, like CV's choice), from every
candidate's out-of-fold predictions (``BasisChoiceCV.candidate_predictions_``), each falling
back to the prior where its out-of-fold MAE is not below the prior's:

* **greedy**: Caruana et al.'s ensemble selection (2004), as in auto-sklearn: 25 rounds,
  each adding (with replacement) the candidate that most lowers the out-of-fold MAE of the
  running mean;
* **top k**: the mean of the ``k`` candidates with the lowest out-of-fold MAEs, ``k`` from
  1 to 10 chosen on the out-of-fold predictions.

A third honest chooser and a yardstick come from CV's own resolution: the candidates CV
cannot tell from its best (within one standard error of the paired fold differences, the
one-standard-error rule) are **tied**; their mean is the third chooser, and a **random tied
pick** (the mean test MAE of the tied candidates) is what choosing among them by chance
would give. The **best tied** is an oracle within them, and ``rank_rho`` per target the
Spearman correlation of the candidates' CV and test MAEs.

The oracles on all test rows carry a winner's curse: the best of 50 candidates on 41 rows is
partly the luckiest on those rows. The **held-out oracles** remove it: cross-fitted on the
test rows, each choosing on four fifths of them (whole groups, e.g. devices, where they
have groups) and scored on the other fifth, each row scored once per shuffle, 20 shuffles.
They see rows of the test period or test devices themselves, which no chooser on the
training rows sees; a goal above their ratios is beyond choosing among these candidates as
far as the test rows can tell.

Printed per dataset and seed: the peer's test MAE (from ``--peers``, the JSON
``peers.py --json`` wrote for the same splits; its tuning is seeded), the config's CV choice
refitted here, and the two oracles, each also as a ratio to the peer. Where an oracle's ratio
is above a goal, no way of choosing among these candidates (by CV or otherwise) reaches the
goal: only new candidates can.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr
from sklearn.base import clone

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from peers import BENCHMARKS, DEFAULT_SEEDS, simulated, write_config  # noqa: E402

TOP = 10
ROUNDS = 25
FOLDS, REPEATS = 5, 20


def _mae(y, p) -> float:
    return float(np.mean(np.abs(np.asarray(y) - p)))


def greedy_weights(oof: dict, y: np.ndarray, rounds: int = ROUNDS) -> dict:
    """Caruana's ensemble selection on out-of-fold predictions: name -> weight."""
    names = list(oof)
    M = np.array([oof[n] for n in names])
    counts, total = np.zeros(len(names)), np.zeros(len(y))
    for k in range(rounds):
        i = int(np.argmin(np.mean(np.abs(y - (total + M) / (k + 1)), axis=1)))
        counts[i] += 1
        total += M[i]
    return {names[i]: c / rounds for i, c in enumerate(counts) if c}


def top_k_weights(oof: dict, y: np.ndarray) -> dict:
    """The mean of the k candidates best out of fold, k (<= TOP) chosen out of fold."""
    ranked = sorted(oof, key=lambda n: _mae(y, oof[n]))
    k = 1 + int(np.argmin([_mae(y, np.mean([oof[n] for n in ranked[:k]], axis=0))
                           for k in range(1, min(TOP, len(ranked)) + 1)]))
    return {n: 1 / k for n in ranked[:k]}


def chooser(weights: dict, est, y, predictions: dict, prior_test) -> np.ndarray:
    """Test predictions of ``weights`` over the candidates, or the prior's where their
    out-of-fold MAE is not below the prior's."""
    oof = sum(w * est.candidate_predictions_[n] for n, w in weights.items())
    if _mae(y, oof) >= _mae(y, est.cv_predictions_prior_):
        return prior_test
    return sum(w * predictions[n] for n, w in weights.items())


def held_out_oracles(predictions: dict, y_test: np.ndarray, groups, seed: int = 0,
                     folds: int = FOLDS, repeats: int = REPEATS) -> tuple[float, float]:
    """The two oracles without the winner's curse: cross-fitted on the test rows. The test
    rows are dealt into ``folds`` folds (whole groups, where the test rows have groups), each
    oracle chooses on the other folds' rows and is scored on the fold's, over ``repeats``
    shuffles; returns the mean absolute error of the scored rows (each row once a repeat).
    The best of 50 candidates on 41 rows is partly the luckiest on those rows; chosen on
    other test rows, only what carries over from row to row is left."""
    names = list(predictions)
    P = np.array([predictions[n] for n in names])
    err = np.abs(P - y_test)  # candidates x rows
    labels = np.asarray(groups) if groups is not None else np.arange(len(y_test))
    units = np.unique(labels)
    rng = np.random.default_rng(seed)
    single, mean = np.zeros(len(y_test)), np.zeros(len(y_test))
    for _ in range(repeats):
        fold_of = dict(zip(rng.permutation(units), np.arange(len(units)) % folds))
        fold = np.array([fold_of[u] for u in labels])
        for k in range(folds):
            choose, score = fold != k, fold == k
            ranked = np.argsort(err[:, choose].mean(axis=1))
            top = ranked[:TOP]
            means = np.cumsum(P[top], axis=0) / np.arange(1, len(top) + 1)[:, None]
            best_k = int(np.argmin(np.abs(means[:, choose] - y_test[choose]).mean(axis=1)))
            single[score] += err[ranked[0], score]
            mean[score] += np.abs(means[best_k, score] - y_test[score])
    return float(single.mean() / repeats), float(mean.mean() / repeats)


def oracles(est, X_train, y, X_test, y_test, groups=None) -> dict:
    """Test MAE of the CV choice, of the two honest choosers and of the two oracles, for one
    target's fitted ``BasisChoiceCV`` ``est``."""
    fitted = {name: clone(cand).fit(X_train, y) for name, cand in est.candidates}
    predictions = {name: m.predict(X_test) for name, m in fitted.items()}
    prior_test = next(iter(fitted.values())).predict_prior(X_test)
    honest = {key: _mae(y_test, chooser(weights(est.candidate_predictions_, y), est, y,
                                        predictions, prior_test))
              for key, weights in (("greedy", greedy_weights), ("top_k", top_k_weights))}
    mae = {name: float(np.mean(np.abs(y_test - p))) for name, p in predictions.items()}
    tied = indistinguishable(est.candidate_scores_, set(est.candidate_predictions_))
    honest["tied_mean"] = _mae(y_test, chooser({n: 1 / len(tied) for n in tied}, est, y,
                                               predictions, prior_test))
    cv_mae = {n: -float(np.mean(est.candidate_scores_[n])) for n in mae}
    ranked = sorted(mae, key=mae.get)
    means = [float(np.mean(np.abs(y_test - np.mean([predictions[n] for n in ranked[:k]],
                                                    axis=0))))
             for k in range(1, min(TOP, len(ranked)) + 1)]
    return dict(cv=float(np.mean(np.abs(y_test - est.predict(X_test)))), **honest,
                chosen=est.selected_candidate_ or "prior", best_single=mae[ranked[0]],
                best_single_name=ranked[0], best_mean=min(means),
                best_mean_k=int(np.argmin(means)) + 1, candidates=len(mae),
                **dict(zip(("held_out_single", "held_out_mean"),
                           held_out_oracles(predictions, y_test, groups))),
                tied=len(tied), tied_pick=float(np.mean([mae[n] for n in tied])),
                tied_best=min(mae[n] for n in tied), oracle_tied=ranked[0] in tied,
                rank_rho=float(spearmanr([cv_mae[n] for n in mae], list(mae.values()))[0]))


def indistinguishable(fold_scores: dict, ok: set) -> list:
    """The candidates CV cannot tell from its best: those whose mean fold score is within one
    standard error of the paired fold differences from the best's (the one-standard-error
    rule of Breiman et al., paired); the best included."""
    names = [n for n in fold_scores if n in ok]
    best = max(names, key=lambda n: np.mean(fold_scores[n]))
    out = []
    for n in names:
        d = np.asarray(fold_scores[best]) - np.asarray(fold_scores[n])
        if n == best or d.mean() <= d.std(ddof=1) / np.sqrt(len(d)):
            out.append(n)
    return out


def _with_ratio(row: dict, key: str) -> str:
    """``row[key]`` and, where the peer is known, its ratio to the peer's."""
    if row["peer"] is None:
        return "n/a" if key == "peer" else f"{row[key]:.3f}"
    return f"{row[key]:.3f}" + ("" if key == "peer" else f" ({row[key] / row['peer']:.3f})")


def run(name: str, seed: int, config: Path, tmp: Path) -> dict:
    from workbench.experiment.config import load_dataset
    from workbench.experiment.families.stage import per_target_boost
    from workbench.experiment.runs.prepare import load_config

    data = BENCHMARKS[name](seed) if name in BENCHMARKS else simulated(name, seed, tmp)[0]
    cfg = load_config(write_config(config, data, tmp / f"{name}_{seed}.toml"))
    ds = load_dataset(cfg)
    X_train, X_test, Y_train, Y_test = ds.split()
    model = per_target_boost(cfg, ds, ds.prior_names).fit(X_train, Y_train)
    groups = None if ds.groups is None else ds.groups.loc[X_test.index].to_numpy()
    per_target = {}
    for target, est in zip(ds.target_names, model.estimators_):
        per_target[target] = oracles(est, X_train, Y_train[target].to_numpy(), X_test,
                                     Y_test[target].to_numpy(), groups)
    avg = {k: float(np.mean([t[k] for t in per_target.values()]))
           for k in ("cv", "greedy", "top_k", "tied_mean", "best_single", "best_mean",
                     "tied_pick", "tied_best", "held_out_single", "held_out_mean")}
    return dict(dataset=name, seed=seed, **avg, targets=per_target)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--datasets", nargs="+", default=["google", "ibm", "ibm_devices"])
    parser.add_argument("--seeds", type=int, nargs="+", default=None)
    parser.add_argument("--config", type=Path, default=ROOT / "experiments" / "generic.toml")
    parser.add_argument("--peers", type=Path, default=HERE / "results" / "peers.json")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    import subprocess

    from scaling import write_json

    peers = {(r["dataset"], r["split_seed"]): r["peer"]
             for r in json.loads(args.peers.read_text())["rows"]}
    before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    rows = []
    print(f"config {args.config.name}; test MAE (average over targets); / peer", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets:
            for seed in (args.seeds if args.seeds is not None else DEFAULT_SEEDS[name]):
                if name in ("google", "ibm") and seed != 0:
                    continue
                r = run(name, seed, args.config, Path(tmp))
                r["peer"] = peers.get((name, seed))
                rows.append(r)
                print(f"{name} seed {seed}: peer " + _with_ratio(r, "peer") + ", CV choice "
                      + _with_ratio(r, "cv") + ", greedy " + _with_ratio(r, "greedy")
                      + ", top k " + _with_ratio(r, "top_k") + ", mean of the tied "
                      + _with_ratio(r, "tied_mean") + ", random tied pick "
                      + _with_ratio(r, "tied_pick") + ", best tied "
                      + _with_ratio(r, "tied_best") + ", oracle single "
                      + _with_ratio(r, "best_single") + ", oracle mean "
                      + _with_ratio(r, "best_mean") + ", held-out oracle single "
                      + _with_ratio(r, "held_out_single") + ", held-out oracle mean "
                      + _with_ratio(r, "held_out_mean"), flush=True)
    for name in args.datasets:
        these = [r for r in rows if r["dataset"] == name and r["peer"]]
        if these:
            peer = sum(r["peer"] for r in these)
            print(f"{name}: summed over {len(these)} split(s), / peer: CV choice "
                  f"{sum(r['cv'] for r in these) / peer:.3f}, greedy "
                  f"{sum(r['greedy'] for r in these) / peer:.3f}, top k "
                  f"{sum(r['top_k'] for r in these) / peer:.3f}, mean of the tied "
                  f"{sum(r['tied_mean'] for r in these) / peer:.3f}, random tied pick "
                  f"{sum(r['tied_pick'] for r in these) / peer:.3f}, best tied "
                  f"{sum(r['tied_best'] for r in these) / peer:.3f}, oracle single "
                  f"{sum(r['best_single'] for r in these) / peer:.3f}, oracle mean "
                  f"{sum(r['best_mean'] for r in these) / peer:.3f}, held-out oracle single "
                  f"{sum(r['held_out_single'] for r in these) / peer:.3f}, held-out oracle "
                  f"mean {sum(r['held_out_mean'] for r in these) / peer:.3f}; median oracle-mean "
                  f"ratio {statistics.median(r['best_mean'] / r['peer'] for r in these):.3f}")
    after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    if args.json:
        write_json(args.json, {"config": args.config.name, "rows": rows}, before, after)


if __name__ == "__main__":
    main()
