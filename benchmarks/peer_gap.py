"""Why the generic config trails the peer on the outside sets, on their training rows only.

    python benchmarks/peer_gap.py [--sets ...] [--trials 50] [--variants base ...]
                                  [--oracle] [--json benchmarks/results/peer_gap.json]

Every outside set loses its test rows first; its training rows are split again by the set's
own kind of rule (``benchmarks/outside_validation.py``: the validation rows). On the inner
training rows, per set:

* **peer** (``workbench.experiment.paper.peer``): LightGBM boosted from the prior, its
  settings and objective searched by ``--trials`` Optuna trials of 5-fold CV;
* **generic**: the recommended config's per-target model (its CV choice, rule as
  configured), for each ``--variants`` entry (:data:`VARIANTS`: the config with overrides,
  and/or candidates added beside its own);
* with ``--oracle``, the bound (``benchmarks/peer_bound.py``'s choosers on these rows): every
  candidate of the base config refitted on the inner training rows and scored on the
  validation rows; **oracle single** / **oracle mean**: the best candidate, and the best mean
  of the k best (k <= 10), chosen *on the validation rows themselves*; **held-out**: the same
  chosen on four fifths of the validation rows (whole groups where they have groups) and
  scored on the fifth left. If an oracle's mean ratio to the peer is above a goal, no way of
  choosing among these candidates reaches it.

``--cache DIR`` keeps each set's peer (seeded; the same for every variant), so the sets and
variants can run in several processes and ``--merge`` joins their JSONs (a variant that did
not reach every set is compared with the first complete one on the sets it ran on, under
``partial``, and left out of the table). The run in ``benchmarks/results/peer_gap.json``
(docs/benchmarks.md, "Why it trails the peer")::

    python benchmarks/peer_gap.py --oracle --variants base early --cache C --json A.json
    python benchmarks/peer_gap.py --variants peer_params --cache C --json B.json   # etc.
    python benchmarks/peer_gap.py --variants base halving --cache C --json D.json
    python benchmarks/peer_gap.py --variants halving_48 --cache C --json E.json
    python benchmarks/peer_gap.py --merge A.json B.json ... --json benchmarks/results/peer_gap.json

Printed per set and variant: validation MAE (average over targets) and its ratio to the
peer's and to the prior's; summed up: the mean and worst ratio to the peer over the sets and
the sets where a variant is worse than the prior. The outside sets' test rows are never
loaded into a fit nor scored. CPU is shared: every fit runs on one thread (set
``OMP_NUM_THREADS=1``); the CPU-seconds per set are recorded, wall times are not claims.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: name -> (config overrides, extra candidate kinds): what each variant changes.
VARIANTS: dict[str, tuple[dict[str, Any], tuple[str, ...]]] = {
    "base": ({}, ()),
    "best_rule": ({"selection.rule": "best"}, ()),
    "no_ensemble": ({"selection.ensemble": 1}, ()),
    "identity_only": ({"model.link": "identity"}, ()),
    "draws_48": ({"model.draws": 48}, ()),
    "draws_12": ({"model.draws": 12}, ()),
    "l1_huber": ({"model.basis_params.lightgbm.objective":
                  {"choices": ["regression_l1", "huber"]}}, ()),
    "extrapolate": ({"model.out_of_bounds": "extrapolate"}, ()),
    "plain_folds": ({"selection.groups": False}, ()),
    "tuned": ({}, ("tuned",)),
    "early": ({}, ("early",)),
    "tuned10": ({}, ("tuned10",)),
    "peer_params": ({}, ("peer_params",)),
    # per basis and link, the 24 draws raced by successive halving inside every fit
    # (workbench.halving.HalvingChoiceCV): instead of the draws, or beside them
    "halving": ({"model.tune": "halving"}, ()),
    "halving_added": ({}, ("halving",)),
    "halving_48": ({"model.tune": "halving", "model.draws": 48}, ()),
}


def _mae(y: np.ndarray, p: np.ndarray) -> float:
    return float(np.mean(np.abs(np.asarray(y, dtype=float) - np.ravel(p))))


def _load(name: str, config: Path, overrides: dict, tmp: Path):
    from outside_validation import validation_set
    from peers import write_config

    from workbench.experiment.config import load_dataset
    from workbench.experiment.runs.prepare import load_config

    spec = validation_set(name)  # the test rows are gone; "test" = the validation rows
    csv = tmp / f"{name}.csv"
    if not csv.exists():
        spec.frame.to_csv(csv, index=False)
    cfg = load_config(write_config(config, spec.data(str(csv)), tmp / f"{name}.toml"),
                      {"n_jobs": 1, **overrides})
    return cfg, load_dataset(cfg)


def fit_generic(cfg, ds, extra: tuple[str, ...], X_tr, Y_tr, peer_params=None):
    """The config's per-target model, with ``extra`` candidates added to each target's."""
    from workbench.experiment.families.stage import per_target_boost

    model = per_target_boost(cfg, ds, ds.prior_names)
    if extra:
        from peer_candidates import add_candidates

        add_candidates(model, extra, cfg, ds, peer_params)
    return model.fit(X_tr, Y_tr)


def run_set(name: str, args, tmp: Path) -> dict:
    from workbench.experiment.config.overrides import parse_overrides
    from workbench.experiment.paper.peer import peer_predict

    cfg, ds = _load(name, args.config, parse_overrides(args.overrides), tmp)
    X_tr, X_va, Y_tr, Y_va = ds.split()
    targets = ds.target_names
    prior = [_mae(Y_va[t], X_va[p]) for t, p in zip(targets, ds.prior_names)]
    t0 = time.process_time()
    cache = args.cache / f"{name}_{args.trials}.json" if args.cache else None
    if cache is not None and cache.exists():  # the peer's fit is the same for every variant
        peer = json.loads(cache.read_text())
    else:
        fitted = peer_predict(X_tr, Y_tr, X_va, ds.prior_names, ds.feature_names,
                              trials=args.trials, random_state=cfg.random_state or 0, n_jobs=1)
        peer = {"mae": float(np.mean([_mae(Y_va[t], fitted.predictions[:, j])
                                      for j, t in enumerate(targets)])),
                "params": fitted.params, "cpu_s": time.process_time() - t0}
        if cache is not None:
            cache.parent.mkdir(parents=True, exist_ok=True)
            cache.write_text(json.dumps(peer))
    row: dict[str, Any] = {
        "set": name, "train_rows": len(X_tr), "validation_rows": len(X_va),
        "prior": float(np.mean(prior)), "peer": peer["mae"], "peer_params": peer["params"],
        "cpu_s": {"peer": peer["cpu_s"]}, "variants": {}}
    for variant in args.variants:
        overrides, extra = VARIANTS[variant]
        vcfg, vds = _load(name, args.config, {**parse_overrides(args.overrides), **overrides},
                          tmp)
        t0 = time.process_time()
        model = fit_generic(vcfg, vds, extra, X_tr, Y_tr, peer["params"])
        maes = [_mae(Y_va[t], est.predict(X_va)) for t, est in zip(targets, model.estimators_)]
        chosen = {t: getattr(est, "selected_candidate_", None) or est.selected_
                  for t, est in zip(targets, model.estimators_)}
        row["variants"][variant] = {"mae": float(np.mean(maes)), "chosen": chosen}
        if args.oracle and variant == args.variants[0]:
            row["oracle"] = _oracle(model, ds, X_tr, X_va, Y_tr, Y_va)
        row["cpu_s"][variant] = time.process_time() - t0
    return row


def _oracle(model, ds, X_tr, X_va, Y_tr, Y_va) -> dict:
    """peer_bound's choosers for each target, averaged over targets."""
    from peer_bound import oracles

    groups = None if ds.groups is None else ds.groups.loc[X_va.index].to_numpy()
    per = [oracles(est, X_tr, Y_tr[t].to_numpy(), X_va, Y_va[t].to_numpy(), groups)
           for t, est in zip(ds.target_names, model.estimators_)]
    keys = ("cv", "greedy", "top_k", "best_single", "best_mean", "held_out_single",
            "held_out_mean")
    out: dict[str, Any] = {k: float(np.mean([p[k] for p in per])) for k in keys}
    out["best_single_name"] = [p["best_single_name"] for p in per]
    out["rank_rho"] = [p["rank_rho"] for p in per]
    return out


def summarise(rows: list[dict], variants: list[str]) -> dict:
    """Mean and worst ratio to the peer over the sets, and the sets worse than the prior."""
    out = {}
    for v in variants:
        ratios = [r["variants"][v]["mae"] / r["peer"] for r in rows]
        out[v] = {"mean_ratio_to_peer": float(np.mean(ratios)),
                  "worst_ratio_to_peer": float(np.max(ratios)),
                  "more_than_3pct_behind_peer": int(sum(x > 1.03 for x in ratios)),
                  "worse_than_prior": int(sum(r["variants"][v]["mae"] > r["prior"]
                                              for r in rows))}
    oracle_rows = [r for r in rows if "oracle" in r]
    if oracle_rows:
        for k in oracle_rows[0]["oracle"]:
            if isinstance(oracle_rows[0]["oracle"][k], float):
                ratios = [r["oracle"][k] / r["peer"] for r in oracle_rows]
                out[f"oracle:{k}"] = {"mean_ratio_to_peer": float(np.mean(ratios)),
                                      "worst_ratio_to_peer": float(np.max(ratios))}
    return out


def merge(paths: list[Path], out: Path | None) -> None:
    """Join several runs (e.g. the sets split over processes, variants run apart): a set's
    rows are one, its variants and oracle joined; the summary recomputed over the sets every
    variant ran on."""
    runs = [json.loads(p.read_text()) for p in paths]
    rows: dict[str, dict] = {}
    variants: dict[str, Any] = {}
    for run in runs:
        variants.update(run["variants"])
        for r in run["rows"]:
            row = rows.setdefault(r["set"], {**r, "variants": {}, "cpu_s": {}})
            row["variants"].update(r["variants"])
            row["cpu_s"].update(r["cpu_s"])
            if "oracle" in r:
                row["oracle"] = r["oracle"]
    complete = [v for v in variants if all(v in r["variants"] for r in rows.values())]
    summary = summarise(list(rows.values()), complete)
    # a variant that did not reach every set (time ran out): compared with the first
    # complete one on the sets it ran on, and left out of the table
    partial = {}
    for v in (v for v in variants if v not in complete):
        ran = [r for r in rows.values() if v in r["variants"]]
        partial[v] = {"sets": [r["set"] for r in ran],
                      **{k: summarise(ran, [k])[k] for k in (v, complete[0])}}
        for r in ran:
            r.setdefault("partial_variants", {})[v] = r["variants"].pop(v)
        print(f"{v} (on {len(ran)} sets only): mean "
              f"{partial[v][v]['mean_ratio_to_peer']:.3f} against {complete[0]}'s "
              f"{partial[v][complete[0]]['mean_ratio_to_peer']:.3f} on the same sets")
    for r in rows.values():
        print(_line(r))
    for k, s in summary.items():
        print(f"{k}: mean {s['mean_ratio_to_peer']:.3f}, worst {s['worst_ratio_to_peer']:.3f}"
              + (f", worse than prior {s['worse_than_prior']}" if "worse_than_prior" in s
                 else ""))
    if out:
        out.write_text(json.dumps({
            "measured": {**runs[0]["measured"], "runs": len(runs),
                         "load_after": runs[-1]["measured"]["load_after"],
                         "commits": sorted({run["measured"]["commit"] for run in runs})},
            **{k: runs[0][k] for k in ("config", "overrides", "trials")},
            "variants": {v: variants[v] for v in complete}, "summary": summary,
            "partial": partial, "rows": list(rows.values())},
            indent=1) + "\n")


def _line(r: dict) -> str:
    parts = [f"{v} {d['mae']:.4g} ({d['mae'] / r['peer']:.3f})"
             for v, d in r["variants"].items()]
    if "oracle" in r:
        o = r["oracle"]
        parts.append("oracle: " + ", ".join(
            f"{k} {o[k] / r['peer']:.3f}" for k in o if isinstance(o[k], float)))
    cpu = ", ".join(f"{k} {v:.0f}" for k, v in r["cpu_s"].items())
    return (f"{r['set']} ({r['train_rows']} inner train / {r['validation_rows']} validation "
            f"rows): prior {r['prior']:.4g} ({r['prior'] / r['peer']:.3f}), peer "
            f"{r['peer']:.4g}; " + "; ".join(parts) + f" [CPU-s: {cpu}]")


def main(argv: list[str] | None = None) -> None:
    from outside_data import SETS
    from scaling import write_json

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--trials", type=int, default=50, help="the peer's Optuna trials")
    parser.add_argument("--variants", nargs="+", default=["base"], choices=list(VARIANTS))
    parser.add_argument("--oracle", action="store_true",
                        help="the bound: the first variant's candidates chosen on the "
                             "validation rows")
    parser.add_argument("--config", type=Path, default=ROOT / "experiments" / "generic.toml")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    parser.add_argument("--cache", type=Path, help="a directory keeping the peer's fits")
    parser.add_argument("--merge", type=Path, nargs="+",
                        help="merge these runs' JSONs (rows by set, their variants joined)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    if args.merge:
        return merge(args.merge, args.json)
    before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"validation MAE (ratio to the peer); peer {args.trials} trials; variants "
          f"{args.variants}", flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.sets:
            rows.append(run_set(name, args, Path(tmp)))
            print(_line(rows[-1]), flush=True)
    summary = summarise(rows, args.variants)
    for k, s in summary.items():
        print(f"{k}: mean ratio to the peer {s['mean_ratio_to_peer']:.3f}, worst "
              f"{s['worst_ratio_to_peer']:.3f}"
              + (f"; > 3% behind on {s['more_than_3pct_behind_peer']}, worse than the prior "
                 f"on {s['worse_than_prior']} of {len(rows)}" if "worse_than_prior" in s
                 else ""))
    after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    if args.json:
        write_json(args.json, {"config": args.config.name, "overrides": args.overrides,
                               "trials": args.trials, "variants": {
                                   v: {"overrides": VARIANTS[v][0],
                                       "extra_candidates": list(VARIANTS[v][1])}
                                   for v in args.variants},
                               "summary": summary, "rows": rows}, before, after)


if __name__ == "__main__":
    main()
