"""scikit-learn's estimator checks, one pytest test per check; the core's parameters by keyword."""

import importlib
import inspect
import pkgutil

from sklearn.base import BaseEstimator
from sklearn.linear_model import Ridge
from sklearn.tree import DecisionTreeRegressor
from sklearn.utils.estimator_checks import parametrize_with_checks

import workbench
from workbench import (
    ARDGaussianProcess,
    BaseBoostCV,
    BaseBoostRegressor,
    HalvingChoiceCV,
    ParametricBoostRegressor,
    ParametricModel,
    ParametricRegressor,
    PriorDerivedInputs,
    StageChoiceCV,
)
from workbench.parametric_gbm import ParameterSpaceBoostRegressor
from workbench.selection import BasisChoiceCV

# Expected failures, each with its reason (empty: every check passes).
EXPECTED_FAILED: dict[str, str] = {}


def _line(params, data):
    """A user's model: a line in the first column (module level: the checks pickle it)."""
    return params["a"] + params["b"] * data.iloc[:, 0].to_numpy()


LINE = ParametricModel.from_functions({"a": 0.0, "b": 1.0}, _line, source="line")
#: The parametric regressors fit the user's model, here a line in the first feature only.
PARAMETRIC_FAILED = {"check_regressors_train": "the user's model (a line in the first "
                     "feature) cannot fit the check's data, whatever its parameters",
                     "check_regressor_multioutput": "the user's model predicts one target; "
                     "a y of several is a model of the wrong shape"}


#: Boosting the line's parameters with trees of the features fits the check's data.
BOOST_FAILED = {"check_regressor_multioutput": PARAMETRIC_FAILED["check_regressor_multioutput"]}


def _expected_failed(estimator):
    if isinstance(estimator, ParameterSpaceBoostRegressor) or getattr(estimator, "boost", None):
        return BOOST_FAILED
    if getattr(estimator, "candidates", None) is not None:  # a drift of the line in x0 fits
        return BOOST_FAILED
    if isinstance(estimator, (ParametricRegressor, ParametricBoostRegressor)):
        return PARAMETRIC_FAILED
    return EXPECTED_FAILED


@parametrize_with_checks(
    [BaseBoostRegressor(), BaseBoostRegressor(n_stages=3, loss="absolute_error"),
     BaseBoostCV(BaseBoostRegressor(), cv=3),
     BaseBoostCV(BaseBoostRegressor(), cv=3, rule="one_se"),
     BasisChoiceCV([("one", BaseBoostRegressor()), ("two", BaseBoostRegressor(n_stages=2))],
                   cv=3, ensemble=2, rule="one_se"), PriorDerivedInputs(),
     ARDGaussianProcess(max_rows=20, random_state=0),
     StageChoiceCV([("ridge", Ridge()), ("tree", DecisionTreeRegressor(max_depth=2))],
                   random_state=0),
     BaseBoostRegressor(n_stages=2, basis=StageChoiceCV(
         [("ridge", Ridge()), ("tree", DecisionTreeRegressor(max_depth=2))])),
     HalvingChoiceCV([(f"tree{d}", DecisionTreeRegressor(max_depth=d)) for d in (1, 2, 3)],
                     random_state=0),
     ParametricRegressor(model=LINE), ParametricBoostRegressor(model=LINE, candidates=None, cv=3),
     # boosting in parameter space, alone and as the choice's "boost" candidate (tiny: 3 rounds)
     ParameterSpaceBoostRegressor(model=LINE, n_estimators=3, random_state=0),
     # the extrapolation guard: the calibrated model's parameters beyond the training box
     ParametricBoostRegressor(model=LINE, cv=3, squares=False, products=False, max_steps=1,
                              out_of_bounds="calibrated"),
     ParameterSpaceBoostRegressor(model=LINE, n_estimators=3, out_of_bounds="calibrated",
                                  random_state=0),
     ParametricBoostRegressor(model=LINE, candidates=None, cv=3, boost=ParameterSpaceBoostRegressor(
         n_estimators=3, estimator=DecisionTreeRegressor(max_depth=2)))],
    expected_failed_checks=_expected_failed,
)
def test_sklearn_compatible(estimator, check):
    check(estimator)


#: The parameters a core estimator may take by position: what it wraps, first (as
#: scikit-learn's meta-estimators take ``estimator`` and ``StackingRegressor`` its
#: ``estimators``), and ``alpha`` where it mirrors ``KernelRidge(alpha, *, ...)``.
WRAPPED = {"estimator", "estimators", "candidates", "members", "regressor", "physics", "boost",
           "alpha"}


def _core_estimators():
    found = {}
    for info in pkgutil.iter_modules(workbench.__path__):
        if info.name == "experiment" or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"workbench.{info.name}")
        for name, cls in inspect.getmembers(module, inspect.isclass):
            if (cls.__module__ == module.__name__ and not name.startswith("_")
                    and issubclass(cls, BaseEstimator)):
                found[f"{info.name}.{name}"] = cls
    return found


def test_core_estimators_take_their_hyperparameters_by_keyword():
    """As scikit-learn's estimators do since 1.0: ``Est(*, param=...)``, only what an
    estimator wraps may come first by position."""
    estimators = _core_estimators()
    assert {"boosting.BaseBoostRegressor", "selection.BaseBoostCV", "derived.PriorDerivedInputs",
            "bases.NormalQuantileTransformer"} <= set(estimators)  # it sees the core
    positional = {}
    for name, cls in estimators.items():
        params = list(inspect.signature(cls.__init__).parameters.values())[1:]
        by_position = [p.name for p in params
                       if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
        if set(by_position) - WRAPPED:
            positional[name] = by_position
    assert positional == {}
    assert "prior" not in [p.name for p in inspect.signature(
        BaseBoostRegressor.__init__).parameters.values() if p.kind == p.POSITIONAL_OR_KEYWORD]
