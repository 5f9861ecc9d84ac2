"""The peer every claim is measured against: LightGBM boosted from the prior, tuned by CV.

    python benchmarks/peers.py [--datasets google ibm ibm_devices chain grid none]
                               [--seeds 0 1 2] [--trials 50] [--squared-peer]
                               [--config experiments/generic.toml]

For each dataset (and seed) on its train/test split:

* **prior**: the physics model's prediction;
* **peer** (``workbench.experiment.paper.peer``): per target, ``LGBMRegressor`` fitted with
  ``init_score`` = the prior column, on the prior columns and the dataset's features, its
  hyperparameters tuned by 5-fold CV on the training rows (Optuna TPE, ``--trials`` per
  target, seeded, one LightGBM thread per fit and a trial's folds on both cores; the search
  chooses LightGBM's objective too, among l2, l1 and huber: the strongest peer;
  ``--squared-peer`` keeps squared error); it predicts ``prior + booster``;
* **workbench**: ``workbench evaluate`` of one config (``--config``; only its ``[data]`` is
  pointed at each dataset: a benchmark's ``source`` and split, or a simulated CSV with its
  columns and coupling graph);
* **noise floor** (simulated devices): the MAE of the true eigenvalues against the measured
  ones, i.e. the best any model can do on the test rows. The true eigenvalues come from the
  same simulation with measurement noise and misidentified peaks switched off (the simulator
  draws its random numbers in the same order whatever the mismatch sizes).

Prints one line per dataset with the test MAEs (average over targets) and their 95% bootstrap
intervals over the test rows, the paired interval of workbench - peer, the ratio
workbench / peer and the two fitting times (the peer's tuning and final fit; the workbench's
``evaluate`` with the config's intervals, figures off: ``--no-track``).
Datasets: ``google`` (the Google benchmark's paper split), ``ibm`` (the IBM two-qubit gates,
the time split: newer snapshots held out), ``ibm_devices`` (the IBM gates, 30% of the devices
held out; ``--seeds`` draw the devices), ``chain`` (5-site chain, 400 experiments, default
mismatches), ``grid`` (3x3 grid, 600 experiments), ``none`` (5-site chain, 400 experiments,
the control model exact but for noise).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATASETS = {"chain": dict(sites=5, experiments=400, topology="chain", shape=None),
            "grid": dict(sites=None, experiments=600, topology="grid", shape=(3, 3)),
            "none": dict(sites=5, experiments=400, topology="chain", shape=None,
                         mismatch="none")}


def simulated(name: str, seed: int, directory: Path):
    """Write a simulated dataset; returns (csv path, [data] table, true eigenvalues)."""
    from workbench.simulate import Mismatch, simulate, write_simulation

    spec = DATASETS[name]
    mismatch = Mismatch.none() if spec.get("mismatch") == "none" else Mismatch.default()
    mismatch = dataclasses.replace(mismatch, noise_sd=0.3) if name == "none" else mismatch
    kw = dict(device_seed=seed, topology=spec["topology"], shape=spec["shape"])
    sim = simulate(spec["sites"], spec["experiments"], mismatch=mismatch, **kw)
    clean = simulate(spec["sites"], spec["experiments"], **kw,
                     mismatch=dataclasses.replace(mismatch, noise_sd=0.0,
                                                  misidentified_rate=0.0))
    csv = directory / f"{name}_{seed}.csv"
    write_simulation(sim, csv)
    n, edges = sim.truth["n_sites"], sim.truth["graph"]["edges"]
    data = {"csv": str(csv), "prior": [f"model_E{k}" for k in range(1, n + 1)],
            "targets": [f"measured_E{k}" for k in range(1, n + 1)],
            "features": [f"v_q{k}" for k in range(1, n + 1)]
            + [f"v_c{k}" for k in range(1, len(edges) + 1)],
            "test_fraction": 0.3, "split_seed": seed,
            "hamiltonian": {"onsite": [f"model_f{k}" for k in range(1, n + 1)],
                            "couplings": [f"model_g{k}" for k in range(1, len(edges) + 1)],
                            "edges": edges,
                            "qubit_features": [f"v_q{k}" for k in range(1, n + 1)],
                            "coupler_features": [f"v_c{k}" for k in range(1, len(edges) + 1)]}}
    true = clean.data[[f"measured_E{k}" for k in range(1, n + 1)]]
    return data, true


def _toml(value) -> str:
    if isinstance(value, dict):
        raise TypeError
    return json.dumps(value)


def write_config(base: Path, data: dict, out: Path) -> Path:
    """``base`` with its ``[data]`` (and ``[data.hamiltonian]``) replaced by ``data``."""
    raw = tomllib.loads(base.read_text())
    raw["data"] = data
    lines = []

    def table(prefix, tab):
        plain = {k: v for k, v in tab.items() if not isinstance(v, dict)}
        if prefix:
            lines.append(f"[{prefix}]")
        lines.extend(f"{k} = {_toml(v)}" for k, v in plain.items())
        for k, v in tab.items():
            if isinstance(v, dict):
                table(f"{prefix}.{k}" if prefix else k, v)

    table("", raw)
    out.write_text("\n".join(lines) + "\n")
    return out


#: the real benchmarks: ``[data]`` of each (``seed``: the split's seed where it has one)
BENCHMARKS = {
    "google": lambda seed: {"source": "google_5q"},
    "ibm": lambda seed: {"source": "ibm_gates", "split": "time"},
    "ibm_devices": lambda seed: {"source": "ibm_gates", "split": "devices",
                                 "split_seed": seed},
}
DEFAULT_SEEDS = {"chain": range(5), "grid": range(3), "none": range(3), "google": [0],
                 "ibm": [0], "ibm_devices": range(3)}


def _ci(low_high) -> str:
    return f"[{low_high[0]:.3f}, {low_high[1]:.3f}]"


def run(name: str, seed: int, args, tmp: Path) -> dict:
    from workbench.experiment.config import load_dataset
    from workbench.experiment.paper.peer import PEER_OBJECTIVES, peer_predict
    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.prepare import load_config
    from workbench.experiment.scoring.bootstrap import bootstrap_error_interval

    true = None
    split_seed = seed
    if name in BENCHMARKS:
        data = BENCHMARKS[name](seed)
    else:
        data, true = simulated(name, seed, tmp)
    cfg = load_config(write_config(Path(args.config), data, tmp / f"{name}_{seed}.toml"))
    if name in BENCHMARKS:  # a benchmark's random_state is the config's; the seed its split's
        seed = cfg.random_state or 0
    ds = load_dataset(cfg)
    X_train, X_test, y_train, y_test = ds.split()
    objectives = ("regression",) if args.squared_peer else PEER_OBJECTIVES
    fitted = peer_predict(X_train, y_train, X_test, ds.prior_names, ds.feature_names,
                          trials=args.trials, random_state=seed, objectives=objectives, n_jobs=2)
    peer, peer_s = fitted.predictions, fitted.seconds
    start = time.perf_counter()
    ev = evaluate(cfg, return_model=True)
    res, model = ev.result, ev.model
    wb_s = time.perf_counter() - start
    y = y_test.to_numpy()
    wb_err = y - np.asarray(model.predict(X_test), dtype=float).reshape(y.shape)
    peer_err, prior_err = y - peer, y - X_test[ds.prior_names].to_numpy()
    floor = (float(np.mean(np.abs(true.loc[ds.test_index].to_numpy() - y)))
             if true is not None else None)
    ci = {k: bootstrap_error_interval(e).average
          for k, e in (("prior", prior_err), ("peer", peer_err), ("workbench", wb_err))}
    return dict(dataset=name, seed=seed, split_seed=split_seed,
                prior=float(np.mean(np.abs(prior_err))),
                peer=float(np.mean(np.abs(peer_err))), workbench=float(np.mean(np.abs(wb_err))),
                ci=ci, diff=bootstrap_error_interval(wb_err, baseline=peer_err).average,
                floor=floor, selected=res.model.selected, peer_s=peer_s, workbench_s=wb_s,
                chosen=[c["chosen"] for c in res.details.get("candidates", {}).values()],
                test_rows=len(y))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--datasets", nargs="+",
                        default=["google", "ibm", "ibm_devices", "chain", "grid", "none"])
    parser.add_argument("--seeds", type=int, nargs="+", default=None,
                        help="default: chain 0-4, grid 0-2, none 0-2, ibm_devices 0-2")
    parser.add_argument("--trials", type=int, default=50)
    parser.add_argument("--squared-peer", action="store_true",
                        help="the peer with squared error only (default: its search chooses "
                             "LightGBM's objective among l2, l1 and huber)")
    parser.add_argument("--config", default=str(ROOT / "experiments" / "generic.toml"))
    parser.add_argument("--json", type=Path,
                        help="also write the rows as JSON (benchmarks/results/peers.json is "
                             "what docs/benchmarks.md's table is made from)")
    args = parser.parse_args()
    rows = []
    import subprocess
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from scaling import write_json

    before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"config {args.config}; peer: {args.trials} trials per target"
          + (", squared error only" if args.squared_peer else ", objective searched")
          + "; test MAE (average over targets) [95% bootstrap interval]", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets:
            for seed in (args.seeds if args.seeds is not None else DEFAULT_SEEDS[name]):
                if name in ("google", "ibm") and seed != 0:
                    continue
                r = run(name, seed, args, Path(tmp))
                rows.append(r)
                floor = f", noise floor {r['floor']:.3f}" if r["floor"] is not None else ""
                print(f"{name} seed {seed} ({r['test_rows']} test rows): "
                      f"prior {r['prior']:.3f} {_ci(r['ci']['prior'])}, "
                      f"peer {r['peer']:.3f} {_ci(r['ci']['peer'])}, "
                      f"workbench {r['workbench']:.3f} {_ci(r['ci']['workbench'])}{floor}; "
                      f"workbench / peer {r['workbench'] / r['peer']:.3f}, workbench - peer "
                      f"{_ci(r['diff'])}; {','.join(sorted(set(r['selected'])))}; "
                      f"seconds: peer {r['peer_s']:.0f}, workbench {r['workbench_s']:.0f}",
                      flush=True)
    for name in args.datasets:
        ratios = [r["workbench"] / r["peer"] for r in rows if r["dataset"] == name]
        if ratios:
            print(f"{name}: workbench / peer median {statistics.median(ratios):.3f}, "
                  f"worst {max(ratios):.3f} over {len(ratios)} seed(s)")
    after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    if args.json:
        write_json(args.json, {"config": Path(args.config).name, "trials": args.trials,
                               "peer_objectives": "squared" if args.squared_peer else "searched",
                               "rows": rows}, before, after)


if __name__ == "__main__":
    main()
