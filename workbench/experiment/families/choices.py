"""What CV chose per target, for the result: among candidates, and each stage's basis."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ...selection import BasisChoiceCV, paired_standard_error

__all__ = ["candidate_choices"]


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
