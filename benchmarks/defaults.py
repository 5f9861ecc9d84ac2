"""What the default commands cost, each as a whole ``workbench`` process (start-up included),
against the bare fit or a peer, paired and alternating (prints a table; no assertions).

    python benchmarks/defaults.py [--parts hamiltonian any_device single_target]
                                  [--repeats 5]

* ``hamiltonian``: ``workbench evaluate experiments/hamiltonian.toml`` as a user runs it
  (tracked into a store made beforehand, its 90% intervals, ``[evaluation]``'s repeated CV,
  the tables and figures, the model) against its bare fit (the same config with
  ``[evaluation] cv_repeats = 0``, ``--no-track --no-intervals``). Issue 19 asks the default
  to be <= 2.5x the bare fit and <= 60 s.
* ``any_device``: ``workbench evaluate experiments/any_device.toml`` (tracked, intervals)
  on a simulated 3x3 grid with 600 experiments (seed 0, default mismatches), its ``[data]``
  pointed at it; ``--repeats`` runs, no pairing (asked: <= 120 s).
* ``single_target``: one target of 2,353 simulated experiments (a 5-site chain, seed 0;
  the lowest eigenvalue, its control-model prediction as the prior, the 9 voltages as
  features; 30% test rows), the eigenvalue family with ``basis = ["ridge",
  "kernel_ridge", "lightgbm"]`` chosen by CV, 2 stages, Huber loss; the default command
  (tracked, intervals, curves, SHAP) against the peer: a LightGBM fitted to ``y - prior``
  on the prior and the voltages, tuned by a 24-point grid with 5-fold CV
  (``GridSearchCV``, both cores), as a whole process. Issue 19 asks <= 3x the peer.

Every process gets one BLAS/OpenMP thread (``OMP_NUM_THREADS=1`` ...) and may use both
cores through its worker processes. Prints each run's wall and CPU time (user + system of
the process and its children), the medians, the ratios and ``uptime`` before and after.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import tempfile
import tomllib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from peers import simulated, write_config  # noqa: E402
from vs_reference import THREADS, _run, _uptime  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"

SINGLE_TARGET = """name = "single_target"
random_state = 0

[data]
csv = "{csv}"
prior = ["model_E1"]
targets = ["measured_E1"]
features = ["v_q1", "v_q2", "v_q3", "v_q4", "v_q5", "v_c1", "v_c2", "v_c3", "v_c4"]
test_fraction = 0.3
split_seed = 0

[model]
basis = ["ridge", "kernel_ridge", "lightgbm"]
n_stages = 2
loss = "huber"
basis_inputs = "prior+features"
input_transform = "standard"

[selection]
cv = 5
shuffle = true
"""

PEER = """
import sys, time
import numpy as np, pandas as pd
from lightgbm import LGBMRegressor
from sklearn.model_selection import GridSearchCV, KFold, train_test_split
data = pd.read_csv(sys.argv[1])
features = ["model_E1"] + [f"v_q{k}" for k in range(1, 6)] + [f"v_c{k}" for k in range(1, 5)]
train, test = train_test_split(np.arange(len(data)), test_size=0.3, random_state=0)
X, y, prior = data[features].to_numpy(), data["measured_E1"].to_numpy(), data["model_E1"].to_numpy()
grid = {"n_estimators": [100, 300, 600], "learning_rate": [0.03, 0.1], "num_leaves": [7, 31],
        "min_child_samples": [5, 20]}
search = GridSearchCV(LGBMRegressor(n_jobs=1, verbose=-1, random_state=0), grid,
                      scoring="neg_mean_absolute_error", n_jobs=2,
                      cv=KFold(5, shuffle=True, random_state=0))
search.fit(X[train], y[train] - prior[train])
pred = prior[test] + search.predict(X[test])
print(f"peer test MAE {np.mean(np.abs(y[test] - pred)):.3f} best {search.best_params_}")
"""


def _median_line(name: str, a: str, wa: list[float], ca: list[float], b: str | None = None,
                 wb: list[float] | None = None, cb: list[float] | None = None) -> str:
    ma, mca = statistics.median(wa), statistics.median(ca)
    line = f"{name}: median {a} {ma:.1f} s wall ({mca:.1f} s CPU)"
    if b is not None and wb:
        mb, mcb = statistics.median(wb), statistics.median(cb)
        ratios = [x / y for x, y in zip(wa, wb)]
        line += (f", {b} {mb:.1f} s wall ({mcb:.1f} s CPU); {a} / {b} = {ma / mb:.2f} "
                 f"(median of paired ratios {statistics.median(ratios):.2f})")
    return line


def _paired(name: str, sides: dict[str, list[str]], env, repeats: int,
            show=lambda side, text: "") -> str:
    walls = {s: [] for s in sides}
    cpus = {s: [] for s in sides}
    names = list(sides)
    for rep in range(repeats):
        order = names if rep % 2 == 0 else names[::-1]
        for side in order:
            wall, cpu, text = _run(sides[side], env)
            walls[side].append(wall)
            cpus[side].append(cpu)
            print(f"{name} run {rep}: {side:<10} {wall:6.1f} s wall {cpu:6.1f} s CPU"
                  f"{show(side, text)}", flush=True)
    a, b = names[0], names[1] if len(names) > 1 else None
    line = _median_line(name, a, walls[a], cpus[a], b, walls.get(b), cpus.get(b))
    print(line, flush=True)
    return line


def _avg_mae(side, text) -> str:
    m = re.search(r"^average\s+[\d.]+\s+([\d.]+)", text, flags=re.M)
    peer = re.search(r"peer test MAE ([\d.]+)", text)
    return (f"  test MAE {m.group(1)}" if m else "") + (f"  {peer.group(0)}" if peer else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", nargs="+", default=["hamiltonian", "any_device",
                                                       "single_target"],
                        choices=["hamiltonian", "any_device", "single_target"])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    env = {**os.environ, **THREADS, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env.setdefault("MPLCONFIGDIR", "/tmp/workbench-bench-mpl")
    wb = [sys.executable, "-m", "workbench.experiment.cli"]
    print(f"load before: {_uptime()}")
    print(f"{os.cpu_count()} CPUs; one BLAS/OpenMP thread per process", flush=True)
    summary = []
    with tempfile.TemporaryDirectory(prefix="workbench-defaults-") as tmp:
        tmp = Path(tmp)
        store = f"sqlite:///{tmp / 'mlflow.db'}"
        _run([sys.executable, "-c", f"from mlflow import MlflowClient; "
              f"MlflowClient({store!r}).search_experiments()"], env)  # the store exists
        if "hamiltonian" in args.parts:
            raw = (EXPERIMENTS / "hamiltonian.toml").read_text()
            bare = tmp / "hamiltonian_bare.toml"
            bare.write_text(re.sub(r"^cv_repeats = \d+", "cv_repeats = 0", raw, flags=re.M))
            summary.append(_paired("hamiltonian", {
                "default": [*wb, "evaluate", str(EXPERIMENTS / "hamiltonian.toml"),
                            "--tracking-uri", store],
                "bare": [*wb, "evaluate", str(bare), "--no-track", "--no-intervals"]},
                env, args.repeats, _avg_mae))
        if "any_device" in args.parts:
            data, _ = simulated("grid", 0, tmp)
            cfg = write_config(EXPERIMENTS / "any_device.toml", data, tmp / "grid.toml")
            summary.append(_paired("any_device 3x3 grid 600", {
                "default": [*wb, "evaluate", str(cfg), "--tracking-uri", store]},
                env, args.repeats, _avg_mae))
        if "single_target" in args.parts:
            from workbench.simulate import Mismatch, simulate, write_simulation

            csv = tmp / "chain_2353.csv"
            write_simulation(simulate(5, 2353, device_seed=0, mismatch=Mismatch.default()), csv)
            cfg = tmp / "single_target.toml"
            cfg.write_text(SINGLE_TARGET.format(csv=csv))
            assert tomllib.loads(cfg.read_text())["data"]["csv"] == str(csv)
            summary.append(_paired("single target 2353", {
                "default": [*wb, "evaluate", str(cfg), "--tracking-uri", store],
                "peer": [sys.executable, "-c", PEER, str(csv)]},
                env, args.repeats, _avg_mae))
    print(f"load after:  {_uptime()}")
    print("\n".join(["summary:", *summary]))


if __name__ == "__main__":
    main()
