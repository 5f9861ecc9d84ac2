"""Losses (values, gradients, registry) and the exact line search against a brute-force grid."""

import numpy as np
import pytest

from workbench.line_search import line_search
from workbench.losses import LOSSES, Huber, Quantile, get_loss

NAMES = sorted(LOSSES)


def test_unknown_loss_lists_valid_names():
    with pytest.raises(ValueError, match=r"unknown loss 'lad'.*absolute_error, huber, quantile, "
                                         r"squared_error"):
        get_loss("lad")


@pytest.mark.parametrize("name", NAMES)
def test_negative_gradient_is_minus_derivative(name):
    rng = np.random.default_rng(1)
    y = rng.normal(size=50)
    pred = rng.normal(size=50)
    loss = get_loss(name, alpha=0.7)
    bound = loss.bind(y - pred)  # fix Huber's delta so the loss is one function of pred
    eps = 1e-6
    grad = loss.negative_gradient(y, pred)
    for i in range(0, 50, 7):
        up, down = pred.copy(), pred.copy()
        up[i] += eps
        down[i] -= eps
        numeric = -(bound(y, up) - bound(y, down)) / (2 * eps) * len(y)
        scale = 2.0 if name == "squared_error" else 1.0  # mean(u^2) has derivative 2u; psi = u
        assert grad[i] * scale == pytest.approx(numeric, abs=1e-4)


def test_huber_delta_is_quantile_of_abs_residual():
    u = np.arange(1, 101, dtype=float)
    assert Huber(quantile=0.9).bind(u).delta == pytest.approx(np.quantile(u, 0.9))
    assert np.all(np.abs(Huber().negative_gradient(u, 0 * u)) <= np.quantile(u, 0.9) + 1e-12)


def test_loss_parameter_validation():
    with pytest.raises(ValueError, match="quantile alpha must be in"):
        Quantile(alpha=1.5)
    with pytest.raises(ValueError, match="huber quantile must be in"):
        Huber(quantile=0.0)


def _objective(name, y, F, b, penalty, alpha=0.9):
    """The line objective, vectorised over an array of coefficients."""
    loss = get_loss(name, alpha=alpha).bind(y - F)

    def f(a):
        a = np.asarray(a, dtype=float)[..., None]
        return np.mean(loss.elementwise(y - F - a * b), axis=-1) + penalty * np.abs(a[..., 0])

    return f


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("penalty", [0.0, 0.1, 2.0])
def test_line_search_matches_grid(name, penalty):
    rng = np.random.default_rng(hash((name, penalty)) % 2**32)
    for _ in range(20):
        n = int(rng.integers(1, 30))
        y, F = rng.normal(size=n) * 3, rng.normal(size=n)
        b = rng.normal(size=n) * rng.choice([0.01, 1.0, 10.0])
        b[rng.random(n) < 0.2] = 0.0
        a = line_search(y, F, b, name, penalty, alpha=0.7)
        f = _objective(name, y, F, b, penalty, alpha=0.7)
        grid = np.concatenate([np.linspace(-300, 300, 60001), a + np.linspace(-1e-2, 1e-2, 2001)])
        assert f(a) <= f(grid).min() + 1e-12


def test_line_search_closed_forms():
    y = np.array([1.0, 2.0, 3.0, 10.0])
    F = np.zeros(4)
    b = np.ones(4)
    # squared, no penalty: mean of the residuals
    assert line_search(y, F, b, "squared_error", 0.0) == pytest.approx(4.0)
    # absolute, no penalty: a median of the residuals (any point in [2, 3])
    assert 2.0 <= line_search(y, F, b, "absolute_error", 0.0) <= 3.0
    # a huge penalty pins the coefficient to zero
    assert line_search(y, F, b, "absolute_error", 100.0) == 0.0
    # zero direction: zero coefficient
    assert line_search(y, F, 0 * b, "squared_error", 0.1) == 0.0


def test_line_search_rejects_bad_input():
    with pytest.raises(ValueError, match="same length"):
        line_search(np.ones(3), np.ones(2), np.ones(3))
    with pytest.raises(ValueError, match="direction contains NaN"):
        line_search(np.ones(3), np.ones(3), np.array([1.0, np.nan, 1.0]))
    with pytest.raises(ValueError, match="penalty must be >= 0"):
        line_search(np.ones(3), np.ones(3), np.ones(3), penalty=-1)
    with pytest.raises(ValueError, match="unknown loss"):
        line_search(np.ones(3), np.ones(3), np.ones(3), loss="l2")
