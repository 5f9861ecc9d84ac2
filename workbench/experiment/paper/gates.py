"""``reproduce``'s second benchmark: the IBM two-qubit gates (:mod:`workbench.datasets.ibm_gates`).

Three systems on the honest split (the snapshots taken from 2025 on held out: newer devices
on later dates): the coherence limit (the prior), the peer (LightGBM boosted from the prior,
tuned by CV: :mod:`.peer`) and the recommended generic config (``experiments/generic.toml``);
each scored once on the test rows, with 95% bootstrap intervals and the paired intervals of
each system's gain over the prior and of the generic config's over the peer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ...datasets import Dataset
from ..config import ExperimentConfig
from ..figures import model_comparison_bars
from ..runs.evaluate import evaluate
from ..runs.intervals import family_model
from ..runs.prepare import load_config
from ..runs.run_fields import result_metrics, run_params, score_metrics
from ..scoring.bootstrap import bootstrap_error_interval, bootstrap_test_scores
from ..scoring.results import Result
from ..scoring.scores import ModelScores, Scores, mae, mse
from .peer import PEER_TRIALS, peer_predict
from .systems import Stopwatch, System

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["GATE_SYSTEMS", "Gates", "gate_systems", "gates_benchmark", "gates_figure"]


#: The benchmark's systems: key -> (its MLflow run's and table row's name, its description).
GATE_SYSTEMS = {
    "gates_prior": ("IBM gates: coherence limit",
                    "The error T1 and T2 alone cause during each two-qubit gate (the prior), "
                    "scored on the test rows (snapshots from 2025 on)."),
    "gates_peer": ("IBM gates: LightGBM from the prior, tuned by CV",
                   "The peer: LightGBM boosted from the coherence limit (init_score) on the "
                   "prior and the features, 50 Optuna trials of 5-fold CV on the training "
                   "rows, LightGBM's objective (squared, absolute, Huber) searched too "
                   "(workbench.experiment.paper.peer)."),
    "gates_generic": ("IBM gates: base boosting, generic config",
                      "The recommended generic config (`experiments/generic.toml`): per "
                      "target a ridge stage, one of the LightGBM stages drawn from the peer's "
                      "search space, or the prior alone, chosen by 5-fold CV on the training "
                      "rows (each device whole in a fold)."),
}


@dataclass
class Gates:
    """The IBM benchmark's results.

    Parameters
    ----------
    generic, peer : Result
        The generic config's and the peer's (the peer's ``model`` scores, its ``prior`` the
        coherence limit's).
    peer_params : list of dict
        The peer's chosen settings per target.
    generic_minus_peer : list of float
        The paired 95% interval of generic - peer test MAE.
    chosen : list of str
        What the generic config's CV chose per target.
    config : ExperimentConfig
        The generic config, as run.
    dataset : Dataset
        The IBM gates.
    watches : dict of str to Stopwatch
        Each system's time.
    """

    generic: Result
    peer: Result
    peer_params: list[dict]
    generic_minus_peer: list[float]
    chosen: list[str]
    config: ExperimentConfig
    dataset: Dataset
    watches: dict[str, Stopwatch] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """Write the benchmark's results as JSON (``results.json``'s ``ibm_gates``).

        Returns
        -------
        dict
            The generic config's and the peer's results, the peer's settings, what the
            generic config chose and the paired interval of generic - peer.
        """
        return {"generic": self.generic.to_json(), "peer": self.peer.to_json(),
                "peer_params": self.peer_params, "generic_chosen": self.chosen,
                "generic_minus_peer_test_mae_avg_ci": self.generic_minus_peer}


def gates_benchmark(configs: Path, random_state: int, quick: bool,
                    say: Callable[[str], None]) -> Gates:
    """Fit the generic config and the peer on the training rows, score both once.

    Parameters
    ----------
    configs : Path
        The folder holding ``generic.toml``.
    random_state : int
        Seeds the config, the peer's search and the bootstrap.
    quick : bool
        3 draws of the generic config's candidates and 2 trials of the peer's search.
    say : callable
        Shows a progress line.

    Returns
    -------
    Gates
        The benchmark's results.
    """
    watches = {key: Stopwatch() for key in GATE_SYSTEMS}
    cfg = load_config(configs / "generic.toml")
    model = cfg.model if not quick else cfg.model.model_copy(update={"draws": 3})
    cfg = replace(cfg, random_state=random_state, model=model,
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
                            trials=trials, random_state=random_state, n_jobs=2)
    y = y_test.to_numpy(dtype=float)
    prior_pred = X_test[ds.prior_names].to_numpy(dtype=float)
    prior = Scores(test_mae=mae(y, prior_pred), test_mse=mse(y, prior_pred), cv_mae=[],
                   cv_mse=[])
    scores = ModelScores(test_mae=mae(y, peer.predictions), test_mse=mse(y, peer.predictions),
                         cv_mae=[], cv_mse=[], selected=["boosted"] * y.shape[1])
    boot = bootstrap_test_scores(prior, scores, y, prior_pred, peer.predictions,
                                 random_state=random_state)
    peer_result = Result(name="peer", config=None, family="lightgbm peer",
                         targets=ds.target_names, n_train=len(X_train), n_test=len(X_test),
                         prior=prior, model=scores, bootstrap=boot, wall_s=peer.seconds,
                         unit=ds.unit)
    generic_pred = np.asarray(run.model.predict(X_test), dtype=float).reshape(y.shape)
    diff = bootstrap_error_interval(y - generic_pred, baseline=y - peer.predictions,
                                    random_state=random_state).average
    watches["gates_prior"].started = watches["gates_prior"].ended = \
        watches["gates_generic"].ended
    chosen = [f"{getattr(e, 'selected_candidate_', None) or e.selected_}"
              + (f" (stage coefficient {e.best_estimator_.coefs_[0]:.3f})"
                 if e.selected_ == "boosted" else "")
              for e in family_model(run.model).estimators_]
    return Gates(generic=run.result, peer=peer_result, peer_params=peer.params,
                 generic_minus_peer=list(diff), chosen=chosen, config=cfg, dataset=ds,
                 watches=watches)


def gates_figure(gates: Gates) -> Figure:
    """Draw the test MAE of the three systems with their 95% intervals.

    Parameters
    ----------
    gates : Gates
        The benchmark's results.

    Returns
    -------
    matplotlib.figure.Figure
        The bars.
    """
    g, p = gates.generic, gates.peer
    names = [GATE_SYSTEMS[k][0].removeprefix("IBM gates: ") for k in GATE_SYSTEMS]
    values = dict(zip(names, (g.prior.test_mae, p.model.test_mae, g.model.test_mae)))
    intervals = dict(zip(names, (g.prior.ci("test_mae"), p.model.ci("test_mae"),
                                 g.model.ci("test_mae"))))
    return model_comparison_bars(
        g.targets, values, metric="MAE", unit=gates.dataset.unit,
        intervals={k: v for k, v in intervals.items() if v is not None},
        title="IBM two-qubit gates, newer devices held out: test MAE")


def gate_systems(gates: Gates, figures: list[Path]) -> list[System]:
    """Gather the IBM benchmark's systems (:data:`GATE_SYSTEMS`) in the shared schema.

    Parameters
    ----------
    gates : Gates
        The benchmark's results.
    figures : list of Path
        The benchmark's figure (the peer's and the generic config's runs log it).

    Returns
    -------
    list of System
        The coherence limit, the peer and the generic config.
    """
    out = []
    targets, g, p = gates.generic.targets, gates.generic, gates.peer
    for key, (name, description) in GATE_SYSTEMS.items():
        watch = gates.watches[key]
        system = System(key, name, watch.started, watch.ended,
                        description=f"{description} Test rows scored once; errors in "
                                    "percentage points of gate error.",
                        figures=list(figures) if key != "gates_prior" else [])
        base = {"n_train": g.n_train, "n_test": g.n_test}
        if key == "gates_prior":
            system.metrics = score_metrics(targets, g.prior)
            system.params = {"system": "coherence limit", **base}
        elif key == "gates_peer":
            system.result, system.metrics = p, result_metrics(p, wall=False)
            system.params = {"system": "peer", **base,
                             **{f"{t}.{k}": v for t, params in zip(targets, gates.peer_params)
                                for k, v in params.items()}}
        else:
            system.config, system.result = gates.config, g
            system.metrics = result_metrics(g, wall=False)
            system.params = run_params(gates.config, targets, g.n_train, g.n_test)
        out.append(system)
    return out
