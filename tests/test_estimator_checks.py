"""scikit-learn's estimator checks, one pytest test per check."""

from sklearn.linear_model import Ridge
from sklearn.tree import DecisionTreeRegressor
from sklearn.utils.estimator_checks import parametrize_with_checks

from workbench import (
    ARDGaussianProcess,
    BaseBoostCV,
    BaseBoostRegressor,
    PriorDerivedInputs,
    StageChoiceCV,
)
from workbench.selection import BasisChoiceCV

# Expected failures, each with its reason (empty: every check passes).
EXPECTED_FAILED: dict[str, str] = {}


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
         [("ridge", Ridge()), ("tree", DecisionTreeRegressor(max_depth=2))]))],
    expected_failed_checks=lambda est: EXPECTED_FAILED,
)
def test_sklearn_compatible(estimator, check):
    check(estimator)
