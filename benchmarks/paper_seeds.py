"""Spread of the paper-settings benchmark result over seeds (prints a table; no assertions).

    python benchmarks/paper_seeds.py [--seeds 0 1 2 3 4]

Intervals are off (the test MAE does not depend on them). Each run uses every core.
"""

import argparse
import dataclasses
import statistics

from workbench.experiment.runs.evaluate import evaluate
from workbench.experiment.runs.prepare import load_config


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", default="experiments/paper_main_body.toml")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    args = parser.parse_args()
    base = load_config(args.config)
    # the point predictions only: CV+ intervals would refit every model 5 more times
    base = dataclasses.replace(base, intervals=base.intervals.model_copy(
        update={"enabled": False}))
    avgs, walls = [], []
    for seed in args.seeds:
        res = evaluate(dataclasses.replace(base, random_state=seed)).to_json()
        maes = " ".join(f"{m:.3f}" for m in res["model"]["test_mae"])
        print(f"seed {seed}: per-target test MAE {maes}  avg {res['model']['test_mae_avg']:.4f}"
              f"  cv avg {res['model']['cv_mae_avg']:.4f}  {res['wall_s']:.1f} s", flush=True)
        avgs.append(res["model"]["test_mae_avg"])
        walls.append(res["wall_s"])
    print(f"avg test MAE: median {statistics.median(avgs):.4f}, min {min(avgs):.4f}, "
          f"max {max(avgs):.4f}, sd {statistics.pstdev(avgs):.4f}; "
          f"median wall {statistics.median(walls):.1f} s")


if __name__ == "__main__":
    main()
