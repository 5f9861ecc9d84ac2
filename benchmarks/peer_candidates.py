"""Candidates the peer's strength suggests, offered to the generic config's CV beside its own.

Used by ``benchmarks/peer_gap.py`` (``VARIANTS``' extra candidate kinds):

* ``"tuned"``: the peer itself as one more candidate: a base-boosting stage whose basis
  (:class:`TunedLGBM`) runs the peer's own search (its space and objectives, Optuna's TPE,
  shuffled 5-fold CV, ``trials`` trials) on the rows it is fitted on, inside every CV fold
  (``"tuned10"``: 10 trials, the reduced run);
* ``"peer_params"``: the peer's chosen settings (tuned by its search on all the rows the
  config is fitted on) as one fixed LightGBM candidate: cheap (six fits), but its CV score is
  optimistic (the search saw every fold's rows), which tilts CV towards it;
* ``"halving"``: per link, the drawn LightGBM candidates' settings raced by successive
  halving inside every fit (:class:`workbench.halving.HalvingChoiceCV`), one candidate
  beside them (``[model] tune = "halving"`` makes it instead of them);
* ``"early"``: a LightGBM stage stopped early on a tenth of the rows it is fitted on
  (:class:`EarlyLGBM`: 2000 rounds at most, learning rate 0.05, l1 objective).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from lightgbm import LGBMRegressor, early_stopping
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.model_selection import KFold

TUNED_TRIALS = 30


class TunedLGBM(RegressorMixin, BaseEstimator):
    """LightGBM tuned as the peer is (``workbench.experiment.paper.peer``), on the rows it
    is fitted on."""

    def __init__(self, trials: int = TUNED_TRIALS, random_state: int | None = 0) -> None:
        self.trials = trials
        self.random_state = random_state

    def fit(self, X: Any, y: Any) -> TunedLGBM:
        import optuna

        from workbench.experiment.paper.peer import PEER_OBJECTIVES, _suggest

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        X, y = np.asarray(X, dtype=float), np.asarray(y, dtype=float)
        seed = self.random_state or 0
        folds = list(KFold(5, shuffle=True, random_state=seed).split(X))

        def make(params: dict) -> LGBMRegressor:
            return LGBMRegressor(n_jobs=1, verbose=-1, random_state=seed, subsample_freq=1,
                                 **params)

        def objective(trial: Any) -> float:
            params = _suggest(trial, PEER_OBJECTIVES)
            return float(np.mean([np.mean(np.abs(y[v] - make(params).fit(X[f], y[f])
                                                 .predict(X[v]))) for f, v in folds]))

        study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=seed))
        study.optimize(objective, n_trials=self.trials)
        self.best_params_ = dict(study.best_params)
        self.model_ = make(self.best_params_).fit(X, y)
        return self

    def predict(self, X: Any) -> np.ndarray:
        return self.model_.predict(np.asarray(X, dtype=float))


class EarlyLGBM(RegressorMixin, BaseEstimator):
    """LightGBM stopped early on a random tenth of its rows, then refitted on all of them
    with the rounds found."""

    def __init__(self, objective: str = "regression_l1", learning_rate: float = 0.05,
                 num_leaves: int = 8, random_state: int | None = 0) -> None:
        self.objective = objective
        self.learning_rate = learning_rate
        self.num_leaves = num_leaves
        self.random_state = random_state

    def fit(self, X: Any, y: Any) -> EarlyLGBM:
        X, y = np.asarray(X, dtype=float), np.asarray(y, dtype=float)
        rng = np.random.default_rng(self.random_state or 0)
        held = rng.random(len(y)) < 0.1
        params = dict(objective=self.objective, learning_rate=self.learning_rate,
                      num_leaves=self.num_leaves, min_child_samples=10, subsample=0.8,
                      subsample_freq=1, colsample_bytree=0.8, n_jobs=1, verbose=-1,
                      random_state=self.random_state or 0)
        probe = LGBMRegressor(n_estimators=2000, **params).fit(
            X[~held], y[~held], eval_X=(X[held],), eval_y=(y[held],), eval_metric="l1",
            callbacks=[early_stopping(50, verbose=False)])
        self.n_rounds_ = max(10, int(probe.best_iteration_ or 2000))
        self.model_ = LGBMRegressor(n_estimators=self.n_rounds_, **params).fit(X, y)
        return self

    def predict(self, X: Any) -> np.ndarray:
        return self.model_.predict(np.asarray(X, dtype=float))


BASES = {"tuned": lambda seed: TunedLGBM(random_state=seed),
         "tuned10": lambda seed: TunedLGBM(trials=10, random_state=seed),
         "early": lambda seed: EarlyLGBM(random_state=seed)}


def _basis(kind: str, seed: int, peer_params: dict | None) -> Any:
    if kind == "peer_params":
        return LGBMRegressor(n_jobs=1, verbose=-1, random_state=seed, subsample_freq=1,
                             **(peer_params or {}))
    return BASES[kind](seed)


def _add_halving(est: Any) -> None:
    """Beside the drawn LightGBM candidates of one target's ``BasisChoiceCV``, one per link
    whose basis races their settings by successive halving inside every fit."""
    from workbench.halving import HalvingChoiceCV

    drawn = [(n, c) for n, c in est.candidates if n.startswith("lightgbm#")]
    added = []
    for link in dict.fromkeys(c.get_params()["link"] for _, c in drawn):
        mine = [c for _, c in drawn if c.get_params()["link"] == link]
        basis = HalvingChoiceCV([(f"d{i:02d}", clone(c.basis)) for i, c in enumerate(mine)])
        added.append((f"lightgbm#halving/{link}", clone(mine[0]).set_params(basis=basis)))
    est.set_params(candidates=list(est.candidates) + added)


def add_candidates(model: Any, kinds: tuple[str, ...], cfg: Any, ds: Any,
                   peer_params: list[dict] | None = None) -> None:
    """Append ``kinds`` (:data:`BASES`, or ``"peer_params"``: ``peer_params[j]`` for target
    ``j``) to each target's candidates of the unfitted ``MultiTargetBaseBoost`` ``model``: a
    copy of its first identity-link LightGBM candidate (the same inputs, line search and
    bounds) with the basis replaced."""
    seed = cfg.random_state or 0
    for j, est in enumerate(model.target_estimators.values()):
        if "halving" in kinds:
            _add_halving(est)
            if kinds == ("halving",):
                continue
        template = next(c for n, c in est.candidates if n.startswith("lightgbm")
                        and c.get_params()["link"] == "identity")
        added = [(kind, clone(template).set_params(
                    basis=_basis(kind, seed, peer_params[j] if peer_params else None)))
                 for kind in kinds if kind != "halving"]
        est.set_params(candidates=list(est.candidates) + added)
