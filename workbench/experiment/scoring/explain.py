"""Exact SHAP values by enumerating every coalition, in a few batched model calls.

For a model ``f`` of ``M`` features, a row ``x`` and a background set ``B``, the
interventional value of a coalition ``S`` is ``v(S) = mean_b f(x_S, b_rest)`` and the SHAP
value of feature ``i`` is its Shapley value
``phi_i = sum_{S without i} |S|! (M - |S| - 1)! / M! * (v(S + i) - v(S))``. With ``M`` up to
about ten, all ``2^M`` coalitions are cheap to enumerate: ``shap.KernelExplainer`` finds the
same values at its default ``nsamples`` but calls the model once per row; here the model
sees every row's coalitions at once, so a model with a large fixed cost per call (a
1000-tree LightGBM in a stacking) is called a handful of times. :func:`shap_values` picks
the method (exact, or the kernel explainer for many features); exact values import neither
SHAP nor matplotlib (they run in worker processes too).

A per-target model predicts ``prior(X) + correction(X)``; :func:`target_shap_values` explains
the whole prediction (dominated by the prior) and the correction alone on the same rows over
the same background (exact values: the first is the prior's plus the second).
"""

from __future__ import annotations

from collections.abc import Callable
from math import factorial
from typing import Any, NamedTuple

import numpy as np
import pandas as pd
from sklearn.utils import shuffle

from ...boosting import BaseBoostRegressor, PriorModel, check_predictions

__all__ = ["MAX_EXACT_FEATURES", "MAX_MODEL_ROWS", "ShapValues", "TargetShap",
           "check_shap_frame", "correction_predictor", "correction_shap_values",
           "exact_shap_values", "model_columns", "prior_reason", "sample_background",
           "shap_sample", "shap_values", "target_shap_values"]

#: Up to this many features the values are exact (2^M coalitions per row).
MAX_EXACT_FEATURES = 10
#: The most rows a run's SHAP summary sends through the model (explained rows x 2^M
#: coalitions x background rows): about a second of a 300-tree LightGBM on one core.
MAX_MODEL_ROWS = 1_000_000
#: Fewest explained rows and background rows a summary keeps.
MIN_ROWS, MIN_BACKGROUND = 100, 10


def shap_sample(n_rows: int, n_features: int, background: int = 30) -> tuple[int, int]:
    """Rows and background rows of a SHAP summary within :data:`MAX_MODEL_ROWS` model rows.

    Every row and ``background`` background rows when they fit; else the background shrinks
    (to :data:`MIN_BACKGROUND`), then the explained rows (to :data:`MIN_ROWS`, a seeded
    sample): 1,650 rows of 10 features are summarised on 100 rows over a 10-row background.

    Parameters
    ----------
    n_rows, n_features : int
        Rows to summarise, and features explained (exact values up to ten, else 256 sampled
        coalitions per row).
    background : int, default=30
        Background rows wanted.

    Returns
    -------
    rows, background : int
        Rows to explain, and background rows to use.
    """
    # coalitions per row: all 2^M when exact, else the kernel explainer's 256 samples
    per_row = 2 ** n_features if n_features <= MAX_EXACT_FEATURES else 256
    bg = min(background, n_rows)
    if n_rows * per_row * bg > MAX_MODEL_ROWS:
        bg = min(bg, max(MIN_BACKGROUND, MAX_MODEL_ROWS // (n_rows * per_row)))
    rows = min(n_rows, max(MIN_ROWS, MAX_MODEL_ROWS // (per_row * bg)))
    return rows, bg


def sample_background(data: np.ndarray, size: int, random_state: int = 0) -> np.ndarray:
    """Draw ``size`` rows of ``data`` without replacement, as ``shap.sample`` does.

    Parameters
    ----------
    data : ndarray of shape (n_rows, n_features)
        The rows to draw from (all returned when there are no more than ``size``).
    size, random_state : int
        Rows wanted, and the seed (``shap.sample(data, size, random_state)``'s rows).

    Returns
    -------
    ndarray
    """
    if size >= len(data):
        return data
    return shuffle(data, n_samples=size, random_state=random_state)


def exact_shap_values(predict: Callable[[np.ndarray], np.ndarray], data: np.ndarray,
                      background: np.ndarray, *, chunk_rows: int = 250_000
                      ) -> tuple[np.ndarray, float]:
    """Compute exact interventional SHAP values by enumerating every coalition.

    Parameters
    ----------
    predict : callable
        The explained function; takes a 2-D float array of the columns of ``data``.
    data : ndarray of shape (n_rows, n_features)
        Rows to explain (at most :data:`MAX_EXACT_FEATURES` features).
    background : ndarray of shape (k, n_features)
        Background rows the absent features are drawn from.
    chunk_rows : int, default=250_000
        Rows of synthetic data per model call.

    Returns
    -------
    values : ndarray of shape (n_rows, n_features)
    expected : float
        ``mean f(background)``.

    Raises
    ------
    ValueError
        Too many features, or a background of another width.
    """
    data = np.asarray(data, dtype=float)
    background = np.asarray(background, dtype=float)
    n, m = data.shape
    if m > MAX_EXACT_FEATURES:
        raise ValueError(f"exact SHAP values enumerate 2^{m} coalitions per row; at most "
                         f"{MAX_EXACT_FEATURES} features")
    if background.ndim != 2 or background.shape[1] != m or len(background) == 0:
        raise ValueError(f"background must have shape (k, {m}), got {background.shape}")
    coalitions = (np.arange(2 ** m)[:, None] >> np.arange(m)) & 1  # (2^m, m) 0/1
    take = coalitions.astype(bool)[None, :, None, :]  # row x coalition x background x feature
    per_row = len(coalitions) * len(background)
    step = max(1, chunk_rows // per_row)
    values = np.empty((n, len(coalitions)))
    for start in range(0, n, step):
        x = data[start:start + step]
        synth = np.where(take, x[:, None, None, :], background[None, None, :, :])
        flat = synth.reshape(-1, m)
        f = check_predictions(predict(flat), len(flat), "predict")
        values[start:start + step] = f.reshape(len(x), len(coalitions),
                                               len(background)).mean(axis=2)
    size = coalitions.sum(axis=1)
    weight = np.array([factorial(s) * factorial(m - s - 1) / factorial(m) if s < m else 0.0
                       for s in size])
    phi = np.empty((n, m))
    for i in range(m):
        without = np.flatnonzero(coalitions[:, i] == 0)
        phi[:, i] = (values[:, without | (1 << i)] - values[:, without]) @ weight[without]
    return phi, float(values[0, 0])


def check_shap_frame(X: object) -> None:
    """Check that ``X`` is a non-empty DataFrame (its columns name the features).

    Raises
    ------
    TypeError
        ``X`` is not a DataFrame.
    ValueError
        ``X`` has no rows or no columns.
    """
    if not isinstance(X, pd.DataFrame):
        raise TypeError(f"X must be a pandas DataFrame (its columns name the features); got "
                        f"{type(X).__name__}")
    if len(X) == 0 or X.shape[1] == 0:
        raise ValueError(f"X is empty: shape {X.shape}")


def shap_values(predict: Callable[[np.ndarray], np.ndarray], X: pd.DataFrame, *,
                background_size: int = 50, nsamples: int | str = "auto",
                random_state: int = 0) -> tuple[np.ndarray, float]:
    """Compute SHAP values of ``predict`` on the rows of ``X``.

    Exact for ``nsamples="auto"`` and up to ten features (:func:`exact_shap_values`), else
    ``shap.KernelExplainer`` with ``nsamples``.

    Parameters
    ----------
    predict : callable
        The explained function of a 2-D float array of ``X``'s columns.
    X : DataFrame
        Rows to explain.
    background_size : int, default=50
        Rows of ``X`` sampled (with ``random_state``) as the background.
    nsamples : int or "auto", default="auto"
        Coalitions per row of the kernel explainer.
    random_state : int, default=0
        Seed of the background sample and the kernel explainer.

    Returns
    -------
    values : ndarray of shape (n_rows, n_features)
    expected : float
        The explained function's mean over the background.
    """
    check_shap_frame(X)
    data = X.to_numpy(dtype=float)
    background = sample_background(data, background_size, random_state)
    if nsamples == "auto" and data.shape[1] <= MAX_EXACT_FEATURES:
        return exact_shap_values(predict, data, background)
    import shap  # (b) SHAP: exact values (evaluate, sweep) do not need it

    # a lambda, never a bound method (shap 0.51 and scikit-learn 1.9 pipelines disagree)
    explainer = shap.KernelExplainer(lambda a: check_predictions(predict(a), len(a), "predict"),
                                     background, seed=random_state)
    values = np.asarray(explainer.shap_values(data, nsamples=nsamples, silent=True),
                        dtype=float)
    return values, float(np.ravel(explainer.expected_value)[0])


# ------------------------------------------------------------------ a per-target model


class ShapValues(NamedTuple):
    """SHAP values of one explained function.

    Attributes
    ----------
    values : ndarray of shape (n_rows, n_features)
    expected : float
        The explained function's mean over the background.
    rows : DataFrame
        The explained rows (columns: the features).
    """

    values: np.ndarray
    expected: float
    rows: pd.DataFrame


class TargetShap(NamedTuple):
    """A per-target model's SHAP values on the same rows over the same background.

    Attributes
    ----------
    prediction, correction : ShapValues or None
        Of the whole prediction, and of the correction (model - prior; ``None`` when the
        model is the prior).
    note : str
        Why the correction is ``None`` (empty otherwise).
    """

    prediction: ShapValues | None
    correction: ShapValues | None
    note: str = ""


def _fitted_model(estimator: Any) -> Any:
    """Return the fitted model a selection predicts with (``best_estimator_``), or itself."""
    return getattr(estimator, "best_estimator_", estimator)


def prior_reason(estimator: Any) -> str:
    """Say why a fitted per-target model (a BaseBoostCV, or the model it selected) is its prior.

    Parameters
    ----------
    estimator : estimator
        The fitted model.

    Returns
    -------
    str
        The prior was selected by CV, or every boosted stage's coefficient is 0; ``""`` when
        the model is not its prior exactly.
    """
    model = _fitted_model(estimator)
    if isinstance(model, PriorModel):
        return "cross-validation on the training rows selected the prior"
    if isinstance(model, BaseBoostRegressor) and not np.any(model.coefs_):
        return f"all {len(model.coefs_)} boosted stages have coefficient 0"
    return ""


def correction_predictor(estimator: Any) -> Callable[[pd.DataFrame], np.ndarray] | None:
    """Return the correction a fitted per-target model adds to its prior, as a function of ``X``.

    Parameters
    ----------
    estimator : estimator
        A BaseBoostCV or BasisChoiceCV (the model it selected), a BaseBoostRegressor, a
        PriorModel, or any regressor with ``predict_prior``.

    Returns
    -------
    callable or None
        ``X -> model(X) - prior(X)``; ``None`` when the model is the prior exactly.

    Raises
    ------
    TypeError
        The model's prior cannot be told apart.
    """
    model = _fitted_model(estimator)
    if prior_reason(model):
        return None
    if hasattr(model, "predict_correction"):
        return lambda X: model.predict_correction(X)
    if hasattr(model, "predict_prior"):
        return lambda X: (np.asarray(model.predict(X), dtype=float)
                          - np.asarray(model.predict_prior(X), dtype=float))
    raise TypeError(f"cannot tell the prior of a {type(model).__name__}: a per-target model is "
                    "a BaseBoostCV, a BaseBoostRegressor, a PriorModel, or has predict_prior")


def model_columns(estimator: Any, X: pd.DataFrame) -> list[str]:
    """List the columns of ``X`` a fitted per-target model reads.

    Parameters
    ----------
    estimator : estimator
        The fitted model.
    X : DataFrame
        The frame it was fitted on.

    Returns
    -------
    list of str
        Its basis inputs and its prior column (all of ``X``'s columns when it names none).
    """
    model = _fitted_model(estimator)
    names = list(X.columns)
    prior = getattr(model, "prior", None)
    cols = [names[i] for i in getattr(model, "basis_columns_", [])]
    if isinstance(prior, str) and prior not in cols:
        cols.append(prior)
    return cols or names


def target_shap_values(estimator: Any, X: pd.DataFrame, *, random_state: int = 0,
                       prediction: bool = True, correction: bool = True,
                       background: int = 30) -> TargetShap:
    """Compute SHAP values of a fitted per-target model's prediction and correction.

    Both on the rows of ``X`` over the columns the model reads (:func:`model_columns`; the
    others fixed at the first row's values), over the same background, so the two summaries
    are comparable; rows and background sized by :func:`shap_sample`. Exact values up to ten
    columns, else the kernel explainer with 256 coalitions per row.

    Parameters
    ----------
    estimator : estimator
        A fitted per-target model (see :func:`correction_predictor`).
    X : DataFrame
        Rows of the columns the model was fitted on.
    random_state : int, default=0
        Seed of the row sample, the background and the kernel explainer.
    prediction, correction : bool, default=True
        Which to compute (the other is ``None``).
    background : int, default=30
        Background rows wanted.

    Returns
    -------
    TargetShap
        The correction is ``None`` when the model is the prior, ``note`` then says why.
    """
    check_shap_frame(X)
    cols = model_columns(estimator, X)
    base = X.iloc[[0]].to_numpy()

    def on_columns(f: Callable[[pd.DataFrame], Any]) -> Callable[[np.ndarray], Any]:
        def predict(a: np.ndarray) -> Any:
            frame = pd.DataFrame(np.repeat(base, len(a), axis=0), columns=X.columns)
            frame[cols] = a
            return f(frame)
        return predict

    rows, size = shap_sample(len(X), len(cols), background)
    Xs = X[cols]
    if rows < len(Xs):
        keep = sample_background(np.arange(len(Xs)), rows, random_state)
        Xs = Xs.iloc[np.sort(keep)]
    nsamples: int | str = "auto" if len(cols) <= MAX_EXACT_FEATURES else 256

    def explain(f: Callable[[pd.DataFrame], Any]) -> ShapValues:
        values, expected = shap_values(on_columns(f), Xs, nsamples=nsamples,
                                       background_size=size, random_state=random_state)
        return ShapValues(values, expected, Xs)

    model = _fitted_model(estimator)
    whole = explain(lambda frame: model.predict(frame)) if prediction else None
    f = correction_predictor(model) if correction else None
    return TargetShap(whole, None if f is None else explain(f), prior_reason(model))


def correction_shap_values(estimator: Any, X: pd.DataFrame, *, random_state: int = 0,
                           background: int = 30) -> ShapValues | None:
    """Compute SHAP values of the correction (model - prior) of a fitted per-target model.

    Parameters
    ----------
    estimator, X, random_state, background
        As in :func:`target_shap_values`.

    Returns
    -------
    ShapValues or None
        ``None`` when the model is the prior (:func:`prior_reason` says why).
    """
    return target_shap_values(estimator, X, random_state=random_state, prediction=False,
                              background=background).correction
