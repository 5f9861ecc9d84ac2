"""Checks of a target's boosting settings against the estimators they make.

Basis and transform names, and their parameters against each estimator's own constraints
(scikit-learn's ``_parameter_constraints``, read by ``validate_parameter_constraints``).
"""

from __future__ import annotations

from numbers import Integral, Real
from typing import Any

from sklearn.base import BaseEstimator
from sklearn.utils._param_validation import Interval, StrOptions, validate_parameter_constraints

from ...bases import BASES, TRANSFORMS, basis_names, make_basis, make_transform
from ..errors import listing, shorten
from ..space import SpaceError, check_ranges, has_ranges

__all__ = ["check_boost_settings", "validate_estimator"]


def check_boost_settings(settings: dict[str, Any]) -> None:
    """Resolve a target's merged settings the way a fit will.

    Basis and transform names, their parameters against the estimators' own constraints,
    the losses and links (each of a list of candidates too).

    Parameters
    ----------
    settings : dict
        A target's merged settings (:meth:`~.experiment.ExperimentConfig.model_for`).

    Raises
    ------
    ValueError
        The offending key first, then its value and what is allowed.
    """
    for key in ("loss", "line_search_loss", "link", "input_transform"):
        if isinstance(settings.get(key), list):  # candidates chosen by CV per target
            values = settings[key]
            if not values or len(set(values)) != len(values):
                raise ValueError(f"{key} = {shorten(values)}: give distinct {key} names")
            for value in values:
                check_boost_settings({**settings, key: value})
            return
    if isinstance(settings["basis"], list):  # candidates chosen by CV per target
        names = settings["basis"]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"basis = {shorten(names)}: give distinct basis names")
        params = settings["basis_params"]
        extra = sorted(set(params) - set(names))
        if extra or not all(isinstance(v, dict) for v in params.values()):
            raise ValueError(f"basis_params = {shorten(params)}: with a list of bases, give "
                             f"one table per basis of the list ({names})")
        for name in names:
            check_boost_settings({**settings, "basis": name,
                                  "basis_params": params.get(name, {})})
        return
    if settings["basis"] not in BASES and settings["basis"] not in basis_names():  # plug-ins
        raise ValueError(f"basis = {shorten(settings['basis'])}: unknown basis; valid: "
                         f"{sorted(BASES)}")
    if settings["input_transform"] not in ("none", *TRANSFORMS):
        raise ValueError(f"input_transform = {shorten(settings['input_transform'])}: unknown "
                         f"transform; valid: {['none', *sorted(TRANSFORMS)]}")
    params = settings["basis_params"]
    try:  # tables to draw from: each range's ends and each choice must be valid
        ends = check_ranges(settings["basis"], params) if has_ranges(params) else [params]
    except SpaceError as exc:
        raise ValueError(str(exc)) from None
    try:
        for values in ends:
            validate_estimator(make_basis(settings["basis"], **values))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"basis_params ({settings['basis']}): {exc}") from None
    try:
        transform = make_transform(settings["input_transform"],
                                   **settings["input_transform_params"])
        if transform is not None:
            validate_estimator(transform)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"input_transform_params ({settings['input_transform']}): {exc}"
                         ) from None


def _lightgbm_constraints() -> dict[str, list]:
    """LightGBM's documented ranges of its scikit-learn estimator's parameters.

    LightGBM declares no ``_parameter_constraints`` and its own checks (in C++, at fit time)
    accept values the config refuses, such as ``n_estimators = 0``: the ranges are written
    here, in scikit-learn's constraint language.
    """
    positive = [Interval(Real, 0, None, closed="neither")]
    nonneg = [Interval(Real, 0, None, closed="left")]
    fraction = [Interval(Real, 0, 1, closed="right")]
    return {
        "boosting_type": [StrOptions({"gbdt", "dart", "rf"})],
        "num_leaves": [Interval(Integral, 2, 131072, closed="both")],
        "max_depth": [Interval(Integral, -1, None, closed="left")],
        "learning_rate": positive, "n_estimators": [Interval(Integral, 1, None, closed="left")],
        "subsample_for_bin": [Interval(Integral, 1, None, closed="left")],
        "objective": [str, None], "min_split_gain": nonneg, "min_child_weight": nonneg,
        "min_child_samples": [Interval(Integral, 0, None, closed="left")],
        "subsample": fraction, "subsample_freq": [Interval(Integral, 0, None, closed="left")],
        "colsample_bytree": fraction, "reg_alpha": nonneg, "reg_lambda": nonneg,
        "random_state": ["random_state"], "n_jobs": [Integral, None],
        "importance_type": [StrOptions({"split", "gain"})], "verbose": [Integral],
        "max_bin": [Interval(Integral, 2, None, closed="left")],
        "data_sample_strategy": [StrOptions({"bagging", "goss"})],
    }


def validate_estimator(estimator: BaseEstimator) -> None:
    """Check an estimator's (and its nested estimators') parameters, without fitting.

    Parameters
    ----------
    estimator : BaseEstimator
        The estimator; each one's ``_parameter_constraints`` (LightGBM's: the ranges of
        :func:`_lightgbm_constraints`) are checked by scikit-learn's
        ``validate_parameter_constraints``.

    Raises
    ------
    ValueError
        scikit-learn's message for the first bad value, or the unknown LightGBM parameters.
    """
    nested = [estimator] + [v for v in estimator.get_params(deep=True).values()
                            if isinstance(v, BaseEstimator)]
    constraints: dict[str, list[Any]] | None
    for est in nested:
        params = est.get_params(deep=False)
        if any(c.__module__.startswith("lightgbm") for c in type(est).__mro__[:-1]):
            constraints = _lightgbm_constraints()
            unknown = sorted(set(params) - set(constraints) - {"class_weight"})
            extra = sorted(k for k in unknown if params[k] is not None)
            if extra:
                raise ValueError(f"unknown LightGBM parameter(s) [{listing(extra, 60)}]; "
                                 f"valid: {listing(sorted(constraints))}")
            params = {k: v for k, v in params.items() if k in constraints}
        else:
            constraints = getattr(est, "_parameter_constraints", None)
            if constraints is None:
                continue
        validate_parameter_constraints(constraints, params, caller_name=type(est).__name__)

