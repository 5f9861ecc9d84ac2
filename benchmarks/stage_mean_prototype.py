"""Prototype of the mean of the stages over the candidates' priors (issue 42), measured on
the inner splits before it is built (``benchmarks/decisions/stage_mean.md``).

Fits ``init``'s template through ``evaluate`` on one inner split of
``benchmarks/parametric_outside.py`` (training rows only), keeps every stage
:class:`~workbench.fitted_prior.FittedPriorBoost` fits on a candidate's prior (its
``_choose_prior`` patched here to hold them: the product does not keep them), then per
target scores the mean of those stages by the MAE of the mean of their CV predictions and
keeps it where that is the lowest stage CV MAE. Prints and records the template's (B') and
the prototype's (M) validation MAE.

    PYTHONPATH=$PWD OMP_NUM_THREADS=1 python benchmarks/stage_mean_prototype.py \\
        --splits random far --json benchmarks/results/parametric_outside_stage_mean_inner_a.json
"""

from __future__ import annotations

import inspect
import sys
import textwrap
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import parametric_outside as po  # noqa: E402

from workbench.fitted_prior import FittedPriorBoost  # noqa: E402


def _keep_stages() -> None:
    """Patch ``FittedPriorBoost._choose_prior`` to keep its stages (``kept_stages_``)."""
    src = textwrap.dedent(inspect.getsource(FittedPriorBoost._choose_prior))
    anchor = "        self.stage_cv_mae_ = pd.DataFrame(cv, index=list(Y_frame.columns))\n"
    assert anchor.strip() in src
    src = src.replace(anchor.strip(), anchor.strip() + "\n    self.kept_stages_ = {k: stages[k] "
                      "for k in ['physics', *choosable]}", 1)
    import workbench.fitted_prior as module

    namespace = dict(vars(module))
    exec(src, namespace)  # noqa: S102 - a prototype's patch of one method
    FittedPriorBoost._choose_prior = namespace["_choose_prior"]


def measure(split: str) -> dict:
    """B' and M on one inner split."""
    cfg, ev, _, seconds = po.evaluate_inner(split)
    model, ds, X = po.fitted_rows(cfg, ev)
    X_val, Y = X.loc[ds.test_index], ds.targets.loc[ds.train_index].to_numpy(float)
    y_val = ds.targets.loc[ds.test_index].to_numpy(float)
    b = np.asarray(model.predict(X_val), dtype=float)
    stages = getattr(model, "kept_stages_", {"physics": model.boost_})
    cv = model.stage_cv_mae_
    row = {"split": split, "B": float(np.mean(np.abs(y_val - b))), "cpu_seconds": seconds,
           "stages": list(stages), "stage_cv_mae": None if cv is None else cv.to_dict()}
    m = b.copy()
    choice = []
    if len(stages) > 1:
        folds = [np.asarray(s.cv_folds_) for s in stages.values()]
        assert all(np.array_equal(folds[0], f) for f in folds), "the stages' folds differ"
        mean_cv = np.mean([np.asarray(s.cv_predictions_, dtype=float)
                           for s in stages.values()], axis=0)
        mean_mae = np.mean(np.abs(Y - mean_cv), axis=0)
        preds = []
        for name, stage in stages.items():
            fitted = model.physics_ if name == "physics" else model.alternatives_[name]
            prior = np.asarray(fitted.predict(X_val), dtype=float).reshape(b.shape)
            preds.append(np.asarray(stage.predict(model._with_prior(X_val, prior)), dtype=float))
        for j in range(b.shape[1]):
            best_single = float(min(cv.iloc[j][k] for k in stages))
            use = float(mean_mae[j]) < best_single
            choice.append("mean" if use else "single")
            if use:
                m[:, j] = np.mean([p[:, j] for p in preds], axis=0)
        row["mean_cv_mae"] = [float(v) for v in mean_mae]
    row["M"] = float(np.mean(np.abs(y_val - m)))
    row["choice"] = choice or ["single (one prior)"]
    return row


def main() -> None:
    _keep_stages()
    po.prototype_main(__doc__, measure, lambda r: (
        f"B' {r['B']:.5g}, M {r['M']:.5g} (M / B' {r['M'] / r['B']:.3f}; {r['choice']}; "
        f"stage CV {r['stage_cv_mae']}, mean {r.get('mean_cv_mae')})"))

if __name__ == "__main__":
    main()
