"""SHAP of the learned correction (model - prior) beside the whole prediction's (issue 21)."""

import numpy as np
import pandas as pd
import pytest
from sklearn.linear_model import Ridge
from sklearn.tree import DecisionTreeRegressor

from workbench import BaseBoostCV, BaseBoostRegressor, PriorModel
from workbench.experiment import figures
from workbench.experiment.scoring.explain import (
    correction_predictor,
    correction_shap_values,
    model_columns,
    prior_reason,
    target_shap_values,
)


def _data(n=80, seed=0):
    """A prior column ``p`` (tens of units, like an eigenvalue) and two inputs; the target is
    the prior plus a small nonlinear correction of the inputs."""
    rng = np.random.default_rng(seed)
    X = pd.DataFrame({"p": rng.normal(0, 30, n), "a": rng.normal(size=n),
                      "b": rng.normal(size=n), "unused": rng.normal(size=n)})
    y = X["p"] + np.sin(2 * X["a"]) + 0.5 * X["a"] * X["b"] + 0.05 * rng.normal(size=n)
    return X, y.to_numpy()


def _boosted(X, y, **kwargs):
    return BaseBoostRegressor(prior="p", basis=DecisionTreeRegressor(max_depth=3),
                              basis_features=["p", "a", "b"], n_stages=3, random_state=0,
                              **kwargs).fit(X, y)


def test_predict_correction_is_the_prediction_minus_the_prior():
    X, y = _data()
    model = _boosted(X, y)
    assert np.any(model.coefs_)
    np.testing.assert_allclose(model.predict_correction(X),
                               model.predict(X) - model.predict_prior(X), atol=1e-9)
    # coefficient 0 everywhere: exactly 0, and the model is the prior exactly
    flat = _boosted(X, y, line_search_penalty=1e9)
    assert not np.any(flat.coefs_)
    assert np.array_equal(flat.predict_correction(X), np.zeros(len(X)))
    assert np.array_equal(flat.predict(X), flat.predict_prior(X))


def test_correction_shap_values_add_up_to_the_correction():
    """Efficiency: on every explained row the correction's SHAP values sum to the correction
    (model - prior) minus its expected value over the background; the whole prediction's to
    the prediction minus its own. Their difference is the prior's SHAP values: x_p - mean
    over the background on the prior column, 0 elsewhere (Shapley values are linear)."""
    X, y = _data()
    model = _boosted(X, y)
    assert model_columns(model, X) == ["p", "a", "b"]  # the basis inputs and the prior
    out = target_shap_values(model, X, random_state=1)
    whole, corr = out.prediction, out.correction
    assert out.note == ""
    assert whole.rows is corr.rows  # the same rows
    rows = X.loc[corr.rows.index]
    correction = model.predict(rows) - model.predict_prior(rows)
    np.testing.assert_allclose(corr.values.sum(axis=1) + corr.expected, correction, atol=1e-9)
    np.testing.assert_allclose(whole.values.sum(axis=1) + whole.expected, model.predict(rows),
                               atol=1e-9)
    prior_part = whole.values - corr.values
    np.testing.assert_allclose(prior_part[:, 1:], 0.0, atol=1e-9)
    # the same background: the prior's part is x_p minus one constant (its background mean)
    offset = rows["p"].to_numpy() - prior_part[:, 0]
    assert np.ptp(offset) < 1e-9
    assert whole.expected - corr.expected == pytest.approx(offset[0], abs=1e-9)
    # the correction is small next to the prior: what the whole prediction's summary hides
    assert np.abs(corr.values).mean() < 0.1 * np.abs(whole.values).mean()
    # the same numbers from the function reproduce.py calls, and from the same seed
    alone = correction_shap_values(model, X, random_state=1)
    np.testing.assert_array_equal(alone.values, corr.values)
    assert alone.expected == corr.expected
    assert target_shap_values(model, X, random_state=1, prediction=False).prediction is None


def test_a_model_that_is_its_prior_has_no_correction_to_explain(tmp_path):
    X, y = _data()
    flat = _boosted(X, y, line_search_penalty=1e9)
    prior = PriorModel(prior="p").fit(X, y)
    for model, words in ((flat, "all 3 boosted stages have coefficient 0"),
                         (prior, "selected the prior")):
        assert correction_predictor(model) is None
        assert words in prior_reason(model)
        out = target_shap_values(model, X)
        assert out.correction is None and words in out.note
        assert out.prediction is not None  # the whole prediction is still explained
        assert correction_shap_values(model, X) is None
    # BaseBoostCV: the model it selected; prior selected on a target the prior predicts
    cv = BaseBoostCV(BaseBoostRegressor(prior="p", basis=Ridge()), cv=3).fit(X, X["p"])
    assert cv.selected_ == "prior" and correction_predictor(cv) is None
    assert "selected the prior" in prior_reason(cv)
    # a boosted BaseBoostCV has one, its model's
    cv = BaseBoostCV(BaseBoostRegressor(prior="p", basis=DecisionTreeRegressor(max_depth=3),
                                        basis_features=["a", "b"]), cv=3).fit(X, y)
    assert cv.selected_ == "boosted" and prior_reason(cv) == ""
    np.testing.assert_allclose(correction_predictor(cv)(X),
                               cv.predict(X) - cv.best_estimator_.predict_prior(X), atol=1e-9)
    with pytest.raises(TypeError, match="cannot tell the prior of a Ridge"):
        correction_predictor(Ridge().fit(X, y))

    # the figure says so instead of a beeswarm of zeros
    fig = figures.correction_shap_figure(None, target="Y2", note=prior_reason(flat),
                                         unit="MHz", setting="paper settings")
    ax = fig.axes[0]
    assert not ax.axison and not ax.collections
    text = " ".join(t.get_text() for t in ax.texts)
    assert "is its prior (all 3 boosted stages have coefficient 0)" in text
    assert "correction (model − prior) is 0 MHz on every row" in text
    assert "correction (model − prior): Y2" in ax.get_title()
    assert "paper settings" in ax.get_title()
    figures.save_figure(fig, tmp_path / "none.png")


def test_figures_name_what_they_explain_with_units(tmp_path):
    X, y = _data()
    out = target_shap_values(_boosted(X, y), X)
    whole = out.prediction
    fig = figures.shap_figure(whole.values, whole.expected, whole.rows, target="Y1",
                              unit="MHz", explained="prediction", setting="s")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "SHAP value: effect on the whole prediction of Y1 (MHz)"
    assert "SHAP summary of the whole prediction: Y1" in ax.get_title()
    fig = figures.correction_shap_figure(out.correction, target="Y1", unit="MHz", setting="s")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "SHAP value: effect on the correction (model − prior) of Y1 (MHz)"
    assert "SHAP summary of the correction (model − prior): Y1" in ax.get_title()
    assert {t.get_text() for t in ax.get_yticklabels()} == {"p", "a", "b"}
    figures.save_figure(fig, tmp_path / "correction.png")
    # without explained=, the label of a model without a prior, as before
    fig = figures.shap_figure(whole.values, whole.expected, whole.rows, target="Y1", unit="MHz")
    assert fig.axes[0].get_xlabel() == "SHAP value: effect on predicted Y1 (MHz)"
    # data without a unit: none shown
    fig = figures.shap_figure(whole.values, whole.expected, whole.rows, target="Y1")
    assert fig.axes[0].get_xlabel() == "SHAP value: effect on predicted Y1"
    with pytest.raises(ValueError, match="explained must be one of"):
        figures.shap_figure(whole.values, whole.expected, whole.rows, target="Y1",
                            explained="prior")


def test_eigenvalue_runs_draw_the_correction_beside_the_whole_prediction(tmp_path,
                                                                       google_5q_dir):
    """Family eigenvalue's run figures: per target ``shap_<target>`` (the whole prediction)
    and ``shap_correction_<target>``; eeig2's stage is penalised to coefficient 0, so its
    model is the prior and its correction figure says so."""
    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.intervals import family_model
    from workbench.experiment.runs.prepare import load_config

    path = tmp_path / "c.toml"
    path.write_text(f'name = "c"\nrandom_state = 0\nn_jobs = 1\n'
                    f'[data]\ndata_dir = "{google_5q_dir}"\n'
                    '[model]\nbasis = "ridge"\ninput_transform = "standard"\n'
                    '[model.targets.eeig2]\nline_search_penalty = 1e9\n'
                    '[intervals]\nenabled = false\n')
    cfg = load_config(path)
    run = evaluate(cfg, return_model=True)
    model = family_model(run.model)
    out = cfg.family.begin_artifacts(cfg, run.dataset, model, "ridge basis")()
    targets = run.dataset.target_names
    assert {f"shap_correction_{t}" for t in targets} <= set(out.figures)
    for target, est in zip(targets, model.estimators_):
        whole = out.figures[f"shap_{target}"].axes[0]
        assert "whole prediction" in whole.get_xlabel() and "MHz" in whole.get_xlabel()
        ax = out.figures[f"shap_correction_{target}"].axes[0]
        if prior_reason(est):
            assert "is its prior" in " ".join(t.get_text() for t in ax.texts)
        else:
            assert "correction (model − prior)" in ax.get_xlabel()
    assert prior_reason(model.estimators_[1])  # eeig2
    assert run.result.model.selected[1] == "prior"
