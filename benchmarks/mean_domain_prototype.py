"""Prototype of the mean of the stages only inside the training rows' domain (issue 42),
measured on the inner splits before it is built (``benchmarks/decisions/mean_in_domain.md``).

Fits ``init``'s config with ``stage_mean = true`` through ``evaluate`` on one inner split of
``benchmarks/parametric_outside.py`` (training rows only), then per target that keeps the mean
of the stages gives a validation row the mean only inside the training rows' domain
(:func:`in_domain`) and the single stage with the lowest CV MAE elsewhere. Records M (the mean
everywhere, as the product), M_D (the domain rule) and B' (every row outside: the template
without the mean), with the share of validation rows inside the domain.

    PYTHONPATH=$PWD OMP_NUM_THREADS=1 python benchmarks/mean_domain_prototype.py \\
        --splits random far --json benchmarks/results/mean_domain_inner_a.json
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import parametric_outside as po  # noqa: E402

#: the domain's neighbours and the training rows' quantile of their distances
K, QUANTILE = 5, 0.95


def in_domain(train: pd.DataFrame, new: pd.DataFrame) -> np.ndarray:
    """Per row of ``new``: inside the training rows' box in every feature, and its mean
    Euclidean distance to its ``K`` nearest training rows at most the ``QUANTILE`` of the
    training rows' own mean distances to their ``K`` nearest other training rows (features
    standardised by the training rows' mean and sd)."""
    from sklearn.neighbors import NearestNeighbors

    a, b = train.to_numpy(float), new.to_numpy(float)
    box = ((b >= a.min(axis=0)) & (b <= a.max(axis=0))).all(axis=1)
    sd = a.std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    za, zb = (a - a.mean(axis=0)) / sd, (b - a.mean(axis=0)) / sd
    nn = NearestNeighbors(n_neighbors=K + 1).fit(za)
    own = nn.kneighbors(za)[0][:, 1:].mean(axis=1)  # leaving each row itself out
    new_d = nn.kneighbors(zb, n_neighbors=K)[0].mean(axis=1)
    return box & (new_d <= np.quantile(own, QUANTILE))


def measure(split: str) -> dict:
    """B', M and M_D on one inner split."""
    cfg, ev, field, seconds = po.evaluate_inner(split, stage_mean="true")
    model, ds, X = po.fitted_rows(cfg, ev)
    X_val = X.loc[ds.test_index]
    y_val = ds.targets.loc[ds.test_index].to_numpy(float)
    m = np.asarray(model.predict(X_val), dtype=float)
    b = m.copy()
    features = list(field.features)
    inside = in_domain(X.loc[ds.train_index, features], X_val[features])
    if model.stages_:
        priors = model._priors(X_val)
        cv = model.stage_cv_mae_
        for j, kept in enumerate(model.prior_choice_):
            if kept != "mean":
                continue
            best = min(model.stages_, key=lambda k: float(cv.iloc[j][k]))
            stage = model.stages_[best]
            b[:, j] = np.asarray(stage.predict(model._with_prior(X_val, priors[best])),
                                 dtype=float)[:, j]
    d = np.where(inside[:, None], m, b)
    return {"split": split, "M": float(np.mean(np.abs(y_val - m))),
            "B": float(np.mean(np.abs(y_val - b))), "M_D": float(np.mean(np.abs(y_val - d))),
            "inside_share": float(inside.mean()), "validation_rows": int(len(y_val)),
            "choice": list(model.prior_choice_), "cpu_seconds": seconds}


def main() -> None:
    po.prototype_main(__doc__, measure, lambda r: (
        f"B' {r['B']:.5g}, M {r['M']:.5g}, M_D {r['M_D']:.5g} (M_D / B' "
        f"{r['M_D'] / r['B']:.3f}; inside {r['inside_share']:.2f}; {r['choice']})"),
        k=K, quantile=QUANTILE)

if __name__ == "__main__":
    main()
