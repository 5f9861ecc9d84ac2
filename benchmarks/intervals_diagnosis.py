"""Why the CV+ intervals of the parameter-space config over-cover on the simulated device.

    python benchmarks/intervals_diagnosis.py [--seed 0] [--experiments 3000]

Fits ``experiments/any_device.toml`` (its ``[data]`` pointed at a simulated 5-site chain, as
``benchmarks/intervals.py`` does) and prints, per target: the test coverage and width of the
CV+ intervals; of the full model's prediction +- q (q: the conformal quantile of the
out-of-fold residuals); the fold models' spread at the test rows (sd over the 5 fold
models); the test MAE of the full model, the out-of-fold MAE and the fold models' test MAE;
and what each model chose per target. A diagnostic: nothing is chosen from its numbers.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    from peers import write_config

    from workbench.conformal import conformal_rank
    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.intervals import family_model
    from workbench.experiment.runs.prepare import load_config
    from workbench.simulate import Mismatch, simulate, write_simulation

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--experiments", type=int, default=3000)
    args = parser.parse_args()
    base = ROOT / "experiments" / "any_device.toml"
    with tempfile.TemporaryDirectory(prefix="workbench-diagnosis-") as tmp:
        csv = Path(tmp) / "device.csv"
        write_simulation(simulate(5, args.experiments, device_seed=args.seed,
                                  mismatch=Mismatch.default()), csv)
        data = tomllib.loads(base.read_text())["data"]
        data.update(csv=str(csv), split_seed=args.seed)
        cfg = load_config(write_config(base, data, Path(tmp) / "config.toml"))
        cfg = dataclasses.replace(cfg, evaluation=cfg.evaluation.model_copy(
            update={"cv_repeats": 0, "nested_folds": 0}))
        run = evaluate(cfg, return_model=True)
    model, ds = run.model, run.dataset
    X = cfg.family.inputs(cfg, ds).loc[ds.test_index]
    y = ds.targets.loc[ds.test_index].to_numpy(dtype=float)
    iv = model.predict_interval(X)
    point = np.asarray(model.predict(X), dtype=float)
    R = model.residuals_
    q = np.partition(R, conformal_rank(len(R), model.alpha) - 1, axis=0)[
        conformal_rank(len(R), model.alpha) - 1]
    folds = np.stack([np.asarray(e.predict(X), dtype=float) for e in model.estimators_])

    def show(label, values):
        print(f"{label:<34}" + " ".join(f"{v:7.3f}" for v in values), flush=True)

    print(f"seed {args.seed}, {len(R)} training / {len(y)} test rows; targets "
          f"{ds.target_names}")
    show("CV+ coverage", np.mean((y >= iv[..., 0]) & (y <= iv[..., 1]), axis=0))
    show("CV+ mean width", np.mean(iv[..., 1] - iv[..., 0], axis=0))
    show("full model +- q coverage", np.mean(np.abs(y - point) <= q, axis=0))
    show("2 q", 2 * q)
    show("fold models' sd at test rows", folds.std(axis=0).mean(axis=0))
    show("test MAE, full model", np.abs(y - point).mean(axis=0))
    show("out-of-fold MAE (training rows)", R.mean(axis=0))
    show("test MAE, fold models", np.abs(y[None] - folds).mean(axis=(0, 1)))
    for name, est in [("full", family_model(model))] + [
            (f"fold {k}", e) for k, e in enumerate(model.estimators_)]:
        selection = getattr(est.physics_, "selection_", None)
        steps = None if selection is None else len(selection.path) - 1
        print(f"{name:<7} chose {cfg.family.selected(est, ds.target_names)}; covariates "
              f"added by the selection: {steps}")


if __name__ == "__main__":
    main()
