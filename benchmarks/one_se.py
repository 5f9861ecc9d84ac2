"""The choice rule of the generic config, measured on training rows only: ``"best"`` against
``"one_se"`` by nested CV.

    python benchmarks/one_se.py [--splits time devices] [--draws 8] [--folds 5]
                                [--config experiments/generic.toml] [--json OUT]

Per split of the IBM gates (``[data] source = "ibm_gates"``), the training rows alone (the
test rows are never loaded into a fit nor scored) are dealt into ``--folds`` outer folds
(whole devices per fold, like the selection's own folds); in each, the generic config's
per-target model (``--draws`` LightGBM draws) is fitted on the other folds, every choice
remade by its inner CV, and scored on the held-out fold. Both rules choose from the same
inner fits (the same folds and seeds give the same candidate scores): the ``"best"`` model
is the fitted one, the ``"one_se"`` winner is refitted where it differs (it is never the mean
of k unless that is the best too).

Printed and written per split: the inner CV MAE of each rule's choice on all training rows
(what ``evaluate`` prints; biased towards ``"best"``, which minimises it), the nested-CV MAE
of the prior and of each rule (each outer fold's MAE, their mean, and the standard error of
the paired fold differences one_se - best), and what each rule chose in each outer fold.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def one_se_model(est, X, y):
    """The ``"one_se"`` choice of a fitted ``BasisChoiceCV`` ``est`` (fitted with ``"best"``),
    fitted on ``(X, y)`` as its own refit would be: ``(name, fitted model)``."""
    from workbench.boosting import PriorModel
    from workbench.selection import BaseBoostCV, choose, find_prior

    scores = {n: s for n, s in est.candidate_scores_.items() if np.all(np.isfinite(s))}
    name = choose(scores, "one_se")
    if name == (est.selected_candidate_ or "prior"):
        return name, est.best_estimator_
    if name == "prior":
        first = est.candidates[0][1]
        return name, PriorModel(prior=find_prior(first)).fit(X, y)
    candidate = dict(est.candidates)[name]
    return name, BaseBoostCV(candidate, random_state=est.random_state)._candidate().fit(X, y)


def run_split(config: Path, split: str, draws: int, folds: int) -> dict:
    from workbench.experiment.config import load_dataset
    from workbench.experiment.families.stage import per_target_boost
    from workbench.experiment.runs.prepare import load_config
    from workbench.selection import LabelGroupKFold, choose

    cfg = load_config(config, overrides={"data.split": split, "model.draws": draws,
                                         "selection.rule": "best", "n_jobs": 1})
    ds = load_dataset(cfg)
    X_train, _, Y_train, _ = ds.split()  # the test rows are not used below
    out: dict = {"split": split, "n_train": len(X_train), "draws": draws, "folds": folds,
                 "targets": {}}
    # what evaluate prints: each rule's choice and its inner CV MAE on all training rows
    full = per_target_boost(cfg, ds, ds.prior_names).fit(X_train, Y_train)
    outer = LabelGroupKFold(ds.groups, folds, shuffle=True, random_state=1)
    fold_fits = []
    for k, (tr, te) in enumerate(outer.split(X_train)):
        t0 = time.process_time()
        model = per_target_boost(cfg, ds, ds.prior_names).fit(X_train.iloc[tr],
                                                               Y_train.iloc[tr])
        fold_fits.append((tr, te, model))
        print(f"[{split}] outer fold {k + 1}/{folds}: {time.process_time() - t0:.0f} CPU s",
              flush=True)
    for j, target in enumerate(ds.target_names):
        est = full.estimators_[j]
        scores = {n: s for n, s in est.candidate_scores_.items() if np.all(np.isfinite(s))}
        inner = {rule: choose(scores, rule) for rule in ("best", "one_se")}
        row = {"inner_choice": inner,
               "inner_cv_mae": {"prior": -float(np.mean(scores["prior"])),
                                **{rule: -float(np.mean(scores[n])) for rule, n in
                                   inner.items()}},
               "nested": {"prior": [], "best": [], "one_se": []},
               "chosen": {"best": [], "one_se": []}}
        y = Y_train[target].to_numpy()
        for tr, te, model in fold_fits:
            fold_est = model.estimators_[j]
            X_tr, X_te = X_train.iloc[tr], X_train.iloc[te]
            name, fitted = one_se_model(fold_est, X_tr, y[tr])
            preds = {"prior": X_te[ds.prior_names[j]].to_numpy(),
                     "best": fold_est.predict(X_te), "one_se": fitted.predict(X_te)}
            for key, p in preds.items():
                row["nested"][key].append(float(np.mean(np.abs(y[te] - p))))
            row["chosen"]["best"].append(fold_est.selected_candidate_ or "prior")
            row["chosen"]["one_se"].append(name)
        d = np.subtract(row["nested"]["one_se"], row["nested"]["best"])
        row["nested_mean"] = {k: float(np.mean(v)) for k, v in row["nested"].items()}
        row["one_se_minus_best"] = {"mean": float(d.mean()),
                                    "se": float(d.std(ddof=1) / np.sqrt(len(d)))}
        out["targets"][target] = row
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splits", nargs="+", default=["time", "devices"])
    parser.add_argument("--draws", type=int, default=8)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--config", type=Path, default=ROOT / "experiments" / "generic.toml")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    t0 = time.process_time()
    results = []
    for split in args.splits:
        res = run_split(args.config, split, args.draws, args.folds)
        results.append(res)
        for target, row in res["targets"].items():
            n, i = row["nested_mean"], row["inner_cv_mae"]
            print(f"[{split}] {target}: inner CV MAE prior {i['prior']:.4f}, best "
                  f"{i['best']:.4f} ({row['inner_choice']['best']}), one_se {i['one_se']:.4f} "
                  f"({row['inner_choice']['one_se']}); nested CV MAE prior {n['prior']:.4f}, "
                  f"best {n['best']:.4f}, one_se {n['one_se']:.4f} (one_se - best "
                  f"{row['one_se_minus_best']['mean']:+.4f} +- "
                  f"{row['one_se_minus_best']['se']:.4f}); outer choices best "
                  f"{row['chosen']['best']}, one_se {row['chosen']['one_se']}", flush=True)
    if args.json:
        args.json.write_text(json.dumps({"results": results,
                                         "cpu_s": time.process_time() - t0}, indent=1) + "\n")


if __name__ == "__main__":
    main()
