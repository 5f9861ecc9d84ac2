"""Basis regressors by name, and the paper's stacking basis.

Every entry of :data:`BASES` is a small factory ``f(**params) -> regressor``. Another basis is
added with :func:`register_basis` or, from another package, through an entry point of the
group :data:`BASIS_ENTRY_POINT_GROUP` (``workbench.bases``), loaded when a name is not found
(:func:`discover_bases`). LightGBM models
are :class:`LeanLGBMRegressor` (LightGBM's own, without its post-training model copy), built
with ``n_jobs=1`` (the data are tiny, and on few cores its threads spin under contention when
folds, trials or targets run in parallel) and ``verbose=-1``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from numbers import Integral
from typing import Any, Self

import lightgbm.sklearn as _lgb_sklearn
import numpy as np
from lightgbm import LGBMRegressor
from lightgbm.engine import train as _lgb_train
from scipy import stats
from scipy.special import ndtri
from sklearn.base import BaseEstimator, RegressorMixin, TransformerMixin
from sklearn.ensemble import StackingRegressor
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
from sklearn.kernel_approximation import Nystroem
from sklearn.kernel_ridge import KernelRidge
from sklearn.linear_model import Ridge
from sklearn.neural_network import MLPRegressor
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.preprocessing import QuantileTransformer, SplineTransformer, StandardScaler
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import check_is_fitted

from ._plugins import load_entry_points
from .boosting import CachedParamNames
from .derived import PriorDerivedInputs
from .gp import ARDGaussianProcess
from .stagewise import StageChoiceCV

__all__ = [
    "BASES",
    "BASIS_ENTRY_POINT_GROUP",
    "KERNEL_EXACT_ROWS",
    "LeanLGBMRegressor",
    "PAPER_PARAMS",
    "ScalableKernelRidge",
    "TRANSFORMS",
    "NormalQuantileTransformer",
    "basis_names",
    "discover_bases",
    "make_basis",
    "make_transform",
    "paper_basis",
    "register_basis",
]

_KEEP = threading.local()
_PATCH = threading.Lock()


def _train(*args: Any, **kwargs: Any) -> Any:
    """``lightgbm.sklearn``'s ``train``: keeps the training booster inside
    :meth:`LeanLGBMRegressor.fit` (and records its dataset), LightGBM's own elsewhere."""
    if not getattr(_KEEP, "on", False):
        return _lgb_train(*args, **kwargs)
    _KEEP.train_set = kwargs.get("train_set", args[1] if len(args) > 1 else None)
    return _lgb_train(*args, **{**kwargs, "keep_training_booster": True})


class LeanLGBMRegressor(CachedParamNames, LGBMRegressor):
    """:class:`lightgbm.LGBMRegressor` without the copy of the model LightGBM makes after
    training (``keep_training_booster``): it writes the trees to text and parses them back
    (on this project's small data a third of a 1000-tree fit). The trees, and so every
    prediction, are the same; pickling still stores the model as LightGBM's text. The fitted
    model keeps its binned training set (the booster refers to it) until it is pickled.

    Parameters
    ----------
    boosting_type, num_leaves, max_depth, learning_rate, n_estimators, subsample_for_bin, \
objective, class_weight, min_split_gain, min_child_weight, min_child_samples, subsample, \
subsample_freq, colsample_bytree, reg_alpha, reg_lambda, random_state, n_jobs, \
importance_type, **kwargs
        As in :class:`lightgbm.LGBMRegressor`.
    """

    #: ``(id of the booster, its compiled trees)``, cached by :meth:`_numpy_trees`.
    _trees: tuple[int, list[_Tree] | None] | None

    def fit(self, X: Any, y: Any, *args: Any, **kwargs: Any) -> Self:
        """Fit as :meth:`lightgbm.LGBMRegressor.fit` does, keeping the trained booster.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : array-like of shape (n_samples,)
            The target.
        *args, **kwargs
            Passed to :meth:`lightgbm.LGBMRegressor.fit` (``sample_weight``, ...).

        Returns
        -------
        LeanLGBMRegressor
            The fitted model.
        """
        if _lgb_sklearn.train is not _train:
            with _PATCH:  # once per process; thread-safe: the flag is per thread
                _lgb_sklearn.train = _train
        _KEEP.on, _KEEP.train_set = True, None
        self._trees = None
        try:
            super().fit(X, y, *args, **kwargs)
        finally:
            _KEEP.on = False
        self._train_set = _KEEP.train_set
        _KEEP.train_set = None
        self._n_fit_rows = len(X)
        return self

    def _small_trees(self) -> bool:
        """Whether every tree has at most :data:`NUMPY_PREDICT_LEAVES` leaves: ``num_leaves``,
        or the most leaves ``min_child_samples`` allows on the rows it was fitted on."""
        rows = self.__dict__.get("_n_fit_rows")
        most = self.num_leaves if rows is None else \
            min(self.num_leaves, rows // max(1, self.min_child_samples))
        return most <= NUMPY_PREDICT_LEAVES

    def predict(self, X: Any, raw_score: bool = False, start_iteration: int = 0,
                num_iteration: int | None = None, pred_leaf: bool = False,
                pred_contrib: bool = False, validate_features: bool = False,
                **kwargs: Any) -> Any:
        """LightGBM's prediction. On many rows (at least :data:`NUMPY_PREDICT_ROWS`) of a
        regression whose output is the raw sum of small trees (:meth:`_small_trees`), the
        trees are evaluated with numpy, node by node over all rows at once, and summed in
        LightGBM's order: the same numbers, without LightGBM's per-row, per-tree traversal
        (on small trees the bulk of the time, e.g. for SHAP values; on larger trees every row
        through every node costs more than the traversal: 2.8x LightGBM's time for 600 trees
        of 63 leaves on 3,420 rows).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        raw_score, start_iteration, num_iteration, pred_leaf, pred_contrib, \
validate_features, **kwargs
            As in :meth:`lightgbm.LGBMRegressor.predict`.

        Returns
        -------
        ndarray
            The predictions, of shape (n_samples,) (other shapes for ``pred_leaf`` and
            ``pred_contrib``, as LightGBM's).
        """
        if (len(X) >= NUMPY_PREDICT_ROWS and self._small_trees()
                and not (raw_score or pred_leaf or pred_contrib or kwargs or validate_features)
                and start_iteration == 0 and num_iteration is None):
            trees = self._numpy_trees()
            values = None if trees is None else _finite_matrix(X, self.n_features_in_)
            if trees is not None and values is not None:
                return _sum_trees(trees, values)
        return super().predict(X, raw_score=raw_score, start_iteration=start_iteration,
                               num_iteration=num_iteration, pred_leaf=pred_leaf,
                               pred_contrib=pred_contrib, validate_features=validate_features,
                               **kwargs)

    def _numpy_trees(self) -> list[_Tree] | None:
        """The fitted trees as nested ``(feature, threshold, left, right)`` tuples (leaves:
        floats), or ``None`` where LightGBM's own prediction is needed."""
        booster = self.booster_
        key = id(booster)
        cached = self.__dict__.get("_trees")
        if cached is not None and cached[0] == key:
            return cached[1]
        model = booster.dump_model()
        objective = str(model.get("objective", "")).split()
        trees = None
        if (model.get("num_tree_per_iteration") == 1 and not model.get("average_output")
                and objective and objective[0] in _RAW_SUM_OBJECTIVES
                and "sqrt" not in objective and self._best_iteration in (0, None, -1)):
            try:
                trees = [_compile_tree(t["tree_structure"]) for t in model["tree_info"]]
            except _Unsupported:
                trees = None
        self._trees = (key, trees)
        return trees

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the training set and the compiled trees (made again on demand)."""
        state = super().__getstate__()
        state.pop("_train_set", None)  # the booster is stored as text without it
        state.pop("_trees", None)
        return state


#: From this many rows on, :meth:`LeanLGBMRegressor.predict` evaluates small trees with numpy.
NUMPY_PREDICT_ROWS = 2000
#: Trees of at most this many leaves are small enough for numpy (4 leaves: 2x faster than
#: LightGBM's traversal on 3,420 rows; 15 leaves: 1.5x slower).
NUMPY_PREDICT_LEAVES = 8
#: LightGBM regression objectives whose prediction is the raw sum of the trees.
_RAW_SUM_OBJECTIVES = {"regression", "regression_l1", "huber", "fair", "quantile", "mape"}


#: LightGBM's ``kZeroThreshold`` (``1e-35f``, a float): smaller magnitudes are read as zero.
_ZERO = float(np.float32(1e-35))


#: A compiled tree: a leaf value, or ``(feature, threshold, left, right)``.
_Tree = float | tuple[int, float, Any, Any]


class _Unsupported(Exception):
    pass


def _compile_tree(node: dict[str, Any]) -> _Tree:
    if "leaf_value" in node:
        if "leaf_coeff" in node:  # linear trees
            raise _Unsupported
        return float(node["leaf_value"])
    if node.get("decision_type") != "<=" or node.get("missing_type") not in ("None", None):
        raise _Unsupported  # categorical splits, missing-value handling
    return (int(node["split_feature"]), float(node["threshold"]),
            _compile_tree(node["left_child"]), _compile_tree(node["right_child"]))


def _finite_matrix(X: Any, n_features: int) -> np.ndarray | None:
    """``X`` as a float array of ``n_features`` finite columns (column-major), or ``None``."""
    try:
        values = np.asarray(X, dtype=float)
    except (TypeError, ValueError):
        return None
    if values.ndim != 2 or values.shape[1] != n_features or not np.isfinite(values).all():
        return None
    values = np.array(values, dtype=float, order="F")  # a copy: zeroed below
    values[np.abs(values) <= _ZERO] = 0.0  # LightGBM reads these as zero (kZeroThreshold)
    return values


def _tree_value(node: _Tree, X: np.ndarray) -> float | np.ndarray:
    if isinstance(node, float):
        return node
    feature, threshold, left, right = node
    return np.where(X[:, feature] <= threshold, _tree_value(left, X), _tree_value(right, X))


def _sum_trees(trees: list[_Tree], X: np.ndarray, chunk: int = 200_000) -> np.ndarray:
    out = np.zeros(len(X))
    for start in range(0, len(X), chunk):
        part, total = X[start:start + chunk], out[start:start + chunk]
        for tree in trees:  # LightGBM adds the trees one after another, from 0.0
            total += _tree_value(tree, part)
    return out


#: The paper's LightGBM settings shared by all targets (GOSS sampling, absolute-error objective).
PAPER_LGBM: dict[str, Any] = dict(
    objective="mae", boosting_type="gbdt", data_sample_strategy="goss", num_leaves=32,
    max_depth=20, learning_rate=0.2, reg_alpha=0.3, reg_lambda=0.3, max_bin=512,
    subsample_for_bin=200)

#: The paper's per-target stacking hyperparameters (scikit-physlearn's ``_paper_params.py``).
PAPER_PARAMS: dict[str, dict[str, Any]] = {
    "Y1": dict(mlp_hidden=(3,), mlp_alpha=17.0, mlp_max_iter=4390, lgbm_n_estimators=1060,
               final_hidden=(10,), final_alpha=15.0, final_max_iter=4070),
    "Y2": dict(mlp_hidden=(11,), mlp_alpha=15.0, mlp_max_iter=4440, lgbm_n_estimators=1100,
               final_hidden=(13,), final_alpha=15.0, final_max_iter=3700),
    "Y3": dict(mlp_hidden=(8,), mlp_alpha=5.0, mlp_max_iter=3500, lgbm_n_estimators=750,
               final_hidden=(8,), final_alpha=8.0, final_max_iter=2000),
    "Y4": dict(mlp_hidden=(10,), mlp_alpha=9.0, mlp_max_iter=4500, lgbm_n_estimators=380,
               final_hidden=(8,), final_alpha=10.0, final_max_iter=4250),
    "Y5": dict(mlp_hidden=(12,), mlp_alpha=8.0, mlp_max_iter=3450, lgbm_n_estimators=990,
               final_hidden=(7,), final_alpha=4.0, final_max_iter=3650),
}


def paper_stacking(*, mlp_hidden: Iterable[int] = (10,), mlp_alpha: float = 10.0,
                   mlp_max_iter: int = 4000, lgbm_n_estimators: int = 500,
                   final_hidden: Iterable[int] = (10,), final_alpha: float = 10.0,
                   final_max_iter: int = 4000, cv: Any = 5,
                   random_state: int | np.random.RandomState | None = None
                   ) -> StackingRegressor:
    """The paper's basis: stacking of [tanh L-BFGS MLP, LightGBM] -> tanh L-BFGS MLP.

    Parameters
    ----------
    mlp_hidden : iterable of int, default=(10,)
        The first MLP's hidden layer sizes.
    mlp_alpha : float, default=10.0
        The first MLP's L2 penalty.
    mlp_max_iter : int, default=4000
        The first MLP's L-BFGS iterations at most.
    lgbm_n_estimators : int, default=500
        The LightGBM member's boosting rounds (its other settings the paper's).
    final_hidden : iterable of int, default=(10,)
        The final MLP's hidden layer sizes.
    final_alpha : float, default=10.0
        The final MLP's L2 penalty.
    final_max_iter : int, default=4000
        The final MLP's L-BFGS iterations at most.
    cv : int or cross-validation generator, default=5
        The folds of the members' out-of-fold predictions the final MLP is fitted on.
    random_state : int, RandomState instance or None, default=None
        Seeds the three models.

    Returns
    -------
    StackingRegressor
        The unfitted basis (the inputs passed through to the final MLP too).
    """
    first = MLPRegressor(hidden_layer_sizes=tuple(mlp_hidden), activation="tanh",
                         solver="lbfgs", alpha=mlp_alpha, max_iter=mlp_max_iter,
                         random_state=random_state)
    lgbm = LeanLGBMRegressor(n_estimators=lgbm_n_estimators, n_jobs=1, verbose=-1,
                         random_state=random_state, **PAPER_LGBM)
    final = MLPRegressor(hidden_layer_sizes=tuple(final_hidden), activation="tanh",
                         solver="lbfgs", alpha=final_alpha, max_iter=final_max_iter,
                         random_state=random_state)
    return StackingRegressor(estimators=[("mlp", first), ("lgbm", lgbm)],
                             final_estimator=final, cv=cv, passthrough=True)


def paper_basis(target: str | int,
                random_state: int | np.random.RandomState | None = None) -> StackingRegressor:
    """The paper's stacking basis for one of the Google benchmark's targets.

    Parameters
    ----------
    target : str or int
        ``"Y1"`` to ``"Y5"``, or the position 0 to 4.
    random_state : int, RandomState instance or None, default=None
        Seeds the stacking's estimators.

    Returns
    -------
    StackingRegressor
        The unfitted basis.

    Raises
    ------
    ValueError
        An unknown target.
    """
    key = f"Y{target + 1}" if isinstance(target, int) else target
    if key not in PAPER_PARAMS:
        raise ValueError(f"unknown paper target {target!r}; valid: {', '.join(PAPER_PARAMS)}")
    return paper_stacking(**PAPER_PARAMS[key], random_state=random_state)


def ridge(**params: Any) -> Ridge:
    """A ridge regression basis (scikit-learn's ``Ridge``).

    Parameters
    ----------
    **params
        ``Ridge``'s parameters (e.g. ``alpha``).

    Returns
    -------
    Ridge
        The unfitted basis.
    """
    return Ridge(**params)


#: Above this many training rows a ``kernel_ridge`` basis fits Nystroem features instead
#: of the exact kernel (O(rows^2) memory, O(rows^3) time: 171 s and 1.5 GB at 10,000 rows).
KERNEL_EXACT_ROWS = 3000
#: A Gaussian process basis on more training rows than this is warned about before fitting.
GP_WARN_ROWS = 2000


class ScalableKernelRidge(CachedParamNames, RegressorMixin, BaseEstimator):
    """Kernel ridge regression that stays linear in rows: the exact
    :class:`~sklearn.kernel_ridge.KernelRidge` up to ``exact_max_rows`` training rows, above
    that ridge regression (same ``alpha``, no intercept, as kernel ridge) on
    ``n_components`` :class:`~sklearn.kernel_approximation.Nystroem` features of the same
    kernel: the kernel matrix is approximated by rank ``n_components``, O(rows x
    n_components^2) time and O(rows x n_components) memory.

    Parameters
    ----------
    alpha : float, default=1.0
        The ridge penalty.
    kernel, gamma, degree, coef0, kernel_params
        The kernel, as in :class:`~sklearn.kernel_ridge.KernelRidge` (default ``"rbf"``).
    exact_max_rows : int, default=3000
        The most training rows fitted by the exact kernel ridge.
    n_components : int, default=300
        The Nystroem features above that.
    random_state : int, RandomState instance or None, default=None
        Seeds the Nystroem features' rows.

    Attributes
    ----------
    estimator_ : KernelRidge or Pipeline
        The fitted kernel ridge, or the Nystroem + ridge pipeline.
    approximate_ : bool
        Whether the Nystroem features were used.
    """

    _parameter_constraints = {
        **KernelRidge._parameter_constraints,
        "exact_max_rows": [Interval(Integral, 1, None, closed="left")],
        "n_components": [Interval(Integral, 1, None, closed="left")],
        "random_state": ["random_state"],
    }

    def __init__(self, alpha: float = 1.0, *, kernel: str | Callable = "rbf",
                 gamma: float | None = None, degree: float = 3, coef0: float = 1,
                 kernel_params: dict[str, Any] | None = None,
                 exact_max_rows: int = KERNEL_EXACT_ROWS, n_components: int = 300,
                 random_state: int | np.random.RandomState | None = None) -> None:
        self.alpha = alpha
        self.kernel = kernel
        self.gamma = gamma
        self.degree = degree
        self.coef0 = coef0
        self.kernel_params = kernel_params
        self.exact_max_rows = exact_max_rows
        self.n_components = n_components
        self.random_state = random_state

    def fit(self, X: Any, y: Any) -> Self:
        """Fit the exact kernel ridge, or Nystroem features and a ridge above ``exact_max_rows``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : array-like of shape (n_samples,)
            The target.

        Returns
        -------
        self
            The fitted model.
        """
        self._validate_params()
        kernel = dict(kernel=self.kernel, gamma=self.gamma, degree=self.degree,
                      coef0=self.coef0, kernel_params=self.kernel_params)
        self.approximate_ = len(X) > self.exact_max_rows
        if self.approximate_:
            self.estimator_ = make_pipeline(
                Nystroem(**kernel, n_components=min(self.n_components, len(X)),
                         random_state=self.random_state),
                Ridge(alpha=self.alpha, fit_intercept=False))
        else:
            self.estimator_ = KernelRidge(alpha=self.alpha, **kernel)
        self.estimator_.fit(X, y)
        self.n_features_in_ = getattr(self.estimator_, "n_features_in_", np.shape(X)[1])
        return self

    def predict(self, X: Any) -> Any:
        """Predict with the fitted model.

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
        return self.estimator_.predict(X)


def kernel_ridge(**params: Any) -> ScalableKernelRidge:
    """An RBF kernel ridge basis.

    :class:`ScalableKernelRidge`: exact up to :data:`KERNEL_EXACT_ROWS` training rows,
    Nystroem features above.

    Parameters
    ----------
    **params
        :class:`ScalableKernelRidge`'s parameters (the kernel ``"rbf"`` unless given).

    Returns
    -------
    ScalableKernelRidge
        The unfitted basis.
    """
    return ScalableKernelRidge(**{"kernel": "rbf", **params})


def quadratic_basis_warning(name: str, n_rows: int) -> str | None:
    """Warn of a basis whose cost grows faster than linearly in rows.

    Parameters
    ----------
    name : str
        The basis's name.
    n_rows : int
        The training rows it is to be fitted on.

    Returns
    -------
    str or None
        The warning, naming the bases that scale linearly; ``None`` when there is nothing
        to say.
    """
    if name == "gaussian_process" and n_rows > GP_WARN_ROWS:
        return (f"basis gaussian_process on {n_rows:,} training rows: its fit is cubic in rows "
                f"and its memory quadratic (it will be slow above ~{GP_WARN_ROWS:,} rows); "
                "kernel_ridge (Nystroem features above "
                f"{KERNEL_EXACT_ROWS:,} rows), ridge or lightgbm scale linearly")
    return None


def lightgbm(**params: Any) -> LeanLGBMRegressor:
    """A LightGBM basis (:class:`LeanLGBMRegressor`), one thread and quiet unless given.

    Parameters
    ----------
    **params
        LightGBM's parameters (e.g. ``n_estimators``, ``num_leaves``).

    Returns
    -------
    LeanLGBMRegressor
        The unfitted basis.
    """
    return LeanLGBMRegressor(**{"n_jobs": 1, "verbose": -1, **params})


def mlp(**params: Any) -> MLPRegressor:
    """An MLP basis (tanh, L-BFGS by default).

    Parameters
    ----------
    **params
        ``MLPRegressor``'s parameters; an int ``hidden_layer_sizes`` is one layer.

    Returns
    -------
    MLPRegressor
        The unfitted basis.
    """
    if "hidden_layer_sizes" in params:
        sizes = params["hidden_layer_sizes"]
        params["hidden_layer_sizes"] = (sizes,) if isinstance(sizes, int) else tuple(sizes)
    return MLPRegressor(**{"activation": "tanh", "solver": "lbfgs", "max_iter": 2000, **params})


def gaussian_process(*, length_scale: float = 1.0, noise_level: float = 1.0,
                     **params: Any) -> GaussianProcessRegressor:
    """A Gaussian process basis: a scaled RBF kernel plus white noise, targets normalised.

    Parameters
    ----------
    length_scale : float, default=1.0
        The RBF kernel's starting length scale (one for every input).
    noise_level : float, default=1.0
        The white noise's starting level.
    **params
        ``GaussianProcessRegressor``'s parameters.

    Returns
    -------
    GaussianProcessRegressor
        The unfitted basis (its fit cubic in rows: :func:`quadratic_basis_warning`).
    """
    kernel = ConstantKernel() * RBF(length_scale=length_scale) + WhiteKernel(noise_level)
    return GaussianProcessRegressor(**{"kernel": kernel, "normalize_y": True, **params})


def gp_ard(**params: Any) -> ARDGaussianProcess:
    """A Gaussian process with one length scale per input, fitted by marginal likelihood.

    Smooth, with the inputs that matter found by the fit.

    Parameters
    ----------
    **params
        :class:`~workbench.gp.ARDGaussianProcess`'s parameters (it fits on at most
        ``max_rows``, default 1,000, rows).

    Returns
    -------
    ARDGaussianProcess
        The unfitted basis.
    """
    return ARDGaussianProcess(**params)


def spline(*, n_knots: int = 5, degree: int = 3, knots: Any = "quantile",
           alpha: float = 1.0) -> Pipeline:
    """An additive spline basis: each input's B-splines and a ridge on them.

    Smooth in every input and linear beyond the training range (``extrapolation="linear"``),
    where trees stay flat: a basis for a correction that must carry on past the rows it was
    fitted on (later dates, other devices). Linear in rows.

    Parameters
    ----------
    n_knots : int, default=5
        Knots per input (``SplineTransformer``'s).
    degree : int, default=3
        The splines' degree.
    knots : {"uniform", "quantile"} or array-like, default="quantile"
        Where the knots are: at the inputs' quantiles by default.
    alpha : float, default=1.0
        The ridge's penalty.

    Returns
    -------
    Pipeline
        The unfitted basis: ``SplineTransformer`` then ``Ridge``.
    """
    return Pipeline([("splines", SplineTransformer(n_knots=n_knots, degree=degree, knots=knots,
                                                   extrapolation="linear")),
                     ("ridge", Ridge(alpha=alpha))])


def stagewise(*, candidates: Iterable[str] = ("ridge", "spline", "lightgbm"), cv: int = 3,
              **nested: Any) -> StageChoiceCV:
    """Heterogeneous stages: each stage's basis chosen by CV among ``candidates``.

    A :class:`~workbench.stagewise.StageChoiceCV` chooses each stage's basis by ``cv``-fold
    CV on that stage's own residuals (with ``n_stages`` > 1: e.g. a ridge or spline stage for
    a smooth trend, then trees for what is left).

    Parameters
    ----------
    candidates : iterable of str, default=("ridge", "spline", "lightgbm")
        Names of :data:`BASES`, each with its defaults; not ``"stagewise"``.
    cv : int, default=3
        The folds of each stage's choice.
    **nested
        A candidate's parameters as ``<name>__<param>``, as in a Pipeline (e.g.
        ``lightgbm__num_leaves = 15``; ranges there are drawn like any basis's).

    Returns
    -------
    StageChoiceCV
        The unfitted basis.

    Raises
    ------
    ValueError
        When ``"stagewise"`` is among the candidates.
    """
    names = list(candidates)
    if "stagewise" in names:
        raise ValueError("stagewise: a candidate cannot be stagewise itself")
    chooser = StageChoiceCV([(name, make_basis(name)) for name in names], cv=cv)
    return chooser.set_params(**nested) if nested else chooser


#: Basis factories by name.
BASES: dict[str, Callable[..., Any]] = {
    "paper_stacking": paper_stacking,
    "ridge": ridge,
    "kernel_ridge": kernel_ridge,
    "lightgbm": lightgbm,
    "mlp": mlp,
    "gaussian_process": gaussian_process,
    "gp_ard": gp_ard,
    "spline": spline,
    "stagewise": stagewise,
}


#: The entry-point group other packages add bases through: each entry point names a factory
#: ``f(**params) -> regressor`` (an estimator class is one), registered under its own name.
BASIS_ENTRY_POINT_GROUP = "workbench.bases"

_discovered: set[str] = set()


def register_basis(name: str, factory: Callable[..., Any]) -> Callable[..., Any]:
    """Add the basis factory ``factory`` to :data:`BASES` under ``name``.

    Parameters
    ----------
    name : str
        The basis's name (``[model] basis``); an identifier, as it also names
        ``[search.basis_params.<name>]`` tables.
    factory : callable
        ``factory(**params) -> regressor``: a scikit-learn regressor (an estimator class is
        a factory too).

    Returns
    -------
    callable
        ``factory``.

    Raises
    ------
    ValueError
        For a name that is not an identifier.
    TypeError
        For a factory that cannot be called.
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"a basis needs an identifier as its name, got {name!r}")
    if not callable(factory):
        raise TypeError(f"basis {name!r}: the factory must be callable, got {factory!r}")
    BASES[name] = factory
    return factory


def discover_bases() -> list[str]:
    """Register the bases other packages declare as entry points, each once.

    The group is :data:`BASIS_ENTRY_POINT_GROUP`. One that cannot be loaded is reported in
    one warning line naming it and left out.

    Returns
    -------
    list of str
        The names registered by this call.
    """
    def register(name: str, factory: Any) -> str:
        register_basis(name, factory)
        return name

    return load_entry_points(BASIS_ENTRY_POINT_GROUP, register, _discovered)


def basis_names() -> list[str]:
    """The valid basis names, plug-ins included (sorted).

    Returns
    -------
    list of str
        The keys of :data:`BASES` after :func:`discover_bases`.
    """
    discover_bases()
    return sorted(BASES)


def make_basis(name: str, **params: Any) -> Any:
    """Build the basis ``name`` of :data:`BASES` with ``params``.

    A name not registered yet is looked up among the entry points first
    (:func:`discover_bases`).

    Parameters
    ----------
    name : str
        A key of :data:`BASES`.
    **params
        The basis's parameters.

    Returns
    -------
    estimator
        The basis regressor.

    Raises
    ------
    ValueError
        For an unknown name (the message lists the valid ones)."""
    if name not in BASES and name not in basis_names():
        raise ValueError(f"unknown basis {name!r}; valid names are: {', '.join(sorted(BASES))}")
    return BASES[name](**params)


class _NormalQuantiles(CachedParamNames, QuantileTransformer):
    """scikit-learn's ``QuantileTransformer`` whose forward normal mapping calls
    ``scipy.special.ndtri`` itself instead of ``scipy.stats.norm.ppf`` (the same function
    behind ``stats``' argument checks, which cost ~0.25 ms a call, three calls a column):
    the same numbers, ``_transform_col`` otherwise as scikit-learn 1.9 writes it (a test
    compares the two)."""

    def _transform_col(self, X_col: np.ndarray, quantiles: np.ndarray,
                       inverse: bool) -> np.ndarray:
        if inverse or self.output_distribution != "normal":
            return super()._transform_col(X_col, quantiles, inverse)
        with np.errstate(invalid="ignore"):  # hide NaN comparison warnings
            lower_bounds_idx = X_col - _BOUNDS < quantiles[0]
            upper_bounds_idx = X_col + _BOUNDS > quantiles[-1]
        isfinite_mask = ~np.isnan(X_col)
        X_col_finite = X_col[isfinite_mask]
        # both directions, averaged (repeated quantiles), as scikit-learn does
        X_col[isfinite_mask] = 0.5 * (
            np.interp(X_col_finite, quantiles, self.references_)
            - np.interp(-X_col_finite, -quantiles[::-1], -self.references_[::-1]))
        X_col[upper_bounds_idx] = 1
        X_col[lower_bounds_idx] = 0
        with np.errstate(invalid="ignore"):
            return np.clip(_norm_ppf(X_col), *_CLIP)


def _norm_ppf(q: np.ndarray) -> np.ndarray:
    """``scipy.stats.norm.ppf(q)`` for a float array: ``ndtri`` inside (0, 1), the infinite
    ends at 0 and 1, NaN elsewhere."""
    q = np.asarray(q, dtype=float)
    out = np.full(q.shape, np.nan)
    out[q == 0] = -np.inf
    out[q == 1] = np.inf
    inside = (0 < q) & (q < 1)
    out[inside] = ndtri(q[inside]) * 1.0 + 0.0  # scale and loc, as stats applies them
    return out


def _clip_bounds() -> tuple[float, float]:
    low = _BOUNDS - np.spacing(1)
    return float(stats.norm.ppf(low)), float(stats.norm.ppf(1 - low))


try:  # scikit-learn's margin for the ends of the quantile range
    from sklearn.preprocessing._data import BOUNDS_THRESHOLD as _BOUNDS
except ImportError:  # pragma: no cover
    _BOUNDS = 1e-7
_CLIP = _clip_bounds()


class NormalQuantileTransformer(CachedParamNames, TransformerMixin, BaseEstimator):
    """``QuantileTransformer(output_distribution="normal")`` with ``n_quantiles`` capped at
    the number of rows, so small training sets fit without a warning (and its normal
    mapping without ``scipy.stats``' per-call overhead; the same numbers).

    Parameters
    ----------
    n_quantiles : int, default=1000
        Quantiles of the mapping, at most the number of training rows.
    subsample, random_state
        As in :class:`~sklearn.preprocessing.QuantileTransformer`.
    """

    def __init__(self, *, n_quantiles: int = 1000, subsample: int = 10_000,
                 random_state: int | np.random.RandomState | None = None) -> None:
        self.n_quantiles = n_quantiles
        self.subsample = subsample
        self.random_state = random_state

    def fit(self, X: Any, y: Any = None) -> Self:
        """Fit the quantiles of each column, at most one per row.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.
        y : None
            Ignored.

        Returns
        -------
        self
            The fitted transformer.
        """
        n_rows = len(X)
        self.transformer_ = _NormalQuantiles(
            n_quantiles=max(1, min(self.n_quantiles, n_rows)), output_distribution="normal",
            subsample=self.subsample, random_state=self.random_state).fit(X)
        self.n_features_in_ = self.transformer_.n_features_in_
        return self

    def transform(self, X: Any) -> np.ndarray:
        """Map each column to a standard normal through its fitted quantiles.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            The inputs.

        Returns
        -------
        ndarray of shape (n_samples, n_features)
            The transformed inputs.
        """
        check_is_fitted(self)
        return self.transformer_.transform(X)


def derived(*, n_priors: int = 1, kinds: list[str] | None = None) -> PriorDerivedInputs:
    """The basis inputs with physics-derived columns appended, then standardised.

    The priors' differences, ratios and logs, prior x feature products
    (:class:`~workbench.derived.PriorDerivedInputs`): an input transform.

    Parameters
    ----------
    n_priors : int, default=1
        The leading prior columns of the inputs (set by the experiment layer from the basis
        inputs it builds).
    kinds : list of str, default=None
        Which derived columns, as :class:`~workbench.derived.PriorDerivedInputs` takes them
        (``None``: all four kinds).

    Returns
    -------
    PriorDerivedInputs
        The unfitted transform, a ``StandardScaler`` after it.
    """
    return PriorDerivedInputs(n_priors=n_priors, kinds=kinds, then=StandardScaler())


#: Basis-input transforms by name.
TRANSFORMS: dict[str, Callable[..., Any]] = {
    "derived": derived,
    "quantile_normal": NormalQuantileTransformer,
    "standard": StandardScaler,
}


def make_transform(name: str | None, **params: Any) -> Any:
    """Build the input transform ``name`` of :data:`TRANSFORMS` (``None``/"none": no transform).

    Parameters
    ----------
    name : str or None
        A key of :data:`TRANSFORMS`; ``None`` or ``"none"``: no transform.
    **params
        The transform's parameters.

    Returns
    -------
    transformer or None
        The unfitted transform; ``None`` for no transform.

    Raises
    ------
    ValueError
        An unknown name, listing the valid ones.
    """
    if name is None or name == "none":
        return None
    if name not in TRANSFORMS:
        raise ValueError(f"unknown input transform {name!r}; valid names are: "
                         f"{', '.join(['none', *sorted(TRANSFORMS)])}")
    return TRANSFORMS[name](**params)
