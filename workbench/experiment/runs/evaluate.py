"""``workbench evaluate``: fit a config's model on the training rows, score it on the test rows.

The test rows are scored once; optional repeated CV on the training rows and nested CV over
all rows estimate the error again.

Family-independent: the config's family (:mod:`workbench.experiment.families`) builds the
model and assembles its scores; with ``[intervals]`` (the default) the model is wrapped in a
conformal :class:`~workbench.conformal.ConformalRegressor` here, for every family
(:mod:`workbench.experiment.runs.intervals`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np
from sklearn.model_selection import KFold, RepeatedKFold, cross_val_predict

from ..config import ExperimentConfig, load_dataset
from ..scoring.bootstrap import bootstrap_test_scores
from ..scoring.results import Result
from ..scoring.scores import CVEstimate, mae, mse
from ..scoring.units import unit_name
from .intervals import family_model, interval_scores, interval_settings, with_intervals

if TYPE_CHECKING:
    from ...datasets import Dataset

__all__ = ["Evaluation", "evaluate", "fit_and_score", "format_table", "nested_cv_all",
           "repeated_cv"]

log = logging.getLogger("workbench")


@dataclass
class Evaluation:
    """A result with the fitted model and the dataset it came from.

    Parameters
    ----------
    result : Result
        The scores.
    model : object
        The fitted model; with intervals, the fitted ConformalRegressor around the family's
        model.
    dataset : Dataset
        The data it was fitted and scored on.
    """

    result: Result
    model: Any
    dataset: Dataset


@overload
def evaluate(cfg: ExperimentConfig, return_model: Literal[False] = False, *,
             dataset: Dataset | None = None) -> Result: ...


@overload
def evaluate(cfg: ExperimentConfig, return_model: Literal[True], *,
             dataset: Dataset | None = None) -> Evaluation: ...


def evaluate(cfg: ExperimentConfig, return_model: bool = False, *,
             dataset: Dataset | None = None) -> Result | Evaluation:
    """Fit on the training rows, then score prior and model on the test rows.

    Every choice is made by CV on the training rows.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    return_model : bool, default=False
        Whether to return the fitted model and the dataset with the result.
    dataset : Dataset, optional
        The config's dataset, already loaded and checked
        (:func:`~workbench.experiment.runs.prepare.prepare`); loaded here when not given.

    Returns
    -------
    Result or Evaluation
        The :class:`Result` (with ``return_model``, an :class:`Evaluation` holding the
        fitted model and the dataset too).
    """
    start = time.perf_counter()
    ds = dataset if dataset is not None else load_dataset(cfg)
    family = cfg.family
    log.info("[%s] fitting %d targets on %d training rows (test rows: %d)", cfg.name,
             len(ds.target_names), len(ds.train_index), len(ds.test_index))
    result, model = fit_and_score(cfg, ds, family.build(cfg, ds))
    ev = cfg.evaluation
    if ev.cv_repeats > 0:
        log.info("[%s] repeated CV of the chosen model on the training rows (%d x %d folds)",
                 cfg.name, ev.cv_repeats, ev.cv_folds)
        result.repeated_cv = repeated_cv(cfg, ds, family.fixed_choices(family_model(model)))
        if family.cv_from_repeats:
            result.model.cv_mae = list(result.repeated_cv.model_mae)
            result.model.cv_mse = list(result.repeated_cv.model_mse)
    if ev.nested_folds > 0:
        log.info("[%s] nested CV over all %d rows (%d outer folds, every choice remade "
                 "inside)", cfg.name, len(ds.targets), ev.nested_folds)
        result.nested_cv_all = nested_cv_all(cfg, ds)
    result.wall_s = time.perf_counter() - start
    return Evaluation(result, model, ds) if return_model else result


def _oof(model: Any, X: Any, Y: Any, cv: Any) -> np.ndarray:
    """Predict out of fold: ``model`` refitted on each split's training rows."""
    return np.asarray(cross_val_predict(model, X, Y, cv=cv), dtype=float)


def repeated_cv(cfg: ExperimentConfig, ds: Dataset, model: Any) -> CVEstimate:
    """Estimate the error of ``model`` by repeated K-fold CV on the training rows only.

    ``[evaluation]`` cv_folds x cv_repeats folds (``RepeatedKFold`` seeded by cv_seed), with
    the control program's MAE on the same rows.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    ds : Dataset
        The config's dataset.
    model : estimator
        The unfitted model (the choices it made kept fixed).

    Returns
    -------
    CVEstimate
        Per-target MAE and MSE averaged over the repeats.
    """
    ev = cfg.evaluation
    X = cfg.family.inputs(cfg, ds).loc[ds.train_index]
    Y = ds.targets.loc[ds.train_index]
    splits = list(RepeatedKFold(n_splits=ev.cv_folds, n_repeats=ev.cv_repeats,
                                random_state=ev.cv_seed).split(X))
    k = ev.cv_folds
    preds = [_oof(model, X, Y, splits[r * k:(r + 1) * k]) for r in range(ev.cv_repeats)]
    per_repeat = [mae(Y, p) for p in preds]
    return CVEstimate(folds=k, repeats=ev.cv_repeats, seed=ev.cv_seed,
                      model_mae=np.mean(per_repeat, axis=0).tolist(),
                      model_mse=np.mean([mse(Y, p) for p in preds], axis=0).tolist(),
                      prior_mae=mae(Y, ds.prior.loc[ds.train_index]),
                      model_mae_avg_per_repeat=[float(np.mean(m)) for m in per_repeat])


def nested_cv_all(cfg: ExperimentConfig, ds: Dataset) -> CVEstimate:
    """Estimate the error by nested CV over every row (training and test).

    In each of ``nested_folds`` outer folds the whole model, every choice included, is
    fitted on the other rows and scored on the fold's rows. The least noisy estimate for
    small data; no choice is made from it.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    ds : Dataset
        The config's dataset.

    Returns
    -------
    CVEstimate
        Per-target MAE and MSE of the model and the prior's MAE over all rows.
    """
    ev = cfg.evaluation
    X, Y = cfg.family.inputs(cfg, ds), ds.targets
    pred = _oof(cfg.family.build(cfg, ds), X, Y,
                KFold(ev.nested_folds, shuffle=True, random_state=ev.nested_seed))
    return CVEstimate(folds=ev.nested_folds, seed=ev.nested_seed, n_rows=len(Y),
                      model_mae=mae(Y, pred), model_mse=mse(Y, pred), prior_mae=mae(Y, ds.prior))


def fit_and_score(cfg: ExperimentConfig, ds: Dataset, model: Any) -> tuple[Result, Any]:
    """Fit ``model`` on the training rows and score prior and model once on the test rows.

    The model goes inside a conformal wrapper when ``[intervals]`` is on; the intervals'
    coverage and width are scored too.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    ds : Dataset
        The config's dataset.
    model : estimator
        The unfitted model the config's family built.

    Returns
    -------
    result : Result
        The scores.
    model : estimator
        The fitted model; with intervals, the fitted wrapper (the family's fitted model is
        :func:`family_model` of it).
    """
    family = cfg.family
    X_train, X_test, y_train, y_test = ds.split(family.inputs(cfg, ds))
    model = with_intervals(cfg, model)
    if cfg.intervals.enabled:
        log.info("[%s] fitting the model and its %s prediction intervals (%s)", cfg.name,
                 f"{1 - cfg.intervals.alpha:.0%}", cfg.intervals.method)
    model.fit(X_train, y_train)
    pred = np.asarray(model.predict(X_test), dtype=float)
    prior_test = ds.prior.loc[ds.test_index].to_numpy()
    prior, scores, details = family.scores(ds, family_model(model), y_train, prior_test,
                                           y_test, pred)
    for key, values in interval_scores(model, X_test, y_test).items():
        setattr(scores, key, values)
    # 95% intervals of the test errors over the test rows (one seed: the same resamples for
    # the prior, the model and their difference)
    bootstrap = bootstrap_test_scores(prior, scores, y_test, prior_test, pred,
                                      random_state=cfg.random_state or 0)
    result = Result(name=cfg.name, config=str(cfg.path) if cfg.path else None,
                    family=family.name, targets=list(ds.target_names), n_train=len(y_train),
                    n_test=len(y_test), prior=prior, model=scores, details=details,
                    intervals=interval_settings(cfg), bootstrap=bootstrap, unit=ds.unit,
                    folds=family.folds_used(cfg, ds))
    return result, model


def _interval(bounds: Any, fmt: str = ".3f") -> str:
    return f"[{bounds[0]:{fmt}}, {bounds[1]:{fmt}}]"


def _number_format(result: Result) -> str:
    """``".3f"`` for errors of everyday size in the targets' unit; significant digits
    (``".4g"``) below 0.01 or from 1e6 on, where three decimals say nothing (targets in
    seconds of 1e-9) or too much."""
    values = np.abs(np.asarray([*result.prior.test_mae, *result.model.test_mae], dtype=float))
    values = values[np.isfinite(values) & (values > 0)]
    return ".3f" if not values.size or 1e-2 <= values.max() < 1e6 else ".4g"


def _value(values: Any, j: int) -> float | None:
    """``values[j]`` where it is a finite number, else ``None``."""
    try:
        value = float(values[j])
    except (TypeError, IndexError, ValueError):
        return None
    return value if np.isfinite(value) else None


def choice_lines(result: Result) -> list[str]:
    """Say per target what CV chose and how it compares with the prior.

    Where CV chose among candidates: the chosen one with its CV MAE beside the prior's and
    the lowest CV MAEs; ``keeps the prior`` where the prior won, with the best candidate's
    CV MAE and, when it was within noise of the prior (``rule = "one_se"``), the standard
    error of their paired fold differences; and a line when a chosen candidate's CV gain
    over the prior is within that noise. Elsewhere, ``keeps the prior`` where the prior was
    selected.

    Parameters
    ----------
    result : Result
        The scores (its ``candidates`` details,
        :func:`~workbench.experiment.families.choices.candidate_choices`).

    Returns
    -------
    list of str
        One or two lines per target that CV chose for; none for a boosted target without
        candidates.
    """
    lines = []
    choices = result.details.get("candidates", {})
    for target, choice in choices.items():
        mae, chosen = choice["cv_mae"], choice["chosen"]
        prior, se = mae["prior"], choice.get("se_vs_prior", {})
        rivals = {n: v for n, v in mae.items() if n != "prior" and np.isfinite(v)}
        if chosen == "prior":
            rival = min(rivals, key=rivals.__getitem__, default=None)
            if rival is None:
                lines.append(f"{target}: keeps the prior (CV MAE {prior:.4g}; every "
                             "candidate failed)")
            elif rivals[rival] < prior and "best" in se:
                verdict = ("within noise" if prior - rivals[rival] <= se["best"]
                           else "the best candidate's refit failed")
                lines.append(f"{target}: keeps the prior (CV MAE {prior:.4g} vs best candidate "
                             f"{rival} {rivals[rival]:.4g} +- {se['best']:.2g}: {verdict})")
            else:
                lines.append(f"{target}: keeps the prior (CV MAE {prior:.4g}; best candidate "
                             f"{rival} {rivals[rival]:.4g})")
            continue
        best = choice.get("best", chosen)
        simplest = (f", the simplest within one SE of the best, {best} {mae[best]:.4g}"
                    if best != chosen else "")
        lowest = sorted(mae, key=mae.__getitem__)[:3]
        lines.append(f"{target}: CV chose {chosen} (CV MAE {mae[chosen]:.4g}{simplest}; prior "
                     f"{prior:.4g}); lowest CV MAE "
                     + ", ".join(f"{name} {mae[name]:.4g}" for name in lowest)
                     + f" of {len(mae)} (the prior included)")
        if "chosen" in se and prior - mae[chosen] <= se["chosen"]:
            lines.append(f"{target}: its CV gain over the prior is within noise (CV MAE "
                         f"{mae[chosen]:.4g} vs prior {prior:.4g} +- {se['chosen']:.2g})")
    for j, target in enumerate(result.targets):
        if target not in choices and j < len(result.model.selected) \
                and result.model.selected[j] == "prior":
            prior_cv = _value(result.prior.cv_mae, j)
            boosted = _value(result.model.extra.get("cv_mae_boosted"), j)
            versus = f" vs boosted {boosted:.4g}" if boosted is not None else ""
            lines.append(f"{target}: keeps the prior" + (
                f" (CV MAE {prior_cv:.4g}{versus})" if prior_cv is not None else ""))
    return lines


def format_table(result: Result) -> str:
    """Format a per-target table of a result.

    Prior and model test MAE, the model's CV MAE and what was selected; below it the
    bootstrap intervals of the average test MAE (prior, model, model - prior).

    Parameters
    ----------
    result : Result
        The scores.

    Returns
    -------
    str
        The table, lines joined.
    """
    w = max(10, *(len(t) + 2 for t in result.targets))
    rule = "-" * (w + 46)
    f = _number_format(result)
    lines = [f"{'target':<{w}}{'prior MAE':>11}{'model MAE':>11}{'model CV MAE':>14}  selected",
             rule]
    rows = zip(result.targets, result.prior.test_mae, result.model.test_mae,
               result.model.cv_mae, result.model.selected)
    for name, p, m, c, s in rows:
        lines.append(f"{name:<{w}}{p:>11{f}}{m:>11{f}}{c:>14{f}}  {s}")
    lines.append(rule)
    lines.append(f"{'average':<{w}}{result.prior.avg('test_mae'):>11{f}}"
                 f"{result.model.avg('test_mae'):>11{f}}{result.model.avg('cv_mae'):>14{f}}")
    lines.append(f"test MAE in {unit_name(result.unit)}; "
                 f"wall time {result.wall_s:.1f} s")
    if result.folds:
        lines.append(f"folds: {result.folds}")
    if result.model.test_mae_diff_avg_ci:
        boot = result.bootstrap
        ci_level = f"{boot['level']:.0%} " if "level" in boot else ""
        over = f" over the {boot['n_rows']} test rows" if "n_rows" in boot else ""
        lines.append(f"{ci_level}bootstrap intervals{over}, average test MAE: prior "
                     f"{_interval(result.prior.test_mae_avg_ci, f)}, model "
                     f"{_interval(result.model.test_mae_avg_ci, f)}, model - prior "
                     f"{_interval(result.model.test_mae_diff_avg_ci, f)}")
    if result.model.test_coverage:
        model, iv = result.model, result.intervals
        level = f"{iv['level']:.0%} " if "level" in iv else ""
        lines.append(f"{level}prediction intervals ({iv.get('method', 'conformal')}): test "
                     f"coverage {model.avg('test_coverage'):.1%} (per target "
                     f"{', '.join(f'{c:.0%}' for c in model.test_coverage)}), mean width "
                     f"{model.avg('test_width'):{f}}; CV coverage "
                     f"{model.avg('cv_coverage'):.1%}, width {model.avg('cv_width'):{f}}")
    lines += choice_lines(result)
    lines += result.details.get("notes", [])  # a family's remarks on this run
    for target, chosen in result.details.get("stages", {}).items():
        lines.append(f"{target}: each stage's basis by CV on its residuals: "
                     + " > ".join(chosen))
    if result.repeated_cv is not None:
        r = result.repeated_cv
        lines.append(f"repeated CV on the training rows ({r.repeats} x {r.folds} folds): "
                     f"model {r.model_mae_avg:{f}}, prior {r.prior_mae_avg:{f}}")
    if result.nested_cv_all is not None:
        r = result.nested_cv_all
        lines.append(f"nested CV over all {r.n_rows} rows ({r.folds} outer folds): "
                     f"model {r.model_mae_avg:{f}}, prior {r.prior_mae_avg:{f}}")
    if result.sweep is not None:
        sweep = result.sweep
        lines.append(f"nested-CV MAE: model {sweep.nested_cv_mae_avg:{f}}, prior "
                     f"{sweep.nested_cv_prior_mae_avg:{f}} (average over targets)")
    return "\n".join(lines)
