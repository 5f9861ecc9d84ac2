"""Exact SHAP values by coalition enumeration agree with shap's KernelExplainer."""

import numpy as np
import pytest

from workbench.experiment.scoring.explain import exact_shap_values, sample_background


def _model(a):
    return np.sin(a[:, 0]) * a[:, 1] + a[:, 2] ** 2 - 0.5 * a[:, 0] * a[:, 3]


def test_exact_values_match_the_kernel_explainer_and_add_up():
    shap = pytest.importorskip("shap")
    rng = np.random.default_rng(0)
    data = rng.normal(size=(25, 4))
    background = sample_background(data, 10, random_state=0)
    np.testing.assert_array_equal(background, shap.sample(data, 10, random_state=0))
    calls = []

    def predict(a):
        calls.append(len(a))
        return _model(a)

    values, expected = exact_shap_values(predict, data, background, chunk_rows=2000)
    assert len(calls) == 3  # 25 rows x 16 coalitions x 10 background rows: 12 rows a call
    kernel = shap.KernelExplainer(lambda a: _model(a), background, seed=0)
    reference = np.asarray(kernel.shap_values(data, silent=True))
    # the kernel explainer's LARS step may zero a feature whose effect is ~1e-6 (and give
    # that to the others); elsewhere the two agree to rounding
    np.testing.assert_allclose(values, reference, rtol=1e-6, atol=2e-6)
    assert np.mean(np.isclose(values, reference, rtol=1e-9, atol=1e-12)) > 0.9
    assert expected == pytest.approx(kernel.expected_value)
    np.testing.assert_allclose(values.sum(axis=1) + expected, _model(data), atol=1e-9)


def test_too_many_features_and_bad_background():
    with pytest.raises(ValueError, match="at most 10 features"):
        exact_shap_values(_model, np.zeros((2, 11)), np.zeros((2, 11)))
    with pytest.raises(ValueError, match="background must have shape"):
        exact_shap_values(_model, np.zeros((2, 4)), np.zeros((2, 3)))
