"""The per-target boosting stage shared by the model families (not a family itself).

One :class:`~workbench.BaseBoostCV` per target from its prior column, configured by the
``[model]`` settings (``cfg.model_for(target)``), and the stage's CV figures. Family
``eigenvalue`` is this stage on the control program's eigenvalues; family ``hamiltonian``
puts it on top of the parameter-space model.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ...bases import make_basis, make_transform, quadratic_basis_warning
from ...boosting import BaseBoostRegressor
from ...halving import HalvingChoiceCV
from ...multitarget import MultiTargetBaseBoost
from ...selection import BaseBoostCV, BasisChoiceCV
from ..config.space import draw_params, has_ranges
from ..process.errors import ConfigError
from ..splits.folds import selection_cv as _selection_cv
from .choices import by_complexity

if TYPE_CHECKING:
    from ...datasets import Dataset
    from ..config import ExperimentConfig

__all__ = ["booster_cv", "candidate_settings", "cv_mse", "has_candidates", "make_booster",
           "per_target_boost", "selection_cv", "stage_scores", "target_inputs",
           "target_selection"]


def make_booster(settings: dict[str, Any], prior: Any, inputs: list[str] | None,
                 n_priors: int = 1) -> BaseBoostRegressor:
    """Make the :class:`~workbench.BaseBoostRegressor` that one target's settings describe.

    Parameters
    ----------
    settings : dict
        One candidate's boosting settings (no lists).
    prior : str, estimator or None
        What it boosts from (BaseBoostRegressor's ``prior``): a prior column, or ``None``
        where a :class:`~workbench.fitted_prior.FittedPriorBoost` sets its fitted prior's
        columns later.
    inputs : list of str or None
        Its basis inputs, of which the first ``n_priors`` are prior columns.
    n_priors : int, default=1
        What a transform with an ``n_priors`` parameter, such as ``"derived"``, is told.

    Returns
    -------
    BaseBoostRegressor
        Unfitted.
    """
    transform = make_transform(settings["input_transform"], **settings["input_transform_params"])
    if transform is not None and "n_priors" in transform.get_params():
        transform.set_params(n_priors=n_priors)
    if settings.get("halving"):  # the drawn settings, raced inside each fit
        basis = HalvingChoiceCV([(f"d{i:02d}", make_basis(settings["basis"], **p))
                                 for i, p in enumerate(settings["halving"])])
    else:
        basis = make_basis(settings["basis"], **settings["basis_params"])
    return BaseBoostRegressor(
        prior=prior, basis=basis,
        n_stages=settings["n_stages"], loss=settings["loss"],
        line_search_loss=settings["line_search_loss"],
        line_search_penalty=settings["line_search_penalty"], alpha=settings["alpha"],
        link=settings.get("link", "identity"), basis_features=inputs,
        input_transform=transform,
        out_of_bounds=settings.get("out_of_bounds", "extrapolate"))


def has_candidates(settings: dict[str, Any]) -> bool:
    """Tell whether a target's settings describe several candidates for CV to choose from.

    They do with a list of bases, losses, line-search losses, links or input transforms, or
    ranges in a basis's ``basis_params``.

    Parameters
    ----------
    settings : dict
        One target's boosting settings.

    Returns
    -------
    bool
        Whether CV chooses among candidates.
    """
    params = settings["basis_params"]
    tables = list(params.values()) if isinstance(settings["basis"], list) else [params]
    return (any(isinstance(settings.get(k), list)
                for k in ("basis", "loss", "line_search_loss", "link", "input_transform"))
            or any(isinstance(t, dict) and has_ranges(t) for t in tables))


def candidate_settings(settings: dict[str, Any],
                       seed: int | None) -> list[tuple[str, dict[str, Any]]]:
    """List the candidates of settings for which :func:`has_candidates`.

    One per basis, drawn setting, loss, line-search loss, link and input transform (bases
    outer). A basis whose ``basis_params`` hold ranges gives ``draws`` settings drawn at
    random (``seed``; the same draws for every target, loss, link and transform), named
    ``basis#i``; with ``tune = "halving"`` they are one candidate, ``basis#halving``, whose
    settings hold them under ``"halving"`` (:func:`make_booster` races them inside each
    fit, :class:`~workbench.halving.HalvingChoiceCV`). A name joins what varies: the basis
    (or draw), the loss, the line-search loss (after ``line:``), the link and the
    transform, e.g. ``"ridge"``, ``"huber"``,
    ``"lightgbm#07/huber"``, ``"ridge/line:squared_error"``, ``"ridge/log"``,
    ``"lightgbm#03/identity/derived"``.

    Parameters
    ----------
    settings : dict
        One target's boosting settings.
    seed : int or None
        Seeds the draws.

    Returns
    -------
    list of (str, dict)
        Each candidate's name and settings.
    """
    bases, losses, links = settings["basis"], settings["loss"], settings.get("link", "identity")
    transforms, line_losses = settings["input_transform"], settings["line_search_loss"]
    many_bases, many_losses = isinstance(bases, list), isinstance(losses, list)
    many_links, many_transforms = isinstance(links, list), isinstance(transforms, list)
    many_line = isinstance(line_losses, list)
    pairs = [(loss, line) for loss in (losses if many_losses else [losses])
             for line in (line_losses if many_line else [line_losses])]
    out: list[tuple[str, dict[str, Any]]] = []
    for basis in (bases if many_bases else [bases]):
        params = settings["basis_params"].get(basis, {}) if many_bases else \
            settings["basis_params"]
        drawn = ([(f"{basis}#{i:02d}", p) for i, p in
                  enumerate(draw_params(params, settings["draws"], seed))]
                 if has_ranges(params) else [(basis, params)])
        halving = None
        if has_ranges(params) and settings.get("tune") == "halving":
            halving = [p for _, p in drawn]
            drawn = [(f"{basis}#halving", {})]
        for label, values in drawn:
            for loss, line in pairs:
                for link in (links if many_links else [links]):
                    for transform in (transforms if many_transforms else [transforms]):
                        parts = ([label] if many_bases or label != basis else []) + \
                            ([loss] if many_losses else []) + \
                            ([f"line:{line}"] if many_line else []) + \
                            ([link] if many_links else []) + \
                            ([str(transform)] if many_transforms else [])
                        out.append(("/".join(parts), {
                            **settings, "basis": basis, "basis_params": values, "loss": loss,
                            "line_search_loss": line, "link": link,
                            "input_transform": transform,
                            **({"halving": halving} if halving else {})}))
    return out


def target_inputs(settings: dict[str, Any], ds: Dataset, priors: list[str]) -> list[str]:
    """List the basis input columns ``settings["basis_inputs"]`` names.

    Parameters
    ----------
    settings : dict
        One target's boosting settings.
    ds : Dataset
        The dataset.
    priors : list of str
        The prior columns.

    Returns
    -------
    list of str
        ``priors``, with the dataset's features for ``"prior+features"``.
    """
    extra = ds.feature_names if settings["basis_inputs"] == "prior+features" else []
    return list(priors) + extra


def selection_cv(cfg: ExperimentConfig, ds: Dataset | None = None) -> Any:
    """Make BaseBoostCV's folds (``[selection]``; :func:`.folds.selection_cv`).

    Forward-chaining (:class:`~workbench.selection.LabelTimeSeriesSplit`) when the dataset
    has an order (``[data] order_column``); whole groups
    (:class:`~workbench.selection.LabelGroupKFold`) when it has groups (e.g. the device of
    each row) and ``[selection] groups`` is true, its default; else contiguous unless
    ``shuffle``.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.
    ds : Dataset, optional
        The dataset (its order and groups).

    Returns
    -------
    cross-validator
        ``LabelTimeSeriesSplit``, ``LabelGroupKFold`` or ``KFold``.
    """
    return _selection_cv(cfg, ds)


def per_target_boost(cfg: ExperimentConfig, ds: Dataset, priors: list[str], *,
                     boost_from_prior: bool = True) -> MultiTargetBaseBoost:
    """Make one :class:`BaseBoostCV` per target, as a MultiTargetBaseBoost.

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.
    ds : Dataset
        The dataset.
    priors : list of str
        The prior column of each target.
    boost_from_prior : bool, default=True
        Whether target ``j`` boosts from ``priors[j]`` (else from an outside prior).

    Returns
    -------
    MultiTargetBaseBoost
        Unfitted.

    Raises
    ------
    ConfigError
        For ``[model.targets]`` naming an unknown target, or a lone log link the data refuse.
    """
    names = ds.target_names
    unknown = sorted(set(cfg.model.targets) - set(names))
    if unknown:
        raise ConfigError(f"[model.targets]: unknown target(s) {unknown}; the dataset's "
                          f"targets are {names}")
    _warn_quadratic_bases(cfg, names, len(ds.train_index))
    # training scores: the learning curves reuse a BaseBoostCV's folds (family artifacts)
    per_target = {target: target_selection(cfg, ds, target, cfg.model_for(target),
                                           selection_cv(cfg, ds), priors=priors,
                                           boost_from_prior=boost_from_prior,
                                           return_train_score=True)
                  for target in names}
    return MultiTargetBaseBoost(target_estimators=per_target, n_jobs=cfg.jobs,
                                random_state=cfg.random_state)


def _positive_links(cfg: ExperimentConfig, ds: Dataset, target: str, prior: str,
                    settings: dict[str, Any]) -> dict[str, Any]:
    """Return ``settings`` with a ``link`` that can fit ``target``.

    The log link needs positive targets and priors on the training rows. A "log" among
    several links is left out (a note in the log) where they are not; a lone
    ``link = "log"`` is a ConfigError naming the target.
    """
    link = settings.get("link", "identity")
    links = link if isinstance(link, list) else [link]
    if "log" not in links:
        return settings
    rows = ds.train_index
    columns = {target: ds.targets.loc[rows, target]}
    if prior in ds.prior.columns:  # a prior computed during the fit is checked there
        columns[prior] = ds.prior.loc[rows, prior]
    bad = {name: int((values <= 0).sum()) for name, values in columns.items()
           if (values <= 0).any()}
    if not bad:
        return settings
    what = ", ".join(f"{name} has {n} value(s) <= 0" for name, n in bad.items())
    if len(links) == 1:
        raise ConfigError(f"link = \"log\" needs positive targets and priors; on the "
                          f"training rows {what}: use link = \"identity\"")
    logging.getLogger("workbench").info("[%s] %s: link \"log\" left out (%s)", cfg.name,
                                        target, what)
    return {**settings, "link": [link for link in links if link != "log"]}


def _warn_quadratic_bases(cfg: ExperimentConfig, targets: list[str], n_rows: int) -> None:
    """Warn about a basis that will not scale to ``n_rows``, before anything is fitted.

    The warning goes to the ``workbench`` logger.
    """
    bases: set[str] = set()
    for target in targets:
        basis = cfg.model_for(target)["basis"]
        bases.update(basis if isinstance(basis, list) else [basis])
    for name in sorted(bases):
        message = quadratic_basis_warning(name, n_rows)
        if message:
            logging.getLogger("workbench").warning("[%s] warning: %s", cfg.name, message)


def target_selection(cfg: ExperimentConfig, ds: Dataset, target: str,
                     settings: dict[str, Any], cv: Any, *, priors: list[str],
                     boost_from_prior: bool = True, **kwargs: Any) -> BaseBoostCV:
    """Make one target's choice between its prior and boosting, as its settings describe.

    A :class:`~workbench.BasisChoiceCV` over the candidates where the settings have several
    (:func:`has_candidates`; the mean of the best ``[selection] ensemble`` of them is one
    more), else a :class:`~workbench.BaseBoostCV` of the one booster: the same for
    ``evaluate`` and for a sweep's trials and final model.

    Parameters
    ----------
    cfg, ds : ExperimentConfig, Dataset
        The config and the dataset.
    target, settings : str, dict
        The target and its boosting settings (``cfg.model_for(target)``, or a trial's).
    cv : cross-validator
        The folds of the choice.
    priors : list of str
        The prior column of each of the dataset's targets.
    boost_from_prior : bool, default=True
        Whether the target boosts from its prior column (else from an outside prior).
    **kwargs
        Further parameters of BaseBoostCV (``return_train_score`` only reaches a BaseBoostCV;
        BasisChoiceCV does not take it).

    Returns
    -------
    BaseBoostCV
        Unfitted (a BasisChoiceCV where CV chooses among candidates).

    Raises
    ------
    ConfigError
        For a lone log link the data refuse.
    """
    prior = priors[ds.target_names.index(target)]
    s = _positive_links(cfg, ds, target, prior, settings)
    start = prior if boost_from_prior else None
    inputs = target_inputs(s, ds, priors)
    if has_candidates(s):  # the basis family, its settings or the loss too by CV
        kwargs.pop("return_train_score", None)
        candidates = [(name, make_booster(c, prior=start, inputs=inputs, n_priors=len(priors)))
                      for name, c in by_complexity(candidate_settings(s, cfg.random_state), s)]
        return BasisChoiceCV(candidates, cv=cv, scoring=cfg.selection.scoring,
                             ensemble=cfg.selection.ensemble, rule=cfg.selection.rule,
                             **kwargs)
    return BaseBoostCV(make_booster(s, prior=start, inputs=inputs, n_priors=len(priors)),
                       cv=cv, scoring=cfg.selection.scoring, rule=cfg.selection.rule, **kwargs)


def booster_cv(cfg: ExperimentConfig, ds: Dataset, target: str, settings: dict[str, Any],
               cv: Any, **kwargs: Any) -> BaseBoostCV:
    """Make one target's BaseBoostCV of a sweep, seeded by ``random_state``.

    :func:`target_selection`: a BasisChoiceCV where the settings hold candidates.

    Parameters
    ----------
    cfg, ds, target, settings, cv
        As in :func:`target_selection` (``settings``: a trial's; ``cv``: the inner folds).
    **kwargs
        Further BaseBoostCV parameters.

    Returns
    -------
    BaseBoostCV
        Unfitted.
    """
    return target_selection(cfg, ds, target, settings, cv, priors=ds.prior_names,
                            random_state=cfg.random_state, **kwargs)


def cv_mse(y: Any, predictions: Any) -> float:
    """Compute the MSE of out-of-fold predictions.

    Parameters
    ----------
    y : array-like
        The measured values.
    predictions : array-like
        The out-of-fold predictions; rows without one (NaN, e.g. failed folds) are left out.

    Returns
    -------
    float
        The MSE, NaN when no row has a prediction.
    """
    y, p = np.asarray(y, dtype=float), np.asarray(predictions, dtype=float)
    ok = np.isfinite(p)
    return float(np.mean((y[ok] - p[ok]) ** 2)) if ok.any() else float("nan")


def stage_scores(cvs: Sequence[Any], Y: np.ndarray) -> dict[str, list[Any]]:
    """Collect the per-target CV figures of fitted BaseBoostCVs.

    Parameters
    ----------
    cvs : sequence of BaseBoostCV
        Each target's fitted estimator.
    Y : ndarray
        The training targets, one column per target.

    Returns
    -------
    dict
        ``cv_mae`` their CV score (of what they selected), ``cv_mse`` from out-of-fold
        predictions, the prior's and the boosted candidate's own CV MAE, the stage
        coefficients, and ``selected``: what each target predicts with, "boosted", or
        "prior" when the prior was selected or when every boosted stage's coefficient came
        out 0 in the refit (the model is then the prior exactly).
    """
    coefs = [e.best_estimator_.coefs_.tolist() if e.selected_ == "boosted" else []
             for e in cvs]
    return {
        "cv_mae": [-e.cv_score_ for e in cvs],
        "cv_mse": [cv_mse(Y[:, j], e.cv_predictions_) for j, e in enumerate(cvs)],
        "prior_cv_mae": [float(-np.mean(e.cv_scores_prior_)) for e in cvs],
        "prior_cv_mse": [cv_mse(Y[:, j], e.cv_predictions_prior_) for j, e in enumerate(cvs)],
        "boosted_cv_mae": [float(-np.mean(e.cv_scores_boosted_)) for e in cvs],
        "coefs": coefs,
        "selected": ["boosted" if e.selected_ == "boosted" and np.any(c) else "prior"
                     for e, c in zip(cvs, coefs)],
    }
