"""Any physics model, corrected in its own parameter space, the correction chosen by CV.

:class:`ParametricBoostRegressor` chooses by cross-validation on the rows it is given among
the prior (the model at its start values), the calibrated model (no drift) and linear
drifts whose covariates forward selection picks (:mod:`workbench.param_select`'s engine), each
a :class:`~workbench.param_regressor.ParametricRegressor`.
"""

from __future__ import annotations

import numbers
import time
from collections.abc import Callable, Sequence
from itertools import combinations
from typing import Any, Self

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from ._progress import Progress
from .parallel import effective_n_jobs
from .param_regressor import _MODEL, ParametricRegressor, _as_frame, _targets
from .param_select import (
    SELECTION_METHODS,
    SelectionResult,
    _cv_splits,
    _fit_splits,
    _linearised_select,
    _refit_select,
    _sliced,
)
from .parametric import ParametricModel, resolve_model

__all__ = ["ParametricBoostRegressor", "boost_candidate", "covariate_pool", "ridge_drift"]


def covariate_pool(features: Sequence[str], parameters: Sequence[str], *, squares: bool = True,
                   products: bool = True) -> dict[str, list[str]]:
    """Return every parameter's candidate covariates.

    The features, their squares and their pairwise products (each standardised when fitted).

    Parameters
    ----------
    features : sequence of str
        The columns.
    parameters : sequence of str
        The model's parameters.
    squares, products : bool, default=True
        Whether to add the squares, the pairwise products.

    Returns
    -------
    dict of str -> list of str
        The same candidates for every parameter.
    """
    f = list(features)
    names = f + ([f"{a}^2" for a in f] if squares else []) + (
        [f"{a}*{b}" for a, b in combinations(f, 2)] if products else [])
    return {p: list(names) for p in parameters}



#: :class:`ParametricBoostRegressor`'s ``min_improvement`` is at most this share of the
#: prior's MAE on the training rows.
MIN_IMPROVEMENT_SHARE = 1e-2

#: The candidates :class:`ParametricBoostRegressor` compares, simplest first.
CANDIDATES = ("prior", "calibrated", "drift", "ridge_drift", "boost")

#: ``drift``: how the drift candidates are made (forward selection, ridge over the whole pool).
DRIFTS = ("forward", "ridge", "both")

#: ``method="linearised"``: the best-scored single candidates refitted exactly each step
#: (:func:`~workbench.param_select.forward_select`'s ``shortlist``).
LINEARISED_SHORTLIST = 5

#: The ridge drift's penalties, chosen by the choice's CV (largest first: warm starts).
RIDGE_ALPHAS = (1e4, 1e3, 1e2, 1e1, 1.0, 1e-1, 1e-2)


class ParametricBoostRegressor(RegressorMixin, BaseEstimator):
    """A user's model calibrated, with parameter drifts chosen by CV, or neither.

    ``fit`` scores on the same CV folds of the rows it is given (``cv``): the prior
    (the model at its start values; no fit, so its training MAE), the calibrated model
    (:class:`ParametricRegressor` without covariates) and the linear drift whose covariates
    forward selection chooses from ``start`` over ``candidates``
    (:func:`workbench.param_select.forward_select`'s engine: each candidate refitted on
    every split, warm-started). A more complex candidate wins only by more than
    ``min_improvement``; the winner is refitted on all rows (``estimator_``).
    :attr:`choices_` tells the CV MAE of each and which won; where the drift does not win,
    :attr:`note_` says the error is not a drift of the parameters. With ``drift="ridge"``
    (or ``"both"``) the ``"ridge_drift"`` candidate replaces (or joins) the forward drift:
    every parameter drifts in its whole pool (``start`` and ``candidates``), no selection,
    its ridge penalty chosen from ``ridge_alphas`` on the same folds. With ``boost``, the
    parameter-space boosting (:mod:`workbench.parametric_gbm`, any scikit-learn regressor
    per parameter) is a further candidate, its rounds chosen on the same folds.

    Parameters
    ----------
    model : str or ParametricModel
        The path of a model file or a model.
    start : dict of str -> list of str, default=None
        Covariates every drift model has (None: intercepts only).
    candidates : "auto", dict of str -> list of str or None, default="auto"
        The selection's pool; ``"auto"``: :func:`covariate_pool` of ``features`` for every
        parameter, and ``"intercept"`` first for an optional one (the term as a constant);
        None: no drift candidate.
    features : list of str, default=None
        The columns the ``"auto"`` pool is built from (None: every numeric column of ``X``
        that is no parameter's column).
    squares, products : bool, default=True
        Whether the ``"auto"`` pool has the features' squares and pairwise products.
    cv : int or CV splitter, default=5
        The folds of every choice (the covariates, the candidate, the boosting's rounds):
        an int, ``RepeatedKFold(cv, n_repeats)`` seeded by ``random_state``; a splitter,
        its folds of ``X`` (e.g. the forward-chaining
        :class:`~workbench.selection.LabelTimeSeriesSplit`, which looks the rows up by
        ``X``'s index).
    n_repeats : int, default=1
        The repeats of an int ``cv`` (a splitter's folds are made once: it must be 1).
    max_steps : int, default=20
        The most covariates the selection adds (``"linearised"``: the most steps).
    method : {"refit", "linearised"}, default="refit"
        How the forward selection scores a candidate: ``"refit"`` fits the model with it on
        every fold; ``"linearised"`` takes one Gauss-Newton step of the enlarged model from
        the current fit on every fold (:func:`~workbench.param_linear.linear_scores`, the
        whole model's Jacobian, no refit) and refits only the best-scored candidates
        (:func:`~workbench.param_select.forward_select`'s ``method``: for large pools and
        models whose fits cost much).
    min_improvement : float, default=1e-3
        The CV MAE (targets' units) a covariate, or a more complex candidate, must gain; at
        most :data:`MIN_IMPROVEMENT_SHARE` of the prior's MAE on the training rows
        (:attr:`min_improvement_`), so that targets in small units (1e-9 s) can leave the
        prior.
    drift : {"forward", "ridge", "both"}, default="forward"
        The drift candidates: ``"forward"``, covariates chosen by forward selection (fitted
        with ``alpha``); ``"ridge"``, the ``"ridge_drift"`` candidate, every parameter's
        whole pool at once with the ridge penalty CV picks from ``ridge_alphas`` (no
        selection: many covariates, shrunk); ``"both"``, the two, CV choosing.
    ridge_alphas : sequence of float, default=None
        The ridge drift's penalties (None: :data:`RIDGE_ALPHAS`, 1e-2 to 1e4).
    alpha, alpha_l1, loss, huber_delta, max_iter, tol, out_of_bounds, calibrate, solver
        :class:`ParametricRegressor`'s (``calibrate=False``: the calibrated candidate's and
        the drift's fits start their offsets at 0; a ``boost`` template with ``init=None``
        still starts from its own calibration).
    random_state : int, default=None
        Seeds the splits (None: 0).
    n_jobs : int, default=None
        Processes scoring the selection's candidates (:mod:`workbench.parallel`).
    verbose : bool, default=False
        Report what ``fit`` does, a line per phase, CV fold and selection step (e.g.
        ``parametric: selection step 3: a_s <- Z*N  cv_mae=1.7400 (12 s)``): INFO records of
        the ``workbench.parametric_boost`` logger, or printed to standard error where no
        logging is set up (:mod:`workbench._progress`). No number depends on it.
    boost : ParameterSpaceBoostRegressor, default=None
        The ``"boost"`` candidate's template (None: no such candidate); its ``model``,
        ``loss``, ``huber_delta``, ``out_of_bounds`` and ``random_state`` are set from
        these.

    Attributes
    ----------
    estimator_ : ParametricRegressor or ParameterSpaceBoostRegressor
        The winner, refitted on all rows.
    choice_ : str
        ``"prior"``, ``"calibrated"``, ``"drift"``, ``"ridge_drift"`` or ``"boost"``.
    choices_ : DataFrame
        ``candidate``, ``cv_mae``, ``chosen``.
    note_ : str
    other_candidates_ : dict of str -> estimator
        The candidates CV scored but did not choose, unfitted with their choices made
        (covariates, ridge penalty, boosting rounds), simplest first, the prior and a boost
        of 0 rounds (its start model) left out:
        :class:`~workbench.fitted_prior.FittedPriorBoost`'s ``alternative="candidates"``
        fits the stage on each of them.
    selection_ : SelectionResult or None
        The forward selection (its path).
    ridge_path_ : DataFrame or None
        With a ridge drift: ``alpha``, ``cv_mae`` and ``chosen`` per penalty tried.
    cv_splits_ : list of (fit, validation) index arrays
        The folds every choice was scored on (positions into ``X``).
    cv_mae_ : float
        The winner's CV MAE.
    min_improvement_ : float
        The gain the selection and the choice asked for: ``min_improvement``, at most
        :data:`MIN_IMPROVEMENT_SHARE` of the prior's training MAE.
    n_iter_ : int
        The winner's Gauss-Newton iterations.
    """

    _parameter_constraints: dict = {
        "model": _MODEL,
        "start": [None, dict],
        "candidates": [None, StrOptions({"auto"}), dict],
        "features": [None, list, tuple],
        "squares": ["boolean"],
        "products": ["boolean"],
        "cv": [Interval(numbers.Integral, 2, None, closed="left"),
               HasMethods(["split", "get_n_splits"])],
        "n_repeats": [Interval(numbers.Integral, 1, None, closed="left")],
        "max_steps": [Interval(numbers.Integral, 0, None, closed="left")],
        "method": [StrOptions(set(SELECTION_METHODS))],
        "min_improvement": [Interval(numbers.Real, 0, None, closed="left")],
        "drift": [StrOptions(set(DRIFTS))],
        "ridge_alphas": [None, "array-like"],
        **{k: v for k, v in ParametricRegressor._parameter_constraints.items()
           if k not in ("model", "covariates")},
        "random_state": [None, numbers.Integral],
        "n_jobs": [None, numbers.Integral],
        "verbose": ["boolean"],
        "boost": [None, HasMethods(["fit", "staged_predict"])],
    }

    def __init__(self, *, model: str | ParametricModel | None = None,
                 start: dict[str, list[str]] | None = None,
                 candidates: str | dict[str, list[str]] | None = "auto",
                 features: Sequence[str] | None = None, squares: bool = True,
                 products: bool = True, cv: Any = 5, n_repeats: int = 1, max_steps: int = 20,
                 method: str = "refit", min_improvement: float = 1e-3, drift: str = "forward",
                 ridge_alphas: Sequence[float] | None = None, alpha: float = 1.0,
                 alpha_l1: float = 0.0,
                 loss: str = "huber", huber_delta: float = 1.0, max_iter: int = 20,
                 tol: float = 1e-6, out_of_bounds: str = "extrapolate", calibrate: bool = True,
                 solver: str = "newton", random_state: int | None = None,
                 n_jobs: int | None = None, verbose: bool = False, boost: Any = None) -> None:
        self.model = model
        self.start = start
        self.candidates = candidates
        self.features = features
        self.squares = squares
        self.products = products
        self.cv = cv
        self.n_repeats = n_repeats
        self.max_steps = max_steps
        self.method = method
        self.min_improvement = min_improvement
        self.drift = drift
        self.ridge_alphas = ridge_alphas
        self.alpha = alpha
        self.alpha_l1 = alpha_l1
        self.loss = loss
        self.huber_delta = huber_delta
        self.max_iter = max_iter
        self.tol = tol
        self.out_of_bounds = out_of_bounds
        self.calibrate = calibrate
        self.solver = solver
        self.random_state = random_state
        self.n_jobs = n_jobs
        self.verbose = verbose
        self.boost = boost

    def candidate_pool(self, X: pd.DataFrame) -> dict[str, list[str]]:
        """Return the selection's pool on the rows ``X``: each parameter's candidate
        covariates (``candidates``, or the ``"auto"`` pool of ``features``).

        Parameters
        ----------
        X : pandas.DataFrame
            The rows (the ``"auto"`` pool's columns without ``features``).

        Returns
        -------
        dict of str -> list of str
            Parameter -> its candidate covariates (empty with ``candidates=None``).
        """
        return self._pool(resolve_model(self.model), X)

    def _pool(self, model: ParametricModel, X: pd.DataFrame) -> dict[str, list[str]]:
        if self.candidates is None:
            return {}
        if isinstance(self.candidates, dict):
            return {p: list(v) for p, v in self.candidates.items()}
        if self.features is not None:
            features = list(self.features)
        else:
            used = {v for v in model.parameters.values() if isinstance(v, str)}
            features = [str(c) for c in X.columns if str(c) not in used
                        and pd.api.types.is_numeric_dtype(X[c])]
        pool = covariate_pool(features, model.names, squares=self.squares,
                              products=self.products)
        for p in getattr(model, "optional", ()):  # an optional term may enter as a constant
            pool[p] = ["intercept", *pool[p]]
        return pool

    def _alphas(self) -> list[float]:
        alphas = RIDGE_ALPHAS if self.ridge_alphas is None else self.ridge_alphas
        out = sorted((float(a) for a in np.ravel(alphas)), reverse=True)
        if not out or any(not np.isfinite(a) or a < 0 for a in out):
            raise ValueError(f"ridge_alphas must be finite penalties >= 0, at least one; "
                             f"got {list(np.ravel(alphas))}")
        return out

    def fit(self, X: pd.DataFrame, y: Any) -> Self:
        """Choose among prior, calibrated model and drifts by CV; refit the winner.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.
        y : array-like of shape (n_samples,) or (n_samples, n_targets)
            The measured targets.

        Returns
        -------
        self
            The fitted model.
        """
        self._validate_params()
        X = _as_frame(self, X, reset=True)
        t0 = time.perf_counter()
        say = Progress(__name__, self.verbose, "parametric: ")
        model = resolve_model(self.model)
        Y = _targets(y)
        base = self.calibrated_model()
        # the fit settings every candidate shares (calibrated_model's, one declaration)
        common: dict[str, Any] = {k: v for k, v in base.get_params(deep=False).items()
                                  if k not in ("covariates", "calibrate")}
        prior = ParametricRegressor(**{**common, "max_iter": 0}, calibrate=False)
        prior_fit = clone(prior).fit(X, Y)  # also checks the model (one line per bad case)
        scores = {"prior": float(np.mean(np.abs(prior_fit.predict(X) - Y)))}
        # in the targets' unit, but at most a share of the prior's error: a target measured
        # in small units (1e-9 s) could otherwise never leave the prior
        self.min_improvement_ = min(float(self.min_improvement),
                                    MIN_IMPROVEMENT_SHARE * scores["prior"])
        rs = 0 if self.random_state is None else int(self.random_state)
        self.cv_splits_ = _cv_splits(X, self.cv, self.n_repeats, rs)
        folds = _sliced(X, Y, self.cv_splits_)
        say(f"{len(model.names)} parameters, {len(X)} rows, {len(folds)} CV folds; the "
            f"prior's training MAE {scores['prior']:.4g}")
        scores["calibrated"] = float(_fit_splits(
            base, {}, folds, [None] * len(folds),
            done=_fold_lines(say, "calibrated model", len(folds)))[0])
        say(f"calibrated model: cv_mae={scores['calibrated']:.4g} ({say.elapsed()})")
        pool = self._pool(model, X)
        unknown = [p for p in list(pool) + list(self.start or {}) if p not in model.parameters]
        if unknown:
            raise ValueError(f"start and candidates name unknown parameter(s) {unknown}; the "
                             f"model's parameters are {model.names}")
        current = {p: list((self.start or {}).get(p, [])) for p in model.names}
        pairs = [(p, c) for p in model.names for c in dict.fromkeys(pool.get(p, []))
                 if c not in current[p]]
        self.selection_: SelectionResult | None = None
        self.ridge_path_: pd.DataFrame | None = None
        drift: dict[str, list[str]] | None = None
        ridge: ParametricRegressor | None = None
        if self.drift != "ridge" and (pairs or any(current.values())):
            say(f"drift: forward selection over {len(pairs)} candidate terms, at most "
                f"{self.max_steps} step(s)")
            jobs = effective_n_jobs(self.n_jobs)
            if self.method == "linearised":
                # IRLS-weighted scores: the calibrated model's residuals may lie far beyond
                # Huber's threshold, where the Newton weights are 0 (linear_scores' irls)
                self.selection_ = _linearised_select(
                    X, base, current, pairs, folds, jobs, self.max_steps, self.min_improvement_,
                    LINEARISED_SHORTLIST, "auto", say.child("selection "), t0, common,
                    irls_scores=True)
            else:
                self.selection_ = _refit_select(X, base, current, pairs, folds, jobs,
                                                self.max_steps, self.min_improvement_,
                                                say.child("selection "), t0, common)
            drift = self.selection_.covariates
            scores["drift"] = float(self.selection_.cv_mae)
            say(f"drift: {len(self.selection_.path) - 1} step(s), cv_mae={scores['drift']:.4g} "
                f"({say.elapsed()})")
        if self.drift != "forward" and (pairs or any(current.values())):
            library = {p: current[p] + [c for q, c in pairs if q == p] for p in model.names}
            ridge, scores["ridge_drift"], self.ridge_path_ = ridge_drift(
                clone(base).set_params(covariates=library), folds, self._alphas(),
                progress=say.child("ridge drift: "))
        drifts = {"drift": clone(base).set_params(covariates=drift) if drift else None,
                  "ridge_drift": ridge}
        booster = None
        if self.boost is not None:  # from the better drift by CV (None: the calibrated)
            best = min((k for k in drifts if k in scores), key=scores.__getitem__,
                       default="drift")
            booster, scores["boost"] = boost_candidate(clone(self.boost).set_params(
                model=self.model, loss=self.loss, huber_delta=self.huber_delta,
                out_of_bounds=self.out_of_bounds, random_state=rs), folds, drifts[best],
                progress=say.child("boost: "))[:2]
        self.choice_ = "prior"
        for name in CANDIDATES[1:]:
            if name in scores and scores[self.choice_] - scores[name] > self.min_improvement_:
                self.choice_ = name
        beaten = ("calibrated model" if {"drift", "ridge_drift"} & set(scores)
                  else "other candidates")
        self.note_ = ("" if self.choice_ in ("drift", "ridge_drift", "boost") else
                      "the error is not a drift of the parameters: the drift did not beat "
                      f"the {beaten} in CV")
        self.choices_ = pd.DataFrame({"candidate": list(scores), "cv_mae": list(scores.values()),
                                      "chosen": [k == self.choice_ for k in scores]})
        models = {"prior": prior, "calibrated": base, **drifts, "boost": booster}
        winner = models[self.choice_]
        # a boost of 0 rounds is its start model, a candidate already
        idle = booster is not None and booster.n_estimators == 0
        self.other_candidates_ = {k: clone(models[k]) for k in CANDIDATES[1:]
                                  if k in scores and k != self.choice_
                                  and models[k] is not None and not (k == "boost" and idle)}
        if say:
            cv = ", ".join(f"{k} {v:.4g}" for k, v in scores.items() if k != "prior")
            say(f"chose {self.choice_} (cv_mae: {cv}; the prior's training MAE "
                f"{scores['prior']:.4g}); refitting it on all {len(X)} rows")
        self.estimator_ = clone(winner).fit(X, np.asarray(y, dtype=float))
        self.cv_mae_ = scores[self.choice_]
        self.n_iter_ = self.estimator_.n_iter_
        self.seconds_ = time.perf_counter() - t0
        return self

    def calibrated_model(self) -> ParametricRegressor:
        """The ``"calibrated"`` candidate, unfitted: the model with its parameters calibrated
        and no drift, the fit settings these.

        Returns
        -------
        ParametricRegressor
            Unfitted; with these ``model``, ``calibrate``, penalties, loss, ``max_iter``,
            ``tol``, ``out_of_bounds`` and ``solver``.
        """
        return ParametricRegressor(
            model=self.model, alpha=self.alpha, alpha_l1=self.alpha_l1, loss=self.loss,
            huber_delta=self.huber_delta, max_iter=self.max_iter, tol=self.tol,
            out_of_bounds=self.out_of_bounds, solver=self.solver, calibrate=self.calibrate)

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """The winner's prediction.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        ndarray
            The predictions: ``(rows,)`` if fitted on one-dimensional ``y``, else
            ``(rows, targets)``.
        """
        check_is_fitted(self)
        return self.estimator_.predict(_as_frame(self, X, reset=False))

    def corrected_parameters(self, X: pd.DataFrame) -> pd.DataFrame:
        """The winner's parameters per row.

        Parameters
        ----------
        X : pandas.DataFrame of shape (n_samples, n_features)
            The model's and the covariates' columns, by name.

        Returns
        -------
        pandas.DataFrame
            One column per parameter, indexed as ``X``.
        """
        check_is_fitted(self)
        return self.estimator_.corrected_parameters(_as_frame(self, X, reset=False))

    def __sklearn_tags__(self) -> Any:
        """Multi-output: one column per target of the user's model."""
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True  # one column per target of the user's model
        return tags

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "estimator_")


def _fold_lines(say: Callable[[str], None] | None, what: str,
                n_folds: int) -> Callable[[int], None] | None:
    """``done(k)`` reporting ``"<what>: CV fold k/n"`` (and ``" (t s)"``, the time since
    the fit began, from a :class:`~workbench._progress.Progress`), or None when ``say`` is
    off."""
    if not say:
        return None
    elapsed = getattr(say, "elapsed", None)
    return lambda k: say(f"{what}: CV fold {k}/{n_folds}"
                         + (f" ({elapsed()})" if elapsed is not None else ""))


def boost_candidate(template: Any, folds: list[tuple], drift: Any = None, *,
                    progress: Callable[[str], None] | None = None
                    ) -> tuple[Any, float, np.ndarray]:
    """Score ``template`` by CV on the sliced ``folds`` (``(X_fit, y_fit, X_val, y_val)``).

    Each fold is fitted with ``template.n_estimators`` rounds; the CV MAE after every round
    (the mean over all held-out values, from the staged predictions) chooses the rounds.
    A template with ``init="drift"`` starts from ``drift`` (an unfitted ParametricRegressor
    with the selected covariates; None: the calibrated model).

    Parameters
    ----------
    template : ParameterSpaceBoostRegressor
        The unfitted candidate (:mod:`workbench.parametric_gbm`; its ``n_estimators``:
        the most rounds).
    folds : list of tuple
        ``(X_fit, y_fit, X_val, y_val)`` per fold.
    drift : ParametricRegressor, optional
        The start of an ``init="drift"`` template.
    progress : callable, optional
        Called with a line after each fold and with the chosen rounds (e.g. the fit's
        :class:`~workbench._progress.Progress`); None or false: no lines.

    Returns
    -------
    estimator : ParameterSpaceBoostRegressor
        ``template`` with ``n_estimators`` the chosen rounds (unfitted).
    cv_mae : float
        Its CV MAE.
    curve : ndarray
        The CV MAE after 0, 1, ... rounds.
    """
    if isinstance(template.init, str):
        template = clone(template).set_params(init=drift)
    n = template.n_estimators + 1
    abs_sum, count = np.zeros(n), 0
    done = _fold_lines(progress, f"{n - 1} rounds at most", len(folds))
    for k, (X_fit, y_fit, X_val, y_val) in enumerate(folds, 1):
        fitted = clone(template).fit(X_fit, y_fit)
        y_val = np.asarray(y_val, dtype=float)
        last = 0.0
        for m, pred in enumerate(fitted.staged_predict(X_val)):
            last = float(np.abs(np.reshape(pred, y_val.shape) - y_val).sum())
            abs_sum[m] += last
        abs_sum[fitted.n_iter_ + 1:] += last  # a fold that stopped early keeps its last
        count += y_val.size
        if done is not None:
            done(k)
    curve = abs_sum / count
    rounds = int(np.argmin(curve))
    if progress:
        progress(f"{rounds} rounds chosen, cv_mae={curve[rounds]:.4g}")
    return clone(template).set_params(n_estimators=rounds), float(curve[rounds]), curve


def ridge_drift(template: ParametricRegressor, folds: list[tuple], alphas: Sequence[float], *,
                progress: Callable[[str], None] | None = None
                ) -> tuple[ParametricRegressor, float, pd.DataFrame]:
    """Choose the ridge penalty of a drift over a whole covariate library by CV.

    Every parameter drifts in all of ``template.covariates`` at once (no selection); each
    penalty of ``alphas`` is scored on the sliced ``folds``, in the given order, each fold's
    fit warm-started from the previous penalty's (largest first: the next fit starts near).

    Parameters
    ----------
    template : ParametricRegressor
        The unfitted drift, its ``covariates`` the whole library.
    folds : list of tuple
        ``(X_fit, y_fit, X_val, y_val)`` per fold.
    alphas : sequence of float
        The penalties tried.
    progress : callable, optional
        Called with a line after each penalty is scored; None or false: no lines.

    Returns
    -------
    estimator : ParametricRegressor
        ``template`` with the chosen ``alpha`` (unfitted).
    cv_mae : float
        Its CV MAE.
    path : DataFrame
        ``alpha``, ``cv_mae`` and ``chosen`` per penalty.
    """
    warm: list = [None] * len(folds)
    maes = []
    for i, a in enumerate(alphas, 1):
        mae, warm = _fit_splits(clone(template).set_params(alpha=float(a)),
                                template.covariates or {}, folds, warm)
        maes.append(float(mae))
        if progress:
            progress(f"alpha {float(a):g} ({i}/{len(alphas)}) cv_mae={float(mae):.4g}")
    k = int(np.argmin(maes))
    path = pd.DataFrame({"alpha": [float(a) for a in alphas], "cv_mae": maes,
                         "chosen": [i == k for i in range(len(maes))]})
    return clone(template).set_params(alpha=float(alphas[k])), maes[k], path
