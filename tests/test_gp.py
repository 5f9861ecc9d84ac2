"""ARDGaussianProcess: per-input length scales by marginal likelihood, bounded rows."""

import numpy as np
import pytest

from workbench import ARDGaussianProcess, make_basis


def test_irrelevant_input_gets_a_long_length_scale():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(80, 2))
    y = np.sin(2 * X[:, 0]) + 0.05 * rng.normal(size=80)
    gp = ARDGaussianProcess(random_state=0).fit(X, y)
    relevant, irrelevant = gp.length_scales_
    assert irrelevant > 10 * relevant
    assert np.mean(np.abs(gp.predict(X) - np.sin(2 * X[:, 0]))) < 0.1
    assert not gp.subsampled_


def test_rows_bounded_and_seeded():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(300, 3))
    y = X[:, 0] + 0.1 * rng.normal(size=300)
    a = ARDGaussianProcess(max_rows=50, random_state=3).fit(X, y)
    b = ARDGaussianProcess(max_rows=50, random_state=3).fit(X, y)
    assert a.subsampled_ and a.estimator_.X_train_.shape == (50, 3)
    np.testing.assert_array_equal(a.predict(X), b.predict(X))


def test_registry_and_bad_parameter():
    assert isinstance(make_basis("gp_ard", max_rows=10), ARDGaussianProcess)
    with pytest.raises(ValueError, match="max_rows"):
        ARDGaussianProcess(max_rows=1).fit(np.zeros((5, 1)), np.zeros(5))
