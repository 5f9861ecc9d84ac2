"""scikit-learn's estimator checks, one pytest test per check."""

from sklearn.utils.estimator_checks import parametrize_with_checks

from workbench import ARDGaussianProcess, BaseBoostCV, BaseBoostRegressor, PriorDerivedInputs

# Expected failures, each with its reason (empty: every check passes).
EXPECTED_FAILED: dict[str, str] = {}


@parametrize_with_checks(
    [BaseBoostRegressor(), BaseBoostRegressor(n_stages=3, loss="absolute_error"),
     BaseBoostCV(BaseBoostRegressor(), cv=3), PriorDerivedInputs(),
     ARDGaussianProcess(max_rows=20, random_state=0)],
    expected_failed_checks=lambda est: EXPECTED_FAILED,
)
def test_sklearn_compatible(estimator, check):
    check(estimator)
