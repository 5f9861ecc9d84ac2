"""The selection rules of the generic config compared on the outside sets' training rows only.

    python benchmarks/rules.py [--sets ...] [--rules best one_se prior_se]
                               [--config experiments/generic.toml] [--set KEY=VALUE ...]
                               [--json benchmarks/results/rules.json]

Every outside set (``benchmarks/outside_data.py``) loses its test rows first; its training rows
are split again by the set's own kind of rule (``benchmarks/outside_validation.py``: later
snapshots, other devices, nuclides farther out, heavier compounds, other simulated devices).
On the inner training rows the generic config's per-target model is fitted once with
``[selection] rule = "best"``; each rule then chooses from the same candidates' fold scores
(:func:`workbench.selection.choose`) and its choice, refitted on the inner training rows where it
differs from the best, is scored on the validation rows. The test rows are never loaded into a
fit nor scored: this is where a rule may be chosen.

Printed and written per set: the validation MAE (average over targets) of the prior and of each
rule, each rule's MAE relative to the prior's, and what each rule chose per target.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

RULES = ("best", "one_se", "prior_se")


def rule_model(est, rule: str, X, y):
    """``(name, model fitted on (X, y))``: what ``rule`` chooses among the fold scores of the
    fitted ``BasisChoiceCV`` ``est`` (fitted with ``rule="best"``)."""
    from workbench.boosting import PriorModel
    from workbench.selection import BaseBoostCV, BasisChoiceCV, choose, find_prior

    if not isinstance(est, BasisChoiceCV):
        return est.selected_, est
    scores = {n: s for n, s in est.candidate_scores_.items() if np.all(np.isfinite(s))}
    name = choose(scores, rule)
    if name == (est.selected_candidate_ or "prior"):
        return name, est.best_estimator_
    if name == "prior":
        return name, PriorModel(prior=find_prior(est.candidates[0][1])).fit(X, y)
    if name.startswith("mean of"):
        return name, est.best_estimator_  # the mean is only ever the best
    candidate = dict(est.candidates)[name]
    return name, BaseBoostCV(candidate, random_state=est.random_state)._candidate().fit(X, y)


def run_set(name: str, config: Path, overrides: dict, rules: tuple[str, ...], tmp: Path) -> dict:
    from outside_validation import validation_set
    from peers import write_config

    from workbench.experiment.config import load_dataset
    from workbench.experiment.families.stage import per_target_boost
    from workbench.experiment.runs.prepare import load_config

    spec = validation_set(name)  # the test rows are gone; "test" here = validation rows
    csv = tmp / f"{name}.csv"
    spec.frame.to_csv(csv, index=False)
    cfg = load_config(write_config(config, spec.data(str(csv)), tmp / f"{name}.toml"),
                      {**overrides, "selection.rule": "best"})
    ds = load_dataset(cfg)
    X_tr, X_va, Y_tr, Y_va = ds.split()
    t0 = time.process_time()
    model = per_target_boost(cfg, ds, ds.prior_names).fit(X_tr, Y_tr)
    mae: dict[str, list[float]] = {"prior": [], **{r: [] for r in rules}}
    chosen: dict[str, dict[str, str]] = {r: {} for r in rules}
    for j, target in enumerate(ds.target_names):
        est, y, y_va = model.estimators_[j], Y_tr[target].to_numpy(), Y_va[target].to_numpy()
        mae["prior"].append(float(np.mean(np.abs(y_va - X_va[ds.prior_names[j]].to_numpy()))))
        for rule in rules:
            choice, fitted = rule_model(est, rule, X_tr, y)
            chosen[rule][target] = str(choice)
            mae[rule].append(float(np.mean(np.abs(y_va - np.ravel(fitted.predict(X_va))))))
    avg = {k: float(np.mean(v)) for k, v in mae.items()}
    return {"set": name, "train_rows": len(X_tr), "validation_rows": len(X_va),
            "validation_mae": avg, "ratio_to_prior": {r: avg[r] / avg["prior"] for r in rules},
            "chosen": chosen, "cpu_s": time.process_time() - t0}


def main(argv: list[str] | None = None) -> None:
    from outside_data import SETS

    from workbench.experiment.config.overrides import parse_overrides

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--rules", nargs="+", default=list(RULES), choices=list(RULES))
    parser.add_argument("--config", type=Path, default=ROOT / "experiments" / "generic.toml")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.sets:
            row = run_set(name, args.config, parse_overrides(args.overrides), tuple(args.rules),
                          Path(tmp))
            rows.append(row)
            m = row["validation_mae"]
            print(f"{name}: validation MAE prior {m['prior']:.4g}, "
                  + ", ".join(f"{r} {m[r]:.4g} ({row['ratio_to_prior'][r]:.3f} of the prior)"
                              for r in args.rules)
                  + f"; chosen {row['chosen']} ({row['cpu_s']:.0f} CPU-s)", flush=True)
    ratios = {r: [row["validation_mae"][r] / row["validation_mae"]["best"] for row in rows]
              for r in args.rules}
    summary = {r: {"mean_ratio_to_best": float(np.mean(v)),
                   "worst_ratio_to_best": float(np.max(v)),
                   "worse_than_prior": sum(row["ratio_to_prior"][r] > 1 for row in rows)}
               for r, v in ratios.items()}
    for r, s in summary.items():
        print(f"{r}: mean {s['mean_ratio_to_best']:.3f} of best's validation MAE, worst "
              f"{s['worst_ratio_to_best']:.3f}; above the prior on {s['worse_than_prior']} of "
              f"{len(rows)} sets")
    if args.json:
        args.json.write_text(json.dumps({"config": args.config.name, "overrides": args.overrides,
                                         "summary": summary, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
