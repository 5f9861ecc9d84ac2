"""scikit-learn's estimator checks, one pytest test per check."""

from sklearn.linear_model import Ridge
from sklearn.tree import DecisionTreeRegressor
from sklearn.utils.estimator_checks import parametrize_with_checks

from workbench import (
    ARDGaussianProcess,
    BaseBoostCV,
    BaseBoostRegressor,
    ParametricBoostRegressor,
    ParametricModel,
    ParametricRegressor,
    PriorDerivedInputs,
    StageChoiceCV,
)

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


def _expected_failed(estimator):
    if isinstance(estimator, (ParametricRegressor, ParametricBoostRegressor)):
        return PARAMETRIC_FAILED
    return EXPECTED_FAILED


@parametrize_with_checks(
    [BaseBoostRegressor(), BaseBoostRegressor(n_stages=3, loss="absolute_error"),
     BaseBoostCV(BaseBoostRegressor(), cv=3), PriorDerivedInputs(),
     ARDGaussianProcess(max_rows=20, random_state=0),
     StageChoiceCV([("ridge", Ridge()), ("tree", DecisionTreeRegressor(max_depth=2))],
                   random_state=0),
     BaseBoostRegressor(n_stages=2, basis=StageChoiceCV(
         [("ridge", Ridge()), ("tree", DecisionTreeRegressor(max_depth=2))])),
     ParametricRegressor(LINE), ParametricBoostRegressor(LINE, candidates=None, cv=3)],
    expected_failed_checks=_expected_failed,
)
def test_sklearn_compatible(estimator, check):
    check(estimator)
