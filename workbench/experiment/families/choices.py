"""The order CV chooses in; what it chose per target (among candidates, each stage's basis)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ...selection import BasisChoiceCV, paired_standard_error

__all__ = ["SIZE_PARAMS", "by_complexity", "candidate_choices"]

#: The basis parameters whose product is a drawn setting's size in :func:`by_complexity`:
#: a tree ensemble's trees times the leaves of each, the leaf values it fits.
SIZE_PARAMS = ("n_estimators", "num_leaves")


def by_complexity(candidates: list[tuple[str, dict[str, Any]]],
                  settings: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """Sort candidates simplest first: the order of complexity of ``[selection] rule``.

    :class:`~workbench.selection.BasisChoiceCV` takes its candidates' order as their order
    of complexity (after the prior, before the mean of the best), so ``rule = "one_se"``
    keeps the first candidate within one standard error of the best. The order, key by key:

    1. the basis, in the order of the list ``basis`` (list the simplest first: ``["ridge",
       "lightgbm"]``);
    2. the link, ``"identity"`` first (the stages add to the prior), then the others in the
       order of ``link``: another link is kept only where CV prefers it beyond noise;
    3. the size of a drawn setting, the product of its :data:`SIZE_PARAMS` (a tree
       ensemble's trees times leaves; 1 where a setting has neither);
    4. then as listed: loss, line-search loss, input transform, draw.

    Parameters
    ----------
    candidates : list of (str, dict)
        :func:`~workbench.experiment.families.stage.candidate_settings`' candidates.
    settings : dict
        The target's settings they came from (the lists of bases and links).

    Returns
    -------
    list of (str, dict)
        The same candidates, simplest first.
    """
    bases = settings["basis"] if isinstance(settings["basis"], list) else [settings["basis"]]
    links = settings.get("link", "identity")
    links = links if isinstance(links, list) else [links]
    link_rank = {link: 1 + i for i, link in enumerate(links)} | {"identity": 0}

    def size(params: dict[str, Any]) -> float:
        values = [params.get(k) for k in SIZE_PARAMS]
        return float(np.prod([v for v in values if isinstance(v, (int, float))]))

    return sorted(candidates, key=lambda c: (bases.index(c[1]["basis"]),
                                             link_rank[c[1]["link"]],
                                             size(c[1]["basis_params"])))


def candidate_choices(targets: list[str], cvs: Sequence[Any]) -> dict[str, Any]:
    """Collect what CV chose among candidates per target.

    Parameters
    ----------
    targets : list of str
        The targets.
    cvs : sequence of estimators
        Each target's fitted estimator (:class:`~workbench.selection.BasisChoiceCV` where
        it had candidates).

    Returns
    -------
    dict
        The result's ``candidates`` section: per target, the winning candidate's name
        (``chosen``: basis or draw, loss, link; ``"prior"`` when the prior alone won), the
        choice ``rule``, the ``best`` by mean CV score (the prior possibly), every
        candidate's CV MAE (``cv_mae``, the prior first, in the rule's order of complexity)
        and ``se_vs_prior``: the standard errors of the paired fold differences of ``best``
        and of ``chosen`` from the prior (0 for the prior itself), the noise a CV gain over
        the prior is measured against; empty where no target had candidates. And its
        ``stages`` section where a
        selected model's stages chose their own bases (the ``stagewise`` basis): per target,
        the basis each stage chose.
    """
    out, stages = {}, {}
    for target, est in zip(targets, cvs):
        if isinstance(est, BasisChoiceCV):
            scores = est.candidate_scores_
            won, best = est.selected_candidate_ or "prior", est.best_candidate_ or "prior"
            out[target] = {
                "chosen": won, "rule": est.rule, "best": best,
                "cv_mae": {name: float(-np.mean(s)) for name, s in scores.items()},
                "se_vs_prior": {key: paired_standard_error(scores[name], scores["prior"])
                                for key, name in (("best", best), ("chosen", won))}}
        chosen = _stage_bases(getattr(est, "best_estimator_", None))
        if chosen:
            stages[target] = chosen
    return {**({"candidates": out} if out else {}), **({"stages": stages} if stages else {})}


def _stage_bases(model: Any) -> list[str]:
    """List the basis each stage of a fitted model chose (``StageChoiceCV.chosen_``).

    The members of a mean of candidates are joined by ``" | "``; empty where no stage chose.
    """
    if hasattr(model, "members_"):
        members = [" > ".join(_stage_bases(m)) for m in model.members_]
        return [" | ".join(members)] if any(members) else []
    stages = getattr(model, "estimators_", [])
    return [s.chosen_ for s in stages] if any(hasattr(s, "chosen_") for s in stages) else []
