"""Checks of a target's boosting settings against the estimators they make.

Basis and transform names, and their parameters against each estimator's own constraints:
scikit-learn's ``_parameter_constraints`` (read by ``validate_parameter_constraints``), and
LightGBM's own checks for a LightGBM model (which declares none). Nothing here restates an
estimator's ranges: the typed schema checks the config's own keys, the estimators theirs.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
from lightgbm import LGBMModel
from lightgbm.callback import EarlyStopException
from sklearn.base import BaseEstimator, clone
from sklearn.utils._param_validation import validate_parameter_constraints

from ...bases import BASES, TRANSFORMS, basis_names, make_basis, make_transform
from ..process.errors import listing, shorten
from .space import SpaceError, check_ranges, has_ranges

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


#: A few rows for LightGBM's own checks of its parameters (:func:`_lightgbm_refusal`).
_TRIAL_X = np.linspace(0.0, 1.0, 10).reshape(-1, 1)
#: LightGBM's warning for a parameter it does not know (it trains on, ignoring it).
_UNKNOWN = re.compile(r"Unknown parameter: (\S+)")
#: Parameter sets LightGBM has checked in this process -> its verdict (:func:`_lightgbm_says`).
_CHECKED: dict[tuple[type, str], tuple[str | None, list[str]]] = {}


def _stop_after_one_round(env: Any) -> None:
    raise EarlyStopException(env.iteration, env.evaluation_result_list)


@contextlib.contextmanager
def _native_stderr_silenced() -> Iterator[None]:
    """Silence file descriptor 2 for a moment.

    LightGBM's native library writes its fatal errors there itself (``[LightGBM] [Fatal]
    ...``) before they are raised as exceptions: the config's error is one line.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _lightgbm_says(est: BaseEstimator, params: dict[str, Any]) -> tuple[str | None, list[str]]:
    """Ask LightGBM about ``params`` on ``est``'s class: its error, and the names it ignores.

    A fit on a few rows, stopped after its first round: LightGBM's own checks (its Python
    side's and its native library's) all run, and ``n_estimators`` rounds do not. Each
    parameter set is asked once per process.
    """
    key = (type(est), repr(sorted(params.items())))
    if key not in _CHECKED:
        trial = clone(est).set_params(**{**params, "verbose": 0})  # 0: warnings shown
        out = io.StringIO()
        error, unknown = None, []
        try:
            with contextlib.redirect_stdout(out), _native_stderr_silenced():
                trial.fit(_TRIAL_X, _TRIAL_X[:, 0], callbacks=[_stop_after_one_round])
        except Exception as exc:  # LightGBM's refusal, whatever its type: reported
            error = str(exc).split(" at /")[0].strip()  # without the C++ source location
        else:
            unknown = sorted(set(_UNKNOWN.findall(out.getvalue())))
        _CHECKED[key] = error, unknown
    return _CHECKED[key]


def _lightgbm_refusal(est: BaseEstimator) -> str | None:
    """LightGBM's own verdict on ``est``'s parameters, naming the key it refuses.

    LightGBM declares no ``_parameter_constraints``: its checks run when it fits. The
    parameters set away from LightGBM's defaults are given to it on a few rows
    (:func:`_lightgbm_says`); if it refuses them, each is tried alone to name the one it
    refuses (``key = value: LightGBM: its message``). A name LightGBM does not know (it
    would ignore it with a warning) is refused too.
    """
    default = type(est)()
    defaults = default.get_params(deep=False)
    changed = {k: v for k, v in est.get_params(deep=False).items()
               if k not in defaults or repr(v) != repr(defaults[k])}
    error, unknown = _lightgbm_says(default, changed)
    if unknown:
        return f"unknown LightGBM parameter(s) [{listing(unknown, 60)}]"
    if error is None:
        return None
    for name, value in changed.items():
        alone, _ = _lightgbm_says(default, {name: value})
        if alone is not None:
            return f"{name} = {shorten(value)}: LightGBM: {alone}"
    return f"[{listing(sorted(changed), 60)}] together: LightGBM: {error}"


def validate_estimator(estimator: BaseEstimator) -> None:
    """Check an estimator's (and its nested estimators') parameters, without fitting.

    Parameters
    ----------
    estimator : BaseEstimator
        The estimator; each one's ``_parameter_constraints`` are checked by scikit-learn's
        ``validate_parameter_constraints``. A LightGBM model, which declares none, is checked
        by LightGBM itself: a fit on a few rows stopped after one round
        (:func:`_lightgbm_refusal`).

    Raises
    ------
    ValueError
        scikit-learn's message for the first bad value, or LightGBM's, naming the key.
    """
    nested = [estimator] + [v for v in estimator.get_params(deep=True).values()
                            if isinstance(v, BaseEstimator)]
    for est in nested:
        if isinstance(est, LGBMModel):
            refusal = _lightgbm_refusal(est)
            if refusal is not None:
                raise ValueError(refusal)
            continue
        constraints = getattr(est, "_parameter_constraints", None)
        if constraints is not None:
            validate_parameter_constraints(constraints, est.get_params(deep=False),
                                           caller_name=type(est).__name__)

