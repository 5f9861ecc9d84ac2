"""Inbuilt model selection (the paper's Alg. 2): boost only where cross-validation says it helps."""

from __future__ import annotations

import numbers
import warnings
from collections.abc import Callable, Iterator
from typing import Any, Self

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, MetaEstimatorMixin, RegressorMixin, clone
from sklearn.exceptions import FitFailedWarning
from sklearn.metrics import check_scoring
from sklearn.model_selection import BaseCrossValidator, GroupKFold, check_cv
from sklearn.utils import _safe_indexing, check_random_state
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.metaestimators import _BaseComposition
from sklearn.utils.validation import check_is_fitted, validate_data

from .boosting import BaseBoostRegressor, CachedParamNames, PriorModel, seed_estimator
from .parallel import Plan, Task, gather, run_plans

__all__ = ["RULES", "BaseBoostCV", "BasisChoiceCV", "CandidateMean", "LabelGroupKFold",
           "LabelTimeSeriesSplit", "choose", "find_prior", "paired_standard_error"]


def find_prior(estimator: Any) -> Any:
    """The ``prior`` parameter of ``estimator`` (or of the ones it wraps, e.g. in a Pipeline
    or a :class:`CandidateMean`).

    A composite of several base-boosting estimators has a prior when all of theirs are the
    same (the same column, callable, or estimator type with the same parameters); priors
    nested inside a prior estimator are not counted.

    Parameters
    ----------
    estimator : estimator
        A base-boosting estimator, or one that wraps one or several.

    Returns
    -------
    object
        The prior (the first of the equal ones).

    Raises
    ------
    ValueError
        When ``estimator`` holds no prior, or several that differ."""
    params = estimator.get_params(deep=True)
    if "prior" in params:
        return params["prior"]
    nested = [params[k] for k in params if k.endswith("__prior") and "__prior__" not in k]
    if nested and all(_same_param(p, nested[0]) for p in nested[1:]):
        return nested[0]
    what = "no" if not nested else f"{len(nested)} different"
    raise ValueError(f"cannot find the prior of {type(estimator).__name__} ({what} nested "
                     "'prior' parameters); pass incumbent=")


def _same_param(a: Any, b: Any) -> bool:
    """Whether two parameter values are the same: equal values, or estimators of one type
    whose parameters are the same (what ``clone`` keeps)."""
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    if isinstance(a, BaseEstimator):
        pa, pb = a.get_params(deep=False), b.get_params(deep=False)
        return pa.keys() == pb.keys() and all(_same_param(pa[k], pb[k]) for k in pa)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same_param(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same_param(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return bool(np.array_equal(a, b))
    try:
        return bool(a == b)
    except (TypeError, ValueError):  # e.g. values whose == is elementwise
        return False


class _Predicted(RegressorMixin, BaseEstimator):
    """A regressor whose ``predict`` returns the predictions it holds: a metric scorer's
    input, so a fold's model predicts its held-out rows once, not once for the score and
    once for the out-of-fold predictions."""

    def __init__(self, predictions: Any = None) -> None:
        self.predictions = predictions

    def predict(self, X: Any) -> Any:
        return self.predictions


def _score_and_predict(scorer: Callable, model: Any, X: Any, y: np.ndarray,
                       by_metric: bool) -> tuple[Any, Any]:
    """``(scorer(model, X, y), model.predict(X))``, predicting once when the scorer is a
    metric of the predictions (a scoring name)."""
    if not by_metric:
        return scorer(model, X, y), model.predict(X)
    pred = model.predict(X)
    return scorer(_Predicted(pred), X, y), pred


def _fold(incumbent: Any, estimator: Any, X: Any, y: np.ndarray, train: np.ndarray,
          test: np.ndarray, scorer: Callable, train_score: bool | float = False,
          by_metric: bool = False
          ) -> tuple[float, float, str | None, np.ndarray, np.ndarray, float]:
    """Scores of both models on one fold, their predictions on its held-out rows, and the
    candidate's score on the fold's own training rows (NaN unless ``train_score``).
    ``by_metric``: the scorer is a metric of the predictions (a scoring name), so each model
    predicts the held-out rows once."""
    X_tr, X_te, y_tr, y_te = _safe_indexing(X, train), _safe_indexing(X, test), y[train], y[test]
    prior = clone(incumbent).fit(X_tr, y_tr)
    prior_score, prior_pred = _score_and_predict(scorer, prior, X_te, y_te, by_metric)
    try:
        fitted = clone(estimator).fit(X_tr, y_tr)
        score, pred = _score_and_predict(scorer, fitted, X_te, y_te, by_metric)
        error = None
        train_score = scorer(fitted, X_tr, y_tr) if train_score else np.nan
    except Exception as exc:  # a failed candidate is recorded, never chosen
        score, pred, error = np.nan, np.full(len(test), np.nan), f"{type(exc).__name__}: {exc}"
        train_score = np.nan
    return (float(prior_score), float(score), error, np.asarray(prior_pred), np.asarray(pred),
            float(train_score))


def _refit(estimator: Any, X: Any, y: Any) -> tuple[Any, str | None]:
    """``(estimator fitted on all rows, None)``, or ``(None, error message)``."""
    try:
        return estimator.fit(X, y), None
    except Exception as exc:
        return None, f"{type(exc).__name__}: {exc}"


#: The rules that choose among the prior and the candidates from their fold scores
#: (:func:`choose`).
RULES = ("best", "one_se", "prior_se")


def paired_standard_error(a: Any, b: Any) -> float:
    """The standard error of the mean of the paired fold differences ``a - b``.

    Two models scored on the same folds differ fold by fold; the noise of their mean
    difference is ``std(a - b, ddof=1) / sqrt(n_folds)``. The fold-to-fold variation both
    models share (a hard fold is hard for both) cancels in the differences, so this is
    smaller than either model's own standard error.

    Parameters
    ----------
    a, b : array-like of shape (n_folds,)
        Two models' scores on the same folds.

    Returns
    -------
    float
        The standard error (0 with a single fold: no spread to measure).
    """
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if d.size < 2:
        return 0.0
    return float(np.std(d, ddof=1) / np.sqrt(d.size))


def choose(scores: dict[str, Any], rule: str = "best") -> str:
    """Choose among models from their fold scores, listed simplest first.

    Parameters
    ----------
    scores : dict of str -> array-like of shape (n_folds,)
        Each model's scores on the same folds (greater is better; all finite), in order of
        complexity: the simplest first (in :class:`BasisChoiceCV`: the prior, then the
        candidates as listed, then the mean of the best ones).
    rule : {"best", "one_se", "prior_se"}, default="best"
        ``"best"``: the model with the best mean score; the simplest of those tied for it.
        ``"one_se"``: the one-standard-error rule (Breiman et al. 1984; Hastie, Tibshirani
        and Friedman, *The Elements of Statistical Learning*, 7.10), on paired differences:
        the simplest model whose mean score is within one standard error of the best's,
        where each model's standard error is that of its paired fold differences from the
        best (:func:`paired_standard_error`), i.e. the first ``m`` with
        ``mean(best - m) <= paired_standard_error(best, m)``. A gain the folds cannot tell
        from noise does not buy complexity.
        ``"prior_se"``: the one-standard-error rule between the prior and the best only:
        the prior (the first model) unless the best beats it by more than one standard
        error of their paired fold differences, else the best. It guards against losing to
        the prior without giving up the best candidate's gain for a simpler candidate's.

    Returns
    -------
    str
        The chosen model's name.
    """
    if rule not in RULES:
        raise ValueError(f"unknown rule {rule!r}; valid rules are: {', '.join(RULES)}")
    means = {name: float(np.mean(s)) for name, s in scores.items()}
    best = max(means, key=lambda name: means[name])  # the first of those tied
    if rule == "best":
        return best
    if rule == "prior_se":
        first = next(iter(scores))
        gain = np.asarray(scores[best], dtype=float) - np.asarray(scores[first], dtype=float)
        return first if np.mean(gain) <= paired_standard_error(scores[best], scores[first]) \
            else best
    top = np.asarray(scores[best], dtype=float)
    return next((name for name in scores
                 if np.mean(top - np.asarray(scores[name], dtype=float))
                 <= paired_standard_error(top, scores[name])), best)


class BaseBoostCV(CachedParamNames, MetaEstimatorMixin, RegressorMixin, BaseEstimator):
    """Choose between the prior alone (the incumbent) and a boosted candidate by CV.

    Both are scored on the same folds of the training rows. The candidate is selected only
    if every one of its folds succeeded and its mean score is strictly better (``rule=
    "one_se"``: better by more than one standard error of the paired fold differences);
    ties and failures go to the prior (with a ``FitFailedWarning`` for failures).

    Parameters
    ----------
    estimator : regressor, default=None
        The candidate (``None``: ``BaseBoostRegressor()``).
    incumbent : regressor, default=None
        The prior-alone model; ``None`` builds ``PriorModel(prior=<the estimator's prior>)``.
    cv : int, CV splitter or iterable, default=5
        As in scikit-learn; an int gives contiguous, unshuffled ``KFold`` (the paper's).
    scoring : str or callable, default="neg_mean_absolute_error"
        Selection score, greater is better.
    refit : bool, default=True
        Refit the selected model on all rows. ``False`` only computes the fold scores
        (e.g. inside a hyperparameter search).
    n_jobs : int, default=None
        Folds fitted in parallel.
    random_state : int, RandomState or None, default=None
        If set, seeds every ``random_state`` of the candidate (and of ``cv`` when it shuffles).
    return_train_score : bool, default=False
        Also score the candidate on each fold's own training rows (one more prediction per
        fold): ``cv_train_scores_boosted_``, the whole-fold point of a learning curve.
    rule : {"best", "one_se", "prior_se"}, default="best"
        How CV chooses (:func:`choose`, the prior counting as the simpler model):
        ``"best"``, the better mean score; ``"one_se"`` and ``"prior_se"`` (the same with
        one candidate), the one-standard-error rule, the prior unless the candidate's mean
        gain exceeds one standard error of the paired fold differences.

    Attributes
    ----------
    selected_ : {"prior", "boosted"}
    cv_scores_prior_, cv_scores_boosted_ : ndarray of shape (n_splits,)
        Per-fold scores (NaN where the candidate failed).
    cv_train_scores_boosted_ : ndarray of shape (n_splits,)
        The candidate's score on each fold's own training rows (a learning curve's training
        error at the full fold size, :func:`workbench.curves.selection_learning_curve`); NaN
        unless ``return_train_score``.
    cv_splits_ : list of (train, test) index arrays
        The folds.
    cv_predictions_prior_, cv_predictions_boosted_ : ndarray of shape (n_samples,)
        Out-of-fold predictions of each model (NaN for rows in no held-out fold and where
        the candidate failed; a row held out by several folds keeps the last).
    fit_errors_ : list of str
        Messages of the candidate's failed fits.
    best_estimator_ : regressor
        The selected model refitted on all rows (when ``refit=True``).
    """

    _parameter_constraints: dict = {
        "estimator": [None, HasMethods(["fit", "predict"])],
        "incumbent": [None, HasMethods(["fit", "predict"])],
        "cv": ["cv_object"],
        "scoring": [str, callable],
        "refit": ["boolean"],
        "n_jobs": [numbers.Integral, None],
        "random_state": ["random_state"],
        "return_train_score": ["boolean"],
        "rule": [StrOptions(set(RULES))],
    }

    def __init__(self, estimator: Any = None, *, incumbent: Any = None, cv: Any = 5,
                 scoring: str | Callable = "neg_mean_absolute_error", refit: bool = True,
                 n_jobs: int | None = None,
                 random_state: int | np.random.RandomState | None = None,
                 return_train_score: bool = False, rule: str = "best") -> None:
        self.estimator = estimator
        self.incumbent = incumbent
        self.cv = cv
        self.scoring = scoring
        self.refit = refit
        self.n_jobs = n_jobs
        self.random_state = random_state
        self.return_train_score = return_train_score
        self.rule = rule

    def _candidate(self) -> Any:
        est = BaseBoostRegressor() if self.estimator is None else clone(self.estimator)
        if self.random_state is not None:
            seed_estimator(est, check_random_state(self.random_state).randint(2**31 - 1))
        return est

    def fit(self, X: Any, y: Any,
            fold_callback: Callable[[int, float, float], None] | None = None) -> Self:
        """Score both models by CV, then (if ``refit``) refit the selected one.

        ``fold_callback(fold, prior_score, boosted_score)``, if given, is called after each
        fold (folds then run one after another); an exception it raises stops the fit. This
        lets a hyperparameter search report per-fold scores to a pruner without the core
        knowing about it.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : array-like of shape (n_samples,)
            The target.
        fold_callback : callable, default=None
            ``fold_callback(fold, prior_score, boosted_score)`` after each fold.

        Returns
        -------
        self
            The fitted selection.
        """
        (fitted,) = run_plans([self._fit_plan(X, y, fold_callback)],
                              1 if fold_callback is not None else self.n_jobs)
        return fitted

    def _fit_plan(self, X: Any, y: Any,
                  fold_callback: Callable[[int, float, float], None] | None = None,
                  warn: bool = True) -> Plan:
        """:meth:`fit` as a plan (:mod:`workbench.parallel`): the folds, then the refit
        (``warn=False``: no warning for failed candidate fits, e.g. one of several
        candidates)."""
        self._validate_params()
        candidate = self._candidate()
        incumbent = (PriorModel(prior=find_prior(candidate)) if self.incumbent is None
                     else self.incumbent)
        validate_data(self, X, y, y_numeric=True, dtype=float)
        if not hasattr(X, "iloc"):  # keep DataFrames (column names) for the sub-estimators
            X = np.asarray(X)
        y = np.asarray(y, dtype=float)
        if y.ndim == 2 and y.shape[1] == 1:
            y = y[:, 0]
        cv = check_cv(self.cv, y, classifier=False)
        scorer = check_scoring(candidate, scoring=self.scoring)
        splits = list(cv.split(X, y))
        by_metric = isinstance(self.scoring, str)
        tasks = [Task(_fold, incumbent, candidate, X, y, train, test, scorer,
                      bool(self.return_train_score), by_metric) for train, test in splits]
        if fold_callback is None:
            folds = yield tasks
        else:
            folds = []
            for i, task in enumerate(tasks):
                folds += yield [task]
                fold_callback(i, folds[-1][0], folds[-1][1])
        self.cv_scores_prior_ = np.array([f[0] for f in folds])
        self.cv_scores_boosted_ = np.array([f[1] for f in folds])
        self.cv_train_scores_boosted_ = np.array([f[5] for f in folds])
        self.cv_splits_ = [(np.asarray(tr), np.asarray(te)) for tr, te in splits]
        self.cv_predictions_prior_ = np.full(len(y), np.nan)
        self.cv_predictions_boosted_ = np.full(len(y), np.nan)
        for (_, test), fold in zip(splits, folds):
            self.cv_predictions_prior_[test] = fold[3]
            self.cv_predictions_boosted_[test] = fold[4]
        self.fit_errors_ = [f[2] for f in folds if f[2] is not None]
        boosted_ok = not self.fit_errors_ and np.all(np.isfinite(self.cv_scores_boosted_))
        if self.fit_errors_ and warn:
            warnings.warn(f"{len(self.fit_errors_)} of {len(folds)} candidate fits failed; "
                          f"selecting the prior. First error: {self.fit_errors_[0]}",
                          FitFailedWarning, stacklevel=2)
        wins = boosted_ok and choose({"prior": self.cv_scores_prior_,
                                      "boosted": self.cv_scores_boosted_},
                                     self.rule) == "boosted"
        self.selected_ = "boosted" if wins else "prior"
        if self.refit:
            if wins:
                fitted, error = (yield [Task(_refit, candidate, X, y)])[0]
                if error is None:
                    self.best_estimator_ = fitted
                else:
                    warnings.warn(f"refitting the candidate on all rows failed ({error}); "
                                  "selecting the prior", FitFailedWarning, stacklevel=2)
                    self.fit_errors_.append(error)
                    self.selected_ = "prior"
            if self.selected_ == "prior":
                self.best_estimator_ = clone(incumbent).fit(X, y)
        return self

    @property
    def cv_predictions_(self) -> np.ndarray:
        """Out-of-fold predictions of the selected model."""
        check_is_fitted(self)
        return (self.cv_predictions_boosted_ if self.selected_ == "boosted"
                else self.cv_predictions_prior_)

    @property
    def cv_folds_(self) -> np.ndarray:
        """Per training row, the index of the fold that held it out (-1: none)."""
        check_is_fitted(self)
        folds = np.full(len(self.cv_predictions_prior_), -1, dtype=int)
        for k, (_, test) in enumerate(self.cv_splits_):
            folds[test] = k
        return folds

    @property
    def cv_score_(self) -> float:
        """Mean CV score of the selected model."""
        check_is_fitted(self)
        scores = self.cv_scores_boosted_ if self.selected_ == "boosted" else self.cv_scores_prior_
        return float(np.mean(scores))

    def predict(self, X: Any) -> Any:
        """Predict with the selected model (the prior alone, or the boosted one).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The predictions.
        """
        check_is_fitted(self)
        if not hasattr(self, "best_estimator_"):
            raise AttributeError("BaseBoostCV was fitted with refit=False: it has fold scores "
                                 "but no model to predict with")
        return self.best_estimator_.predict(X)

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "selected_")


class CandidateMean(_BaseComposition, RegressorMixin, BaseEstimator):
    """The mean of several regressors' predictions: :class:`BasisChoiceCV`'s ensemble of its
    best candidates (all boosting from the same prior).

    Parameters
    ----------
    members : list of (str, regressor) tuples
        Cloned and fitted on the same rows; their parameters are nested as
        ``<name>__<param>``, as in a Pipeline.

    Attributes
    ----------
    members_ : list of fitted regressors
    coefs_ : ndarray
        The members' stage coefficients one after another (all 0: the model is the prior).
    """

    _parameter_constraints: dict = {"members": [list]}

    def __init__(self, members: list[tuple[str, Any]] | None = None) -> None:
        self.members = members

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Get the parameters, the members' own nested as ``<name>__<param>``.

        Parameters
        ----------
        deep : bool, default=True
            Include the members' parameters.

        Returns
        -------
        dict
            Parameter name -> value.
        """
        return self._get_params("members", deep=deep)

    def set_params(self, **params: Any) -> Self:
        """Set parameters, a member's as ``<name>__<param>``.

        Parameters
        ----------
        **params
            Parameter name -> value.

        Returns
        -------
        self
            The estimator.
        """
        self._set_params("members", **params)
        return self

    def fit(self, X: Any, y: Any) -> Self:
        """Fit a clone of each member on ``(X, y)``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : array-like of shape (n_samples,)
            The target.

        Returns
        -------
        self
            The fitted mean.
        """
        self._validate_params()
        if not self.members:
            raise ValueError("members must be a non-empty list of (name, regressor) tuples")
        self.members_ = [clone(est).fit(X, y) for _, est in self.members]
        first = self.members_[0]
        for attr in ("n_features_in_", "feature_names_in_"):
            if hasattr(first, attr):
                setattr(self, attr, getattr(first, attr))
        return self

    def predict(self, X: Any) -> np.ndarray:
        """Average the members' predictions.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The mean prediction.
        """
        check_is_fitted(self)
        return np.mean([np.asarray(m.predict(X), dtype=float) for m in self.members_], axis=0)

    def predict_prior(self, X: Any) -> np.ndarray:
        """The members' common prior for ``X``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The prior.
        """
        check_is_fitted(self)
        return self.members_[0].predict_prior(X)

    def predict_correction(self, X: Any) -> np.ndarray:
        """What the mean adds to the prior, in the target's units.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples,)
            The correction.
        """
        check_is_fitted(self)
        return np.mean([m.predict_correction(X) for m in self.members_], axis=0)

    @property
    def coefs_(self) -> np.ndarray:
        """The members' stage coefficients one after another."""
        check_is_fitted(self)
        return np.concatenate([np.ravel(getattr(m, "coefs_", [1.0])) for m in self.members_])

    def __sklearn_is_fitted__(self) -> bool:
        """Tell scikit-learn whether :meth:`fit` has run."""
        return hasattr(self, "members_")


class BasisChoiceCV(_BaseComposition, BaseBoostCV):
    """The prior alone against several boosted candidates (e.g. one per basis family), all
    scored on the same CV folds of the training rows: with ``rule="best"`` the candidate
    with the best mean score is selected if it beats the prior (ties and failed candidates
    go to the prior); with ``rule="one_se"`` the simplest model whose mean score is within
    one standard error of the best's (the prior being the simplest of all).

    A flexible stage for a physics model: which basis (ridge, kernel ridge, LightGBM, the
    paper's stacking, ...) captures what the physics misses is decided by CV per target,
    and boosting is kept only where it helps.

    Parameters
    ----------
    candidates : list of (str, regressor) tuples
        The boosted candidates by name (each with the same ``prior``), listed simplest
        first: ``rule="one_se"`` takes this order as the order of complexity, after the
        prior (the simplest) and before the mean of the best (the most complex). Their
        parameters are nested as ``<name>__<param>``, as in a Pipeline; ``"prior"`` is not
        a candidate's name.
    incumbent, cv, scoring, refit, n_jobs, random_state :
        As in :class:`BaseBoostCV` (one seed reaches every candidate). ``cv`` splits once:
        every candidate is scored on the same folds.
    rule : {"best", "one_se", "prior_se"}, default="best"
        How CV chooses among the prior, the candidates and their mean (:func:`choose`, in
        that order of complexity). ``"best"``: the best mean score (ties to the simpler).
        ``"one_se"``: the one-standard-error rule, the simplest whose mean score is within
        one standard error of the paired fold differences from the best's. Out of 50
        candidates on five folds the best is partly the luckiest; the one-SE rule keeps the
        prior (or a simpler candidate) unless the folds can tell the gain from noise, which
        holds up better when the test rows differ from the training rows (later dates, new
        devices). ``"prior_se"``: the prior unless the best beats it by more than one
        standard error of their paired fold differences, else the best.
    ensemble : int, default=1
        Above 1, the mean of the ``ensemble`` best candidates (:class:`CandidateMean`) is a
        candidate too, scored on the same folds from their out-of-fold predictions (no
        extra fit): it wins where its CV score beats the best single candidate's (and the
        prior's). Averaging several good candidates removes part of the variance that
        choosing one of many on a few folds adds. Needs a scoring name (a metric of the
        predictions).

    Attributes
    ----------
    selected_ : {"prior", "boosted"}
    selected_candidate_ : str or None
        The winning candidate's name (``None`` when the prior is selected); the ensemble's
        is ``"mean of <k>"``.
    candidate_scores_ : dict of str -> ndarray of shape (n_splits,)
        The fold scores of the prior (``"prior"``), of every candidate (NaN where a fit
        failed) and of the ensemble (with ``ensemble`` > 1), in the rule's order of
        complexity.
    best_candidate_ : str or None
        The model with the best mean CV score (``"prior"`` possibly; ``None`` when every
        candidate failed): the rule's reference; the selected one unless ``rule="one_se"``
        chose a simpler one.
    candidate_predictions_ : dict of str -> ndarray of shape (n_samples,)
        Every candidate's out-of-fold predictions on the training rows (those whose fits
        succeeded), from the same folds: for stacking or other ways of combining them.
    estimator_ : regressor
        The winning candidate (the first one when the prior is selected), unfitted: a
        :class:`CandidateMean` when the ensemble won.
    cv_scores_prior_, cv_scores_boosted_, cv_predictions_prior_, cv_predictions_boosted_,
    cv_splits_, fit_errors_, best_estimator_ :
        As in :class:`BaseBoostCV`, the boosted ones of the winning candidate.
    """

    _parameter_constraints: dict = {
        **{k: v for k, v in BaseBoostCV._parameter_constraints.items()
           if k not in ("estimator", "return_train_score")},
        "candidates": [list],
        "ensemble": [Interval(numbers.Integral, 1, None, closed="left")],
    }

    def __init__(self, candidates: list[tuple[str, Any]] | None = None, *, incumbent: Any = None,
                 cv: Any = 5, scoring: str | Callable = "neg_mean_absolute_error",
                 refit: bool = True, n_jobs: int | None = None,
                 random_state: int | np.random.RandomState | None = None,
                 ensemble: int = 1, rule: str = "best") -> None:
        self.candidates = candidates
        self.ensemble = ensemble
        self.rule = rule
        self.incumbent = incumbent
        self.cv = cv
        self.scoring = scoring
        self.refit = refit
        self.n_jobs = n_jobs
        self.random_state = random_state

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Get the parameters, the candidates' own nested as ``<name>__<param>``.

        Parameters
        ----------
        deep : bool, default=True
            Include the candidates' parameters.

        Returns
        -------
        dict
            Parameter name -> value.
        """
        return self._get_params("candidates", deep=deep)

    def set_params(self, **params: Any) -> Self:
        """Set parameters, a candidate's as ``<name>__<param>``.

        Parameters
        ----------
        **params
            Parameter name -> value.

        Returns
        -------
        self
            The estimator.
        """
        self._set_params("candidates", **params)
        return self

    def fit(self, X: Any, y: Any,
            fold_callback: Callable[[int, float, float], None] | None = None) -> Self:
        """Score the prior and every candidate on the same folds, then (if ``refit``) refit
        the selected model. ``fold_callback`` is not supported (it would be called once per
        candidate and fold)."""
        if fold_callback is not None:
            raise TypeError("BasisChoiceCV takes no fold_callback")
        (fitted,) = run_plans([self._fit_plan(X, y)], self.n_jobs)
        return fitted

    def _fit_plan(self, X: Any, y: Any,
                  fold_callback: Callable[[int, float, float], None] | None = None,
                  warn: bool = True) -> Plan:
        """:meth:`fit` as a plan (:mod:`workbench.parallel`): every candidate's folds side by
        side, then the refit. ``warn`` is :class:`BaseBoostCV`'s: here a failed candidate fit
        never warns (the candidate is simply not chosen)."""
        if fold_callback is not None:
            raise TypeError("BasisChoiceCV takes no fold_callback")
        self._validate_params()
        if not self.candidates or not all(
                isinstance(c, tuple) and len(c) == 2 for c in self.candidates):
            raise ValueError(f"candidates must be a non-empty list of (name, regressor) "
                             f"tuples, got {self.candidates!r}")
        self._validate_names([name for name, _ in self.candidates])
        if "prior" in dict(self.candidates):
            raise ValueError("'prior' names the prior alone, not a candidate: rename the "
                             "candidate")
        candidates = dict(self.candidates)
        validate_data(self, X, y, y_numeric=True, dtype=float)
        X_all = X if hasattr(X, "iloc") else np.asarray(X)
        y_all = np.ravel(np.asarray(y, dtype=float))
        # one split shared by every candidate: the one-SE rule pairs their fold scores
        splits = list(check_cv(self.cv, y_all, classifier=False).split(X_all, y_all))
        # a failing candidate is simply not chosen (no warning)
        runs = dict(zip(candidates, (yield from gather(
            BaseBoostCV(candidate, incumbent=self.incumbent, cv=splits, scoring=self.scoring,
                        refit=False, n_jobs=self.n_jobs,
                        random_state=self.random_state)._fit_plan(X, y, warn=False)
            for candidate in candidates.values()))))
        first = next(iter(runs.values()))
        self.candidate_scores_ = {"prior": first.cv_scores_prior_,
                                  **{n: r.cv_scores_boosted_ for n, r in runs.items()}}
        ok = {n: r for n, r in runs.items()
              if not r.fit_errors_ and np.all(np.isfinite(r.cv_scores_boosted_))}
        self.candidate_predictions_ = {n: r.cv_predictions_boosted_ for n, r in ok.items()}
        single = choose({n: r.cv_scores_boosted_ for n, r in ok.items()}) if ok else None
        mean = self._ensemble(ok, candidates, X, y) if ok else None
        pool = {"prior": first.cv_scores_prior_,
                **{n: r.cv_scores_boosted_ for n, r in ok.items()},
                **({mean[0]: mean[1]} if mean is not None else {})}
        self.best_candidate_ = choose(pool) if ok else None
        winner = choose(pool, self.rule)
        # the boosted model reported beside the prior: the winner, else the best of the rest
        boosted = winner if winner != "prior" else (
            choose({n: v for n, v in pool.items() if n != "prior"}) if ok else None)
        base = boosted if boosted in runs else single  # the mean: its best member's folds
        chosen = runs[base] if base is not None else first
        for attr in ("cv_scores_prior_", "cv_scores_boosted_", "cv_predictions_prior_",
                     "cv_predictions_boosted_", "cv_splits_", "fit_errors_"):
            setattr(self, attr, getattr(chosen, attr))
        self.estimator_ = candidates[base if base is not None else next(iter(runs))]
        if mean is not None and boosted == mean[0]:
            _, self.cv_scores_boosted_, self.cv_predictions_boosted_, self.estimator_ = mean
        wins = winner != "prior"
        self.selected_ = "boosted" if wins else "prior"
        self.selected_candidate_ = winner if wins else None
        if self.refit:
            refit = BaseBoostCV(self.estimator_, incumbent=self.incumbent, cv=self.cv,
                                scoring=self.scoring, random_state=self.random_state)
            incumbent = (PriorModel(prior=find_prior(candidates[next(iter(candidates))]))
                         if self.incumbent is None else self.incumbent)
            if wins:
                fitted, error = (yield [Task(_refit, refit._candidate(), X_all, y_all)])[0]
                if error is None:
                    self.best_estimator_ = fitted
                else:
                    warnings.warn(f"refitting {winner} on all rows failed ({error}); selecting "
                                  "the prior", FitFailedWarning, stacklevel=2)
                    self.selected_, self.selected_candidate_ = "prior", None
            if self.selected_ == "prior":
                self.best_estimator_ = clone(incumbent).fit(X_all, y_all)
        return self

    def _ensemble(self, ok: dict[str, Any], candidates: dict[str, Any], X: Any,
                  y: Any) -> tuple[str, np.ndarray, np.ndarray, CandidateMean] | None:
        """``(name, fold scores, out-of-fold predictions, CandidateMean)`` of the mean of the
        ``ensemble`` best candidates, from their out-of-fold predictions on the shared
        folds; ``None`` without ``ensemble`` > 1 or two good candidates."""
        if self.ensemble < 2 or len(ok) < 2:
            return None
        if not isinstance(self.scoring, str):
            raise ValueError("ensemble > 1 needs a scoring name (a metric of the "
                             f"predictions), got {self.scoring!r}")
        top = sorted(ok, key=lambda n: ok[n].cv_scores_boosted_.mean(),
                     reverse=True)[:self.ensemble]
        oof = np.mean([ok[n].cv_predictions_boosted_ for n in top], axis=0)
        y = np.ravel(np.asarray(y, dtype=float))
        scorer = check_scoring(candidates[top[0]], scoring=self.scoring)
        X_arr = X if hasattr(X, "iloc") else np.asarray(X)
        splits = ok[top[0]].cv_splits_
        scores = np.array([scorer(_Predicted(oof[test]), _safe_indexing(X_arr, test), y[test])
                           for _, test in splits])
        name = f"mean of {len(top)}"
        self.candidate_scores_[name] = scores
        return name, scores, oof, CandidateMean([(n, candidates[n]) for n in top])


class LabelGroupKFold(BaseCrossValidator):
    """K-fold CV over groups of rows (scikit-learn's ``GroupKFold``), each row's group looked
    up by its label: ``groups`` maps the row labels of a whole dataset (a pandas Series) to
    their group, e.g. the device a row was measured on, and :meth:`split` takes the groups of
    the rows of ``X`` (a DataFrame) from its index. So an estimator holding this splitter
    makes grouped folds on any subset of the dataset it is fitted on (a training split, an
    outer fold), with no ``groups`` argument to route: rows of one group are never on both
    sides of a fold, as a test split of whole groups demands.

    Parameters
    ----------
    groups : pandas Series
        The group of each row label.
    n_splits : int, default=5
        The folds.
    shuffle, random_state :
        As in ``GroupKFold`` (shuffled groups before they are dealt into folds).
    """

    def __init__(self, groups: Any = None, n_splits: int = 5, *, shuffle: bool = False,
                 random_state: int | np.random.RandomState | None = None) -> None:
        self.groups = groups
        self.n_splits = n_splits
        self.shuffle = shuffle
        self.random_state = random_state

    def get_n_splits(self, X: Any = None, y: Any = None, groups: Any = None) -> int:
        """Return the number of folds.

        Parameters
        ----------
        X, y, groups : None
            Ignored.

        Returns
        -------
        int
            ``n_splits``.
        """
        return self.n_splits

    def split(self, X: Any, y: Any = None,
              groups: Any = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Yield the training and held-out positions of each fold.

        Parameters
        ----------
        X : pandas.DataFrame
            The rows, by the dataset's row labels.
        y : None
            Ignored.
        groups : None
            Ignored (the groups are the estimator's).

        Yields
        ------
        train, test : ndarray of int
            The fold's training and held-out positions.
        """
        if not hasattr(X, "index"):
            raise TypeError("LabelGroupKFold looks the rows' groups up by label: X must be a "
                            "DataFrame with the dataset's row labels")
        missing = X.index.difference(self.groups.index)
        if len(missing):
            raise ValueError(f"LabelGroupKFold: {len(missing)} row label(s) of X have no "
                             f"group, e.g. {missing[0]!r}")
        labels = self.groups.loc[X.index].to_numpy()
        n_groups = len(np.unique(labels))
        if n_groups < self.n_splits:
            raise ValueError(f"LabelGroupKFold: {n_groups} group(s) in these rows, fewer than "
                             f"the {self.n_splits} folds (each fold holds whole groups out)")
        folds = GroupKFold(self.n_splits, shuffle=self.shuffle,
                           random_state=self.random_state if self.shuffle else None)
        yield from folds.split(X, y, labels)

    def _iter_test_indices(self, X: Any = None, y: Any = None,
                           groups: Any = None) -> Iterator[np.ndarray]:  # split is overridden
        raise NotImplementedError


class LabelTimeSeriesSplit(BaseCrossValidator):
    """Forward-chaining folds (scikit-learn's ``TimeSeriesSplit``) over rows ordered by a
    value looked up by label: each fold trains on the rows earlier than its held-out rows.

    ``order`` maps the row labels of a whole dataset (a pandas Series) to a sortable value
    (a date, a time, a run number); :meth:`split` takes the values of the rows of ``X`` (a
    DataFrame) from its index, as :class:`LabelGroupKFold` takes their groups. The rows,
    sorted by their value, are cut as ``TimeSeriesSplit(n_splits)`` cuts them (held-out
    blocks of ``n_rows // (n_splits + 1)`` rows at the end, fold ``k`` training on every
    row before its block), except that each cut moves back to the first row of its value:
    rows with equal values are never on both sides of a fold. The first block is never
    held out (its rows have no out-of-fold prediction).

    Parameters
    ----------
    order : pandas Series
        The order value of each row label (numbers or datetimes; larger is later).
    n_splits : int, default=5
        The folds.
    """

    def __init__(self, order: Any = None, n_splits: int = 5) -> None:
        self.order = order
        self.n_splits = n_splits

    def get_n_splits(self, X: Any = None, y: Any = None, groups: Any = None) -> int:
        """Return the number of folds.

        Parameters
        ----------
        X, y, groups : None
            Ignored.

        Returns
        -------
        int
            ``n_splits``.
        """
        return self.n_splits

    def split(self, X: Any, y: Any = None,
              groups: Any = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Yield the training and held-out positions of each fold.

        Parameters
        ----------
        X : pandas.DataFrame
            The rows, by the dataset's row labels.
        y : None
            Ignored.
        groups : None
            Ignored (the order is the estimator's).

        Yields
        ------
        train, test : ndarray of int
            The fold's training and held-out positions.
        """
        if not hasattr(X, "index"):
            raise TypeError("LabelTimeSeriesSplit looks the rows' order up by label: X must "
                            "be a DataFrame with the dataset's row labels")
        missing = X.index.difference(self.order.index)
        if len(missing):
            raise ValueError(f"LabelTimeSeriesSplit: {len(missing)} row label(s) of X have "
                             f"no order value, e.g. {missing[0]!r}")
        yield from ordered_splits(self.order.loc[X.index].to_numpy(), self.n_splits)

    def _iter_test_indices(self, X: Any = None, y: Any = None,
                           groups: Any = None) -> Iterator[np.ndarray]:  # split is overridden
        raise NotImplementedError


def ordered_splits(values: Any, n_splits: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The positions of :class:`LabelTimeSeriesSplit`'s folds for rows of order ``values``.

    Parameters
    ----------
    values : array-like of shape (n_rows,)
        Each row's order value (numbers or datetimes), no missing value.
    n_splits : int
        The folds (at least 2).

    Returns
    -------
    list of (train, test) index arrays
        Positions into ``values``, each sorted; every training row's value is below every
        held-out row's.

    Raises
    ------
    ValueError
        For missing values, or rows too few (or values too few distinct) for the folds.
    """
    if int(n_splits) < 2:
        raise ValueError(f"n_splits must be at least 2, got {n_splits!r}")
    codes, uniques = pd.factorize(pd.Series(values), sort=True)
    if (codes < 0).any():
        raise ValueError(f"LabelTimeSeriesSplit: {int((codes < 0).sum())} row(s) without an "
                         "order value (NaN)")
    n, k = len(codes), int(n_splits)
    rows = np.argsort(codes, kind="stable")
    sorted_codes = codes[rows]
    size = n // (k + 1)
    cuts = [n - (k - i) * size for i in range(k)]
    # each cut back to the first row of its value: equal values stay on one side
    cuts = [int(np.searchsorted(sorted_codes, sorted_codes[c], "left")) if c < n else n
            for c in cuts] + [n]
    if size == 0 or cuts[0] == 0 or any(a >= b for a, b in zip(cuts, cuts[1:])):
        raise ValueError(f"LabelTimeSeriesSplit: {n} rows with {len(uniques)} distinct order "
                         f"value(s) cannot make {k} forward-chaining folds (each needs "
                         f"earlier rows to train on and later ones to hold out)")
    return [(np.sort(rows[:a]), np.sort(rows[a:b])) for a, b in zip(cuts, cuts[1:])]
