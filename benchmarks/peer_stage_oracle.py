"""Oracle (issue 42): the peer itself as the parametric family's stage, on the inner splits.

Issue 42's goal is the family at <= 0.75 of the peer's MAE on random splits; the best inner
ratio any of the family's candidates reached is 0.788-0.796
(``benchmarks/decisions/boost_template.md``). The family is a drift of the user's model's
parameters chosen by CV, then a generic stage boosted from the drift's out-of-fold
prediction. This replaces that stage by the peer itself: the same tuned LightGBM
(:func:`~workbench.experiment.paper.peer.peer_predict`, the same features, trials and seed as
the peer) boosted from the family's *drift prior* instead of from the calibrated model's
prediction. If even that stays above 0.75 of the peer, no stage tuned as hard as the peer on
this drift reaches the goal (a bound); if it gets below, a tuned stage is the way forward.

An oracle measured on training rows only: each split's inner split
(``parametric_outside.inner``, the training rows split again the same way), never a test row.
Per split, fitted once through ``parametric_outside.evaluate_inner`` (``init``'s config), the
validation MAEs of

* ``prior``: the model at its start values;
* ``peer``: ``parametric_outside.peer`` (the model calibrated on the inner training rows, the
  peer boosted from that prediction, :data:`TRIALS` trials);
* ``template``: the family's config as ``init`` writes it (``evaluate``'s model);
* ``peer_on_drift``: ``peer_predict`` with ``priors = [the drift prior]`` on the peer's
  features, the same trials and seed, trained on the family's out-of-fold prior of the inner
  training rows (``FittedPriorBoost.oof_prior_``, what the family's stage was trained on) and
  predicting the validation rows from ``predict_prior`` (the prior refitted on every training
  row);
* ``peer_on_drift_plus_calibrated``: the same with the calibrated model's prediction (the
  peer's own prior column, fitted on the inner training rows) as one more feature;
* ``peer_on_drift_insample``: ``peer_on_drift`` trained on the in-sample prior of the training
  rows (``predict_prior`` of the training rows, as the peer's calibrated prior is), a check of
  what the out-of-fold prior costs or gains;
* ``peer_on_physics``: only where the family's stage chose another prior than the physics
  model's (``prior_choice_`` not ``"physics"``, e.g. the calibrated alternative): the peer on
  the physics model's (the drift's) out-of-fold prior, recomputed with the family's folds.

with each one's ratio to the peer, what the family chose and the CPU-s of each part; also the
validation MAE of the drift prior alone (``drift_prior_alone``, the stage's prior as chosen)
and of the calibrated prediction alone (``calibrated_alone``).

    PYTHONPATH=$PWD OMP_NUM_THREADS=1 python benchmarks/peer_stage_oracle.py \\
        --splits fus_random --json benchmarks/results/peer_stage_oracle_a.json
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import parametric_outside as po  # noqa: E402

from workbench.fitted_prior import FittedPriorBoost  # noqa: E402

#: the peer's Optuna trials, here and in every peer_on_* system (the environment variable
#: ``PEER_STAGE_TRIALS`` sets another number, a check of the ratios' sensitivity to it)
TRIALS = int(os.environ.get("PEER_STAGE_TRIALS", "20"))
SEED = 0


def inner_frame(split: str) -> tuple[po.Field, pd.DataFrame]:
    """The split's field and inner frame, as ``parametric_outside.evaluate_inner`` builds it."""
    if split in po.FIELD_SPLITS:
        field, frame = po.field_table(split)
    else:
        field = po.CRITICAL if split == "critical" else po.NUCLEAR
        frame = po.critical_table() if split == "critical" else po.table()
    return field, po.inner(frame, split)


def calibrated(frame: pd.DataFrame, test: np.ndarray, field: po.Field) -> np.ndarray:
    """The peer's prior column (``parametric_outside.peer``'s calibration) on every row."""
    from workbench.param_regressor import ParametricRegressor

    X = frame[list(field.features)]
    cal = ParametricRegressor(model=str(field.model), loss="huber", huber_delta=1.0,
                              max_iter=0)
    cal.fit(X[~test], frame.loc[~test, field.target].to_numpy(float))
    return np.asarray(cal.predict(X), dtype=float).reshape(len(X), -1)[:, 0]


def on_prior(frame: pd.DataFrame, test: np.ndarray, field: po.Field, train_prior: np.ndarray,
             val_prior: np.ndarray, extra: dict[str, np.ndarray] | None = None
             ) -> tuple[np.ndarray, dict, float]:
    """``peer_predict`` from the given prior (training rows' and validation rows'), on the
    peer's features (and ``extra`` feature columns): validation predictions, params, CPU-s."""
    from workbench.experiment.paper.peer import peer_predict

    features = list(field.peer_features)
    data = frame[features].copy()
    prior = np.empty(len(frame))
    prior[~test], prior[test] = train_prior, val_prior
    data["drift_prior"] = prior
    for name, col in (extra or {}).items():
        data[name] = col
    t0 = time.process_time()
    fit = peer_predict(data[~test], frame.loc[~test, [field.target]], data[test],
                       ["drift_prior"], [*features, *(extra or {})], trials=TRIALS,
                       random_state=SEED)
    return fit.predictions[:, 0], {"peer_params": fit.params}, time.process_time() - t0


def physics_oof(model: FittedPriorBoost, X: pd.DataFrame, y: np.ndarray) -> np.ndarray:
    """The physics model's out-of-fold prior on the training rows, with the family's folds
    (as ``FittedPriorBoost.fit`` computes it before choosing among priors)."""
    from sklearn.model_selection import check_cv

    splits = list(check_cv(model.cv).split(X))
    held = np.zeros(len(X), dtype=bool)
    for _, val in splits:
        held[val] = True
    never = np.flatnonzero(~held)
    tasks = [*splits, *([(never, never)] if len(never) else [])]
    return model._out_of_fold(model.physics_, X, y.reshape(-1, 1), tasks)[:, 0]


def measure(split: str) -> dict:
    """Every system on one inner split."""
    cfg, ev, field, template_s = po.evaluate_inner(split)
    model, ds, X = po.fitted_rows(cfg, ev)
    X_tr, X_val = X.loc[ds.train_index], X.loc[ds.test_index]
    y_tr = ds.targets.loc[ds.train_index].to_numpy(float)[:, 0]
    y_val = ds.targets.loc[ds.test_index].to_numpy(float)[:, 0]
    template = np.asarray(ev.model.predict(X_val), dtype=float).reshape(len(X_val), -1)[:, 0]

    field_, frame = inner_frame(split)
    assert field_ == field
    test = frame[f"test_{split}"].to_numpy(bool)
    target = frame[field.target].to_numpy(float)
    # the rows line up: the dataset's training / validation rows are the frame's, in order
    assert len(y_tr) == (~test).sum() and len(y_val) == test.sum(), (len(y_tr), len(y_val))
    assert np.array_equal(target[~test], y_tr) and np.array_equal(target[test], y_val)
    assert np.allclose(frame.loc[~test, list(field.features)].to_numpy(float),
                       X_tr[list(field.features)].to_numpy(float))
    assert np.allclose(frame.loc[test, list(field.features)].to_numpy(float),
                       X_val[list(field.features)].to_numpy(float))
    oof = model.oof_prior_
    assert list(oof.index) == list(X_tr.index) and oof.shape[1] == 1
    oof = oof.to_numpy(float)[:, 0]
    new = np.asarray(model.predict_prior(X_val), dtype=float)[:, 0]
    insample = np.asarray(model.predict_prior(X_tr), dtype=float)[:, 0]

    preds = {"prior": frame.loc[test, field.prior].to_numpy(float), "template": template,
             "drift_prior_alone": new}
    seconds = {"template": template_s}
    details: dict = {}
    t0 = time.process_time()
    preds["peer"], details["peer"] = po.peer(frame, test, TRIALS, field)
    seconds["peer"] = time.process_time() - t0
    t0 = time.process_time()
    cal = calibrated(frame, test, field)
    seconds["calibration"] = time.process_time() - t0
    preds["calibrated_alone"] = cal[test]
    assert np.isclose(np.mean(np.abs(cal[test] - y_val)),
                      details["peer"]["calibrated_test_mae"])
    preds["peer_on_drift"], details["peer_on_drift"], seconds["peer_on_drift"] = on_prior(
        frame, test, field, oof, new)
    (preds["peer_on_drift_plus_calibrated"], details["peer_on_drift_plus_calibrated"],
     seconds["peer_on_drift_plus_calibrated"]) = on_prior(frame, test, field, oof, new,
                                                          {"calibrated": cal})
    (preds["peer_on_drift_insample"], details["peer_on_drift_insample"],
     seconds["peer_on_drift_insample"]) = on_prior(frame, test, field, insample, new)
    choice = [str(c) for c in model.prior_choice_]
    if choice != ["physics"]:
        t0 = time.process_time()
        phys = physics_oof(model, X_tr, y_tr)
        phys_new = np.asarray(model.physics_.predict(X_val), dtype=float).reshape(
            len(X_val), -1)[:, 0]
        preds["peer_on_physics"], details["peer_on_physics"], s = on_prior(
            frame, test, field, phys, phys_new)
        seconds["peer_on_physics"] = time.process_time() - t0
        preds["physics_alone"] = phys_new
    mae = {k: float(np.mean(np.abs(y_val - p))) for k, p in preds.items()}
    info = ev.result.details.get("parametric", {})
    return {"split": split, "train_rows": int((~test).sum()),
            "validation_rows": int(test.sum()), "mae": mae,
            "over_peer": {k: v / mae["peer"] for k, v in mae.items()},
            "goal_ratio": po.GOALS[split],
            "family_choice": info.get("choice"), "family_choices": info.get("choices"),
            "prior_choice": choice, "selected": list(ev.result.model.selected),
            "stage_cv_mae": (None if model.stage_cv_mae_ is None
                             else model.stage_cv_mae_.to_dict()),
            "oof_prior_train_mae": float(np.mean(np.abs(y_tr - oof))),
            "insample_prior_train_mae": float(np.mean(np.abs(y_tr - insample))),
            "calibrated_train_mae": float(np.mean(np.abs(y_tr - cal[~test]))),
            "drift_prior_equals_calibrated": bool(np.allclose(new, cal[test])),
            "cpu_seconds": seconds, "details": details}


def line(r: dict) -> str:
    m, q = r["mae"], r["over_peer"]
    names = ["prior", "peer", "template", "peer_on_drift", "peer_on_drift_plus_calibrated",
             "peer_on_drift_insample", *(["peer_on_physics"] if "peer_on_physics" in m else []),
             "drift_prior_alone", "calibrated_alone"]
    return (", ".join(f"{k} {m[k]:.5g} ({q[k]:.3f})" for k in names)
            + f"; choice {r['family_choice']}, prior {r['prior_choice']}; "
            + ", ".join(f"{k} {v:.0f}" for k, v in r["cpu_seconds"].items()) + " CPU-s")


def main() -> None:
    po.prototype_main(__doc__, measure, line, trials=TRIALS, seed=SEED)


if __name__ == "__main__":
    main()
