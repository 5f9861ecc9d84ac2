"""``reproduce``'s second benchmark: the IBM two-qubit gates (:mod:`workbench.datasets.ibm_gates`).

Three systems on the honest split (the snapshots taken from 2025 on held out: newer devices
on later dates): the coherence limit (the prior), the peer (LightGBM boosted from the prior,
tuned by CV: :mod:`.peer`) and the recommended generic config (``experiments/generic.toml``);
each scored once on the test rows, with 95% bootstrap intervals and the paired intervals of
each system's gain over the prior and of the generic config's over the peer.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .bootstrap import bootstrap_description, bootstrap_error_interval, bootstrap_test_scores
from .config import ExperimentConfig
from .evaluate import evaluate
from .families.stage import candidate_settings
from .figures import model_comparison_bars
from .intervals import family_model
from .peer import PEER_TRIALS, peer_predict
from .prepare import load_config
from .results import ModelScores, Result, Scores, mae, mse
from .systems import Stopwatch

__all__ = ["GATE_SYSTEMS", "Gates", "gates_benchmark", "gates_section"]


#: The benchmark's systems: key -> (its MLflow run's and table row's name, its description).
GATE_SYSTEMS = {
    "gates_prior": ("IBM gates: coherence limit",
                    "The error T1 and T2 alone cause during each two-qubit gate (the prior), "
                    "scored on the test rows (snapshots from 2025 on)."),
    "gates_peer": ("IBM gates: LightGBM from the prior, tuned by CV",
                   "The peer: LightGBM boosted from the coherence limit (init_score) on the "
                   "prior and the features, 50 Optuna trials of 5-fold CV on the training "
                   "rows, LightGBM's objective (squared, absolute, Huber) searched too "
                   "(workbench.experiment.peer)."),
    "gates_generic": ("IBM gates: base boosting, generic config",
                      "The recommended generic config (`experiments/generic.toml`): per "
                      "target a ridge stage, one of the LightGBM stages drawn from the peer's "
                      "search space, or the prior alone, chosen by 5-fold CV on the training "
                      "rows (each device whole in a fold)."),
}


@dataclass
class Gates:
    """The benchmark's results: the generic config's and the peer's (the peer's ``model``
    scores, its ``prior`` the coherence limit's), the peer's chosen settings, the paired
    interval of generic - peer test MAE, and each system's stopwatch."""

    generic: Result
    peer: Result
    peer_params: list[dict]
    generic_minus_peer: list[float]
    chosen: list[str]
    config: ExperimentConfig
    dataset: Any
    watches: dict[str, Stopwatch] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"generic": self.generic.to_json(), "peer": self.peer.to_json(),
                "peer_params": self.peer_params, "generic_chosen": self.chosen,
                "generic_minus_peer_test_mae_avg_ci": self.generic_minus_peer}


def gates_benchmark(configs: Path, seed: int, quick: bool, say) -> Gates:
    """Fit the generic config and the peer on the training rows, score both once."""
    watches = {key: Stopwatch() for key in GATE_SYSTEMS}
    cfg = load_config(configs / "generic.toml")
    model = cfg.model if not quick else cfg.model.model_copy(update={"draws": 3})
    cfg = replace(cfg, random_state=seed, model=model,
                  intervals=cfg.intervals.model_copy(update={"enabled": False}))
    say("IBM two-qubit gates: the generic config (experiments/generic.toml)")
    with watches["gates_generic"]:
        run = evaluate(cfg, return_model=True)
    ds = run.dataset
    X_train, X_test, y_train, y_test = ds.split()
    trials = 2 if quick else PEER_TRIALS
    say(f"IBM two-qubit gates: the peer (LightGBM from the prior, {trials} trials of 5-fold "
        "CV, objective searched)")
    with watches["gates_peer"]:
        peer = peer_predict(X_train, y_train, X_test, ds.prior_names, ds.feature_names,
                            trials=trials, seed=seed, n_jobs=2)
    y = y_test.to_numpy(dtype=float)
    prior_pred = X_test[ds.prior_names].to_numpy(dtype=float)
    prior = Scores(test_mae=mae(y, prior_pred), test_mse=mse(y, prior_pred), cv_mae=[],
                   cv_mse=[])
    scores = ModelScores(test_mae=mae(y, peer.predictions), test_mse=mse(y, peer.predictions),
                         cv_mae=[], cv_mse=[], selected=["boosted"] * y.shape[1])
    boot = bootstrap_test_scores(prior, scores, y, prior_pred, peer.predictions,
                                 random_state=seed)
    peer_result = Result(name="peer", config=None, family="lightgbm peer",
                         targets=ds.target_names, n_train=len(X_train), n_test=len(X_test),
                         prior=prior, model=scores, bootstrap=boot, wall_s=peer.seconds)
    generic_pred = np.asarray(run.model.predict(X_test), dtype=float).reshape(y.shape)
    diff = bootstrap_error_interval(y - generic_pred, baseline=y - peer.predictions,
                                    random_state=seed).average
    watches["gates_prior"].started = watches["gates_prior"].ended = \
        watches["gates_generic"].ended
    chosen = [f"{getattr(e, 'selected_candidate_', None) or e.selected_}"
              + (f" (stage coefficient {e.best_estimator_.coefs_[0]:.3f})"
                 if e.selected_ == "boosted" else "")
              for e in family_model(run.model).estimators_]
    return Gates(generic=run.result, peer=peer_result, peer_params=peer.params,
                 generic_minus_peer=list(diff), chosen=chosen, config=cfg, dataset=ds,
                 watches=watches)


def gates_figure(gates: Gates):
    """Test MAE of the three systems with their 95% intervals."""
    g, p = gates.generic, gates.peer
    names = [GATE_SYSTEMS[k][0].removeprefix("IBM gates: ") for k in GATE_SYSTEMS]
    values = dict(zip(names, (g.prior.test_mae, p.model.test_mae, g.model.test_mae)))
    intervals = dict(zip(names, (g.prior.ci("test_mae"), p.model.ci("test_mae"),
                                 g.model.ci("test_mae"))))
    return model_comparison_bars(
        g.targets, values, metric="MAE", unit="% error",
        intervals={k: v for k, v in intervals.items() if v is not None},
        title="IBM two-qubit gates, newer devices held out: test MAE")


def gates_section(gates: Gates, row, figure: str) -> str:
    """The report's section on the benchmark; ``row(name, result_or_scores...)`` draws a
    table row as the Google table does."""
    g, p = gates.generic, gates.peer
    ds = gates.dataset
    n_dev_train = ds.groups[ds.train_index].nunique()
    n_dev_test = ds.groups[ds.test_index].nunique()
    d = gates.generic_minus_peer
    head = ("| system | gate error | average | model - coherence limit, average |\n"
            "|---|---|---|---|")
    rows = [row("coherence limit (prior)", g.prior.test_mae, ci=g.prior.ci("test_mae")),
            row("LightGBM from the prior, tuned by CV (peer)", p.model.test_mae,
                ci=p.model.ci("test_mae"), diff=p.model.test_mae_diff_avg_ci or None),
            row("workbench, generic config", g.model.test_mae, ci=g.model.ci("test_mae"),
                diff=g.model.test_mae_diff_avg_ci or None)]
    ratio = g.model.avg("test_mae") / p.model.avg("test_mae")
    n_candidates = len(candidate_settings(gates.config.model_for(g.targets[0]), 0))
    return f"""## A second benchmark: IBM two-qubit gates

The calibration snapshots of {ds.groups.nunique()} IBM Quantum devices (2020-2026, shipped
in `qiskit-ibm-runtime`'s fake provider; Apache-2.0): one row per two-qubit gate, the target
its measured error (percent), the prior the error that the two qubits' T1 and T2 alone cause
during the gate (the coherence limit), the features the qubits' T1, T2, readout and
single-qubit gate errors, the gate's length, the device's size and the gate type. The honest
split holds out the snapshots taken from 2025 on: {len(ds.test_index)} gates of
{n_dev_test} devices never seen in training, on later dates, against {len(ds.train_index)}
training gates of {n_dev_train} devices. Every choice is made by CV on the training rows.

Test mean absolute error (percentage points of gate error), with 95% bootstrap intervals
over the test rows ({bootstrap_description(gates.peer.bootstrap)}):

{head}
{chr(10).join(rows)}

The generic config's error is {ratio:.3f} of the peer's (paired 95% interval of the
difference, generic - peer: {d[0]:+.3f} to {d[1]:+.3f}). Both learn from the same rows and
features. CV chose {", ".join(gates.chosen)} among {n_candidates} candidates and the
prior alone. `benchmarks/peers.py` repeats the comparison on the devices split (30% of the
devices held out at random) and on the other benchmarks.

{figure}
"""
