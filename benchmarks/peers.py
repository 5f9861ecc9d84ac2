"""The peer every claim is measured against: LightGBM boosted from the prior, tuned by CV.

    python benchmarks/peers.py [--datasets chain grid none google] [--seeds 0 1 2]
                               [--trials 50] [--config experiments/any_device.toml]

For each dataset (and seed) on its train/test split:

* **prior**: the control program's prediction;
* **peer**: per target, ``LGBMRegressor`` fitted with ``init_score`` = the prior column, on the
  prior columns and the voltages, its hyperparameters tuned by 5-fold CV on the training rows
  (Optuna TPE, ``--trials`` per target, seeded, one LightGBM thread); it predicts
  ``prior + booster``;
* **workbench**: ``workbench evaluate`` of one config (``--config``; only its ``[data]`` is
  pointed at the dataset: the CSV, the columns and the coupling graph);
* **noise floor** (simulated devices): the MAE of the true eigenvalues against the measured
  ones, i.e. the best any model can do on the test rows. The true eigenvalues come from the
  same simulation with measurement noise and misidentified peaks switched off (the simulator
  draws its random numbers in the same order whatever the mismatch sizes).

Prints one line per dataset with the four test MAEs and the ratio workbench / peer.
Datasets: ``chain`` (5-site chain, 400 experiments, default mismatches), ``grid`` (3x3 grid,
600 experiments), ``none`` (5-site chain, 400 experiments, the control model exact but for
noise), ``google`` (the benchmark's paper split).
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


def peer_mae(X_train, X_test, y_train, y_test, priors, features, trials, seed) -> list[float]:
    """Per-target test MAE of LightGBM boosted from the prior, tuned by 5-fold CV."""
    import optuna
    from lightgbm import LGBMRegressor
    from sklearn.model_selection import KFold

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    cols = list(dict.fromkeys(priors + features))
    folds = list(KFold(5, shuffle=True, random_state=seed).split(X_train))
    out = []
    for j, target in enumerate(y_train.columns):
        Xtr, ytr = X_train[cols].to_numpy(), y_train[target].to_numpy()
        base = X_train[priors[j]].to_numpy()

        def make(params):
            return LGBMRegressor(n_jobs=1, verbose=-1, random_state=seed, **params)

        # this target's data bound as defaults (the closure is consumed in this iteration)
        def objective(trial, Xtr=Xtr, ytr=ytr, base=base):
            params = dict(
                n_estimators=trial.suggest_int("n_estimators", 20, 600, log=True),
                learning_rate=trial.suggest_float("learning_rate", 0.01, 0.3, log=True),
                num_leaves=trial.suggest_int("num_leaves", 4, 63, log=True),
                min_child_samples=trial.suggest_int("min_child_samples", 3, 40, log=True),
                reg_lambda=trial.suggest_float("reg_lambda", 1e-3, 10.0, log=True),
                subsample=trial.suggest_float("subsample", 0.5, 1.0), subsample_freq=1,
                colsample_bytree=trial.suggest_float("colsample_bytree", 0.5, 1.0))
            errs = []
            for fit_rows, val_rows in folds:
                model = make(params).fit(Xtr[fit_rows], ytr[fit_rows],
                                         init_score=base[fit_rows])
                pred = base[val_rows] + model.predict(Xtr[val_rows])
                errs.append(np.mean(np.abs(ytr[val_rows] - pred)))
            return float(np.mean(errs))

        study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=seed))
        study.optimize(objective, n_trials=trials)
        params = {**study.best_params, "subsample_freq": 1}
        model = make(params).fit(Xtr, ytr, init_score=base)
        pred = X_test[priors[j]].to_numpy() + model.predict(X_test[cols].to_numpy())
        out.append(float(np.mean(np.abs(y_test[target].to_numpy() - pred))))
    return out


def simulated(name: str, seed: int, directory: Path):
    """Write a simulated dataset; returns (csv path, [data] table, true eigenvalues)."""
    from workbench.simulate import Mismatch, simulate, write_simulation

    spec = DATASETS[name]
    mismatch = Mismatch.none() if spec.get("mismatch") == "none" else Mismatch.default()
    mismatch = dataclasses.replace(mismatch, noise_sd=0.3) if name == "none" else mismatch
    kw = dict(seed=seed, topology=spec["topology"], shape=spec["shape"])
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


def run(name: str, seed: int, args, tmp: Path) -> dict:
    from workbench.experiment.config import load_config, load_dataset
    from workbench.experiment.evaluate import evaluate

    true = None
    if name == "google":
        cfg = load_config(args.google_config)
    else:
        data, true = simulated(name, seed, tmp)
        cfg = load_config(write_config(Path(args.config), data, tmp / f"{name}_{seed}.toml"))
    ds = load_dataset(cfg)
    X_train, X_test, y_train, y_test = ds.split()
    start = time.perf_counter()
    peer = peer_mae(X_train, X_test, y_train, y_test, ds.prior_names, ds.feature_names,
                    args.trials, seed)
    peer_s = time.perf_counter() - start
    start = time.perf_counter()
    res = evaluate(cfg)
    wb_s = time.perf_counter() - start
    prior = res.prior.avg("test_mae")
    floor = (float(np.mean(np.abs(true.loc[ds.test_index].to_numpy()
                                  - y_test.to_numpy()))) if true is not None else None)
    return dict(dataset=name, seed=seed, prior=prior, peer=float(np.mean(peer)),
                workbench=res.model.avg("test_mae"), floor=floor, selected=res.model.selected,
                peer_s=peer_s, workbench_s=wb_s)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--datasets", nargs="+", default=["chain", "grid", "none", "google"])
    parser.add_argument("--seeds", type=int, nargs="+", default=None,
                        help="default: chain 0-4, grid 0-2, none 0-2")
    parser.add_argument("--trials", type=int, default=50)
    parser.add_argument("--config", default=str(ROOT / "experiments" / "any_device.toml"))
    parser.add_argument("--google-config", default=str(ROOT / "experiments" / "hamiltonian.toml"))
    args = parser.parse_args()
    default_seeds = {"chain": range(5), "grid": range(3), "none": range(3), "google": [0]}
    rows = []
    print(f"{'dataset':<8}{'seed':>5}{'prior':>8}{'peer':>8}{'workbench':>10}{'floor':>8}"
          f"{'wb/peer':>9}  selected (seconds: peer, workbench)", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets:
            for seed in (args.seeds if args.seeds is not None else default_seeds[name]):
                if name == "google" and seed != 0:
                    continue
                r = run(name, seed, args, Path(tmp))
                rows.append(r)
                floor = f"{r['floor']:8.3f}" if r["floor"] is not None else f"{'-':>8}"
                print(f"{name:<8}{seed:>5}{r['prior']:8.3f}{r['peer']:8.3f}"
                      f"{r['workbench']:10.3f}{floor}{r['workbench'] / r['peer']:9.2f}  "
                      f"{','.join(sorted(set(r['selected'])))} "
                      f"({r['peer_s']:.0f}, {r['workbench_s']:.0f})", flush=True)
    for name in args.datasets:
        ratios = [r["workbench"] / r["peer"] for r in rows if r["dataset"] == name]
        if ratios:
            print(f"{name}: workbench / peer median {statistics.median(ratios):.2f}, "
                  f"worst {max(ratios):.2f} over {len(ratios)} seed(s)")


if __name__ == "__main__":
    main()
