"""Coverage and width of the conformal prediction intervals (``[intervals]``, 90% CV+), and
what they cost.

    python benchmarks/intervals.py [--parts google simulated] [--seeds 0 1 2]
                                   [--experiments 3000] [--no-cost]

* ``google``: the benchmark's paper split (95 training, 41 test rows) with
  ``experiments/hamiltonian.toml`` (the parameter-space model) and
  ``experiments/paper_main_body.toml`` (the paper's settings): per-target coverage of the 41
  test rows, mean widths, the CV estimate on the training rows, and the wall time with and
  without intervals (``--no-cost`` skips the run without). ``[evaluation]``'s extra
  estimates are switched off (they do not touch the intervals).
* ``simulated``: a simulated 5-site chain (default mismatches, ``--experiments`` rows, 30%
  test rows, split seed = seed), for each seed both families: ``experiments/
  simulated_device.toml`` (eigenvalue) and ``experiments/any_device.toml`` (hamiltonian),
  only their ``[data]`` pointed at the simulated CSV.

The intervals' method and level are the configs': 90% with 5 folds, CV+ (the default) except
``any_device.toml``, which uses ``method = "cv"`` (the model on all rows +- the out-of-fold
residual quantile). That choice was made after CV+ over-covered with this config on seeds
0-5 (92.9% on average; its fold models make their own selections, and CV+ widens by their
disagreement); seeds 6-8 had not been run before it (``--seeds 6 7 8``). Nothing is chosen
on the benchmark's test rows. Prints one line per run and, per part, the average test
coverage against the bands of issue 12 (benchmark: 85-95% on average over the targets, each
target 78-100%; simulated: 88-92% averaged over targets and seeds).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"
sys.path.insert(0, str(Path(__file__).resolve().parent))


def _quiet(cfg):
    """``cfg`` without ``[evaluation]``'s extra estimates (repeated and nested CV)."""
    return dataclasses.replace(cfg, evaluation=cfg.evaluation.model_copy(
        update={"cv_repeats": 0, "nested_folds": 0}))


def _line(label: str, res, seconds: float) -> str:
    m = res.model
    cover = " ".join(f"{c:6.1%}" for c in m.test_coverage)
    width = " ".join(f"{w:6.2f}" for w in m.test_width)
    return (f"{label:<34} coverage {cover} | avg {m.avg('test_coverage'):6.1%}  width "
            f"{width} | avg {m.avg('test_width'):6.2f}  CV cov {m.avg('cv_coverage'):6.1%} "
            f"width {m.avg('cv_width'):6.2f}  MAE {m.avg('test_mae'):.3f}  {seconds:5.0f} s")


def google(args) -> None:
    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.prepare import load_config

    print("Google 5-qubit benchmark, paper split (95 training / 41 test rows)", flush=True)
    for name in ("hamiltonian.toml", "paper_main_body.toml"):
        cfg = _quiet(load_config(EXPERIMENTS / name))
        start = time.perf_counter()
        res = evaluate(cfg)
        with_s = time.perf_counter() - start
        print(_line(name, res, with_s), flush=True)
        cover = np.asarray(res.model.test_coverage)
        ok = 0.85 <= cover.mean() <= 0.95 and cover.min() >= 0.78
        print(f"  band 85-95% average, each target 78-100%: "
              f"{'inside' if ok else 'MISSED'}", flush=True)
        if not args.no_cost:
            off = dataclasses.replace(cfg, intervals=cfg.intervals.model_copy(
                update={"enabled": False}))
            start = time.perf_counter()
            evaluate(off)
            without_s = time.perf_counter() - start
            print(f"  wall: {with_s:.0f} s with intervals, {without_s:.0f} s without "
                  f"(x{with_s / without_s:.1f}, +{with_s - without_s:.0f} s)", flush=True)


def simulated(args) -> None:
    from peers import write_config

    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.prepare import load_config
    from workbench.simulate import Mismatch, simulate, write_simulation

    print(f"Simulated 5-site chain, {args.experiments} experiments (30% test rows), default "
          f"mismatches", flush=True)
    configs = {"eigenvalue": EXPERIMENTS / "simulated_device.toml",
               "hamiltonian": EXPERIMENTS / "any_device.toml"}
    cover: dict[str, list[float]] = {k: [] for k in configs}
    with tempfile.TemporaryDirectory(prefix="workbench-intervals-") as tmp:
        for seed in args.seeds:
            csv = Path(tmp) / f"device_{seed}.csv"
            write_simulation(simulate(5, args.experiments, device_seed=seed,
                                      mismatch=Mismatch.default()), csv)
            for family, base in configs.items():
                data = tomllib.loads(base.read_text())["data"]
                data.update(csv=str(csv), split_seed=seed)
                cfg = _quiet(load_config(write_config(base, data,
                                                      Path(tmp) / f"{family}_{seed}.toml")))
                start = time.perf_counter()
                res = evaluate(cfg)
                print(_line(f"{family} ({base.name}) seed {seed}", res,
                            time.perf_counter() - start), flush=True)
                cover[family].append(res.model.avg("test_coverage"))
    for family, values in cover.items():
        avg = float(np.mean(values))
        print(f"{family}: average test coverage over seeds {args.seeds}: {avg:.1%} "
              f"(band 88-92%: {'inside' if 0.88 <= avg <= 0.92 else 'MISSED'})", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", nargs="+", default=["google", "simulated"],
                        choices=["google", "simulated"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--experiments", type=int, default=3000)
    parser.add_argument("--no-cost", action="store_true",
                        help="skip the benchmark runs without intervals")
    args = parser.parse_args()
    if "google" in args.parts:
        google(args)
    if "simulated" in args.parts:
        simulated(args)


if __name__ == "__main__":
    main()
