"""The recommended config on data nobody tuned it on: the outside benchmark.

    python benchmarks/outside.py [--sets ibm_sx_time ... sim_bias] [--trials 50]
                                 [--config experiments/generic.toml] [--set KEY=VALUE ...]
                                 [--json benchmarks/results/outside.json]

For each set of ``benchmarks/outside_data.py`` (real data with a physics or engineering prior,
each with an honest split: later dates, unseen devices, extrapolation), on its train/test
split:

* **prior**: the physics model's prediction;
* **peer** (``workbench.experiment.paper.peer``): LightGBM boosted from the prior, its
  settings and objective (l2, l1, huber) searched by ``--trials`` Optuna trials of 5-fold CV
  on the training rows;
* **generic**: ``evaluate`` of the recommended config (``--config``), only its ``[data]``
  pointed at the set's CSV (as a new user would: target, prior, features, a ``split``
  column and, where rows share a device, a ``group_column``), ``--set`` overrides on top
  (e.g. ``model.draws=4`` for a reduced run).

Prints one line per set (test MAE of the three, the paired 95% bootstrap intervals of
generic - prior and generic - peer, generic / peer, wall and CPU seconds of the peer and of
``evaluate``; CPU: this process and its reaped children) and writes ``--json`` with the
commit measured, whether the measured files (:data:`MEASURED`) had uncommitted changes, and
the settings (``reduced``: true when ``--trials`` or ``--set`` differ from the full run's).
``tests/test_outside.py`` fails when the JSON is older than the last commit touching
:data:`MEASURED`; ``benchmarks/tables.py`` renders docs/benchmarks.md's win/loss table.

These sets decide config changes by CV (or nested CV) on their training rows only; a test
score printed here is seen, and a change adopted for it would be tuned to these sets.

The full run (``make bench-outside``)::

    python benchmarks/outside.py --json benchmarks/results/outside.json
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: What the table measures: a commit touching any of these makes the JSON stale.
MEASURED = (
    "experiments/generic.toml",
    "workbench/bases.py",
    "workbench/boosting.py",
    "workbench/line_search.py",
    "workbench/losses.py",
    "workbench/multitarget.py",
    "workbench/selection.py",
    "workbench/stagewise.py",
    "workbench/experiment/runs/evaluate.py",
    "workbench/experiment/config/space.py",
    "workbench/experiment/families/choices.py",
    "workbench/experiment/families/eigenvalue.py",
    "workbench/experiment/families/fitting.py",
    "workbench/experiment/families/stage.py",
    "workbench/experiment/paper/peer.py",
    "workbench/datasets/csv.py",
    "workbench/datasets/ibm_gates.py",
    "workbench/datasets/ibm_qubits.py",
    "workbench/simulate.py",
    "benchmarks/outside.py",
    "benchmarks/outside_data.py",
)
FULL_TRIALS = 50


def git(*args: str) -> str:
    return subprocess.run(["git", *args], capture_output=True, text=True,
                          cwd=ROOT).stdout.strip()


def _cpu() -> float:
    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF,
                                                  resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _timed(func):
    wall, cpu = time.perf_counter(), _cpu()
    out = func()
    return out, time.perf_counter() - wall, _cpu() - cpu


def run(name: str, args, overrides: dict, tmp: Path) -> dict:
    """One set's row; a set on which the config (or the peer) fails is a row too, with the
    error: the goal is no failure."""
    from outside_data import SETS

    spec = SETS[name]()
    try:
        return _measure(spec, args, overrides, tmp)
    except Exception as exc:  # noqa: BLE001 - recorded, reported, and the run goes on
        train, test = spec.rows
        return dict(set=name, kind=spec.kind, description=spec.description, unit=spec.unit,
                    train_rows=train, test_rows=test,
                    error=f"{type(exc).__name__}: {str(exc).splitlines()[0]}")


def _measure(spec, args, overrides: dict, tmp: Path) -> dict:
    from peers import write_config

    from workbench.experiment.config import load_dataset
    from workbench.experiment.paper.peer import peer_predict
    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.prepare import load_config
    from workbench.experiment.scoring.bootstrap import bootstrap_error_interval

    name = spec.name
    csv = tmp / f"{name}.csv"
    spec.frame.to_csv(csv, index=False)
    cfg = load_config(write_config(Path(args.config), spec.data(str(csv)), tmp / f"{name}.toml"),
                      overrides)
    ds = load_dataset(cfg)
    X_train, X_test, y_train, y_test = ds.split()
    seed = cfg.random_state or 0
    peer, peer_wall, peer_cpu = _timed(lambda: peer_predict(
        X_train, y_train, X_test, ds.prior_names, ds.feature_names, trials=args.trials,
        random_state=seed, n_jobs=2))
    ev, wb_wall, wb_cpu = _timed(lambda: evaluate(cfg, return_model=True))
    y = y_test.to_numpy(dtype=float)
    errors = {"prior": y - X_test[ds.prior_names].to_numpy(dtype=float),
              "peer": y - peer.predictions,
              "generic": y - np.asarray(ev.model.predict(X_test), dtype=float).reshape(y.shape)}
    mae = {k: float(np.mean(np.abs(e))) for k, e in errors.items()}
    candidates = ev.result.details.get("candidates", {})
    cv = {t: {"chosen": c["chosen"], "chosen_cv_mae": c["cv_mae"].get(c["chosen"]),
              "prior_cv_mae": c["cv_mae"].get("prior")} for t, c in candidates.items()}
    return dict(
        set=name, kind=spec.kind, description=spec.description, unit=spec.unit,
        train_rows=len(y_train), test_rows=len(y), **mae,
        ci={k: bootstrap_error_interval(e).average for k, e in errors.items()},
        generic_minus_prior=bootstrap_error_interval(errors["generic"],
                                                     baseline=errors["prior"]).average,
        generic_minus_peer=bootstrap_error_interval(errors["generic"],
                                                    baseline=errors["peer"]).average,
        ratio_to_peer=mae["generic"] / mae["peer"], ratio_to_prior=mae["generic"] / mae["prior"],
        selected=ev.result.model.selected, cv=cv, peer_params=peer.params,
        seconds={"peer_wall": peer_wall, "peer_cpu": peer_cpu, "generic_wall": wb_wall,
                 "generic_cpu": wb_cpu})


def verdict(r: dict) -> str:
    """``win`` (generic ahead of the peer beyond the interval), ``loss`` (behind beyond it),
    ``tie``; ``worse than prior`` overrides where generic - prior is above 0 throughout;
    ``failed`` where the run raised."""
    if "error" in r:
        return "failed"
    if r["generic_minus_prior"][0] > 0:
        return "worse than prior"
    low, high = r["generic_minus_peer"]
    return "win" if high < 0 else "loss" if low > 0 else "tie"


VERDICTS = ("win", "tie", "loss", "worse than prior", "failed")


def summary(rows: list[dict]) -> dict:
    """The goals' figures over the sets that ran (``failed``: those that did not)."""
    ran = [r for r in rows if "error" not in r]
    ratios = [r["ratio_to_peer"] for r in ran] or [float("nan")]
    return {"sets": len(rows), "failed": len(rows) - len(ran),
            "mean_ratio_to_peer": float(np.mean(ratios)),
            "worst_ratio_to_peer": float(np.max(ratios)),
            "worse_than_prior": sum(r["generic_minus_prior"][0] > 0 for r in ran),
            "more_than_3pct_behind_peer": sum(r["ratio_to_peer"] > 1.03 for r in ran),
            "verdicts": {v: sum(verdict(r) == v for r in rows) for v in VERDICTS}}


def _line(r: dict) -> str:
    def ci(pair) -> str:
        return f"[{pair[0]:+.4g}, {pair[1]:+.4g}]"

    if "error" in r:
        return f"{r['set']}: FAILED: {r['error']}"
    s = r["seconds"]
    chosen = ", ".join(c["chosen"] for c in r["cv"].values()) or ",".join(r["selected"])
    return (f"{r['set']} ({r['train_rows']} train / {r['test_rows']} test rows, {r['unit']}): "
            f"prior {r['prior']:.4g}, peer {r['peer']:.4g}, generic {r['generic']:.4g}; "
            f"generic - prior {ci(r['generic_minus_prior'])}, generic - peer "
            f"{ci(r['generic_minus_peer'])}, generic / peer {r['ratio_to_peer']:.3f} "
            f"({verdict(r)}); CV chose {chosen}; wall/CPU s: peer {s['peer_wall']:.0f}/"
            f"{s['peer_cpu']:.0f}, generic {s['generic_wall']:.0f}/{s['generic_cpu']:.0f}")


def main(argv: list[str] | None = None) -> None:
    from outside_data import SETS
    from scaling import write_json

    from workbench.experiment.config.overrides import parse_overrides

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--trials", type=int, default=FULL_TRIALS,
                        help="the peer's Optuna trials per target")
    parser.add_argument("--config", default=str(ROOT / "experiments" / "generic.toml"))
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE", help="override a config value (as evaluate's)")
    parser.add_argument("--json", type=Path, help="also write the rows as JSON")
    args = parser.parse_args(argv)
    overrides = parse_overrides(args.overrides)
    reduced = (args.trials != FULL_TRIALS or bool(overrides) or args.sets != list(SETS)
               or Path(args.config).resolve() != ROOT / "experiments" / "generic.toml")
    before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    # the code measured is the tree at the start: its commit, and whether a measured file
    # differed from it (the JSON then stands for no commit, and tests/test_outside.py fails)
    commit, dirty = git("rev-parse", "HEAD"), bool(git("status", "--porcelain", "--", *MEASURED))
    print(f"config {args.config}{' with ' + ' '.join(args.overrides) if args.overrides else ''};"
          f" peer: {args.trials} trials, objective searched; test MAE"
          + (" (REDUCED run)" if reduced else ""), flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.sets:
            rows.append(run(name, args, overrides, Path(tmp)))
            print(_line(rows[-1]), flush=True)
    total = summary(rows)
    print(f"{total['sets']} sets ({total['failed']} failed): generic / peer mean "
          f"{total['mean_ratio_to_peer']:.3f}, worst "
          f"{total['worst_ratio_to_peer']:.3f}; worse than the prior on "
          f"{total['worse_than_prior']}; more than 3% behind the peer on "
          f"{total['more_than_3pct_behind_peer']}; {total['verdicts']}")
    after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    if args.json:
        dirty = dirty or git("rev-parse", "HEAD") != commit  # a commit during the run
        write_json(args.json, {
            "commit_full": commit, "measured_files": list(MEASURED), "measured_dirty": dirty,
            "config": Path(args.config).name, "overrides": args.overrides,
            "trials": args.trials, "reduced": reduced, "summary": total, "rows": rows},
            before, after)
        data = json.loads(args.json.read_text())  # write_json records HEAD at the end
        data["measured"]["commit"] = commit[:7]
        args.json.write_text(json.dumps(data, indent=1) + "\n")


if __name__ == "__main__":
    main()
