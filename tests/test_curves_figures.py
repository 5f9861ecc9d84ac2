"""Augmented learning curves (core) and the paper's figures (experiment layer)."""

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import FitFailedWarning
from sklearn.linear_model import Ridge
from sklearn.model_selection import KFold

from workbench import BaseBoostRegressor, make_basis
from workbench.curves import LearningCurve, augmented_learning_curve

PRIORS = [f"peig{i}" for i in range(1, 6)]
SIZES = [20, 40, 76]  # 5 folds of 95 rows: 76 fold-training rows


@pytest.fixture(scope="module")
def train(google_5q):
    X_train, _, y_train, _ = google_5q.split()
    return X_train, y_train["eeig3"]


def _estimator(basis=None):
    return BaseBoostRegressor(prior="peig3", basis=basis or make_basis("ridge"),
                              basis_features=PRIORS)


@pytest.fixture(scope="module")
def curve(train):
    X, y = train
    return augmented_learning_curve(_estimator(), X, y, train_sizes=SIZES, cv=5, random_state=0)


# --------------------------------------------------------------------------- the curve


def test_rows_used_equal_the_requested_sizes_in_every_fold(curve):
    assert isinstance(curve, LearningCurve)
    assert curve.train_sizes.tolist() == SIZES
    assert curve.n_train_rows.shape == (3, 5)
    assert curve.n_train_rows.dtype.kind == "i"
    assert (curve.n_train_rows == np.array(SIZES)[:, None]).all()
    np.testing.assert_array_equal(curve.mean_train_rows, SIZES)
    assert curve.n_validation_rows.tolist() == [19] * 5


def test_arrays_have_one_value_per_size_and_fold_and_are_finite(curve):
    for name in ("train_error", "cv_error", "incumbent_error"):
        arr = getattr(curve, name)
        assert arr.shape == (3, 5), name
        assert np.isfinite(arr).all() and (arr > 0).all(), name
    for name in ("train_error_mean", "cv_error_mean", "cv_error_std", "incumbent_error_mean"):
        assert getattr(curve, name).shape == (3,), name
    np.testing.assert_allclose(curve.cv_error_mean, curve.cv_error.mean(axis=1))
    assert not curve.cv_error.flags.writeable  # the frozen result cannot be edited in place
    assert curve.fit_errors == ()


def test_size_above_the_fold_training_size_raises_naming_the_maximum(train):
    X, y = train
    with pytest.raises(ValueError, match=r"train size 77 .*at most 76 rows"):
        augmented_learning_curve(_estimator(), X, y, train_sizes=[20, 77], cv=5, random_state=0)
    with pytest.raises(ValueError, match=r"train size 90 .*at most 47 rows"):
        augmented_learning_curve(_estimator(), X, y, train_sizes=[90], cv=2, random_state=0)


@pytest.mark.parametrize("sizes, match", [([0.5, 0.8], "whole row counts"), ([0, 10], ">= 1"),
                                          ([], "non-empty"), ([10, 10], "duplicates")])
def test_bad_train_sizes_are_refused(train, sizes, match):
    X, y = train
    with pytest.raises(ValueError, match=match):
        augmented_learning_curve(_estimator(), X, y, train_sizes=sizes, cv=5)


def test_non_error_scoring_is_refused(train):
    X, y = train
    with pytest.raises(ValueError, match="'r2'"):
        augmented_learning_curve(_estimator(), X, y, train_sizes=[20], scoring="r2")


def test_incumbent_error_is_the_prior_mae_on_the_validation_rows(train):
    X, y = train
    splitter = KFold(5, shuffle=True, random_state=3)
    c = augmented_learning_curve(_estimator(), X, y, train_sizes=[30, 60], cv=splitter,
                                 random_state=0)
    for j, (_, val) in enumerate(splitter.split(X)):
        by_hand = np.mean(np.abs(y.iloc[val].to_numpy() - X["peig3"].iloc[val].to_numpy()))
        np.testing.assert_allclose(c.incumbent_error[:, j], by_hand, rtol=1e-12)


RECORD: list = []


class Recorder(RegressorMixin, BaseEstimator):
    """Records the row labels it is fitted on; predicts the prior column."""

    def __init__(self, prior="peig3"):
        self.prior = prior

    def fit(self, X, y):
        RECORD.append(X.index.to_numpy().copy())
        self.n_features_in_ = X.shape[1]
        return self

    def predict(self, X):
        return X[self.prior].to_numpy()


def test_each_size_fits_the_first_rows_of_one_permutation_of_the_fold(train):
    X, y = train
    splitter = KFold(5, shuffle=True, random_state=1)
    RECORD.clear()
    c = augmented_learning_curve(Recorder(), X, y, train_sizes=SIZES, cv=splitter,
                                 random_state=0)
    folds = list(splitter.split(X))
    assert len(RECORD) == len(SIZES) * len(folds)  # order: size-major, then fold
    for j, (tr, val) in enumerate(folds):
        fitted = [RECORD[i * len(folds) + j] for i in range(len(SIZES))]
        for size, rows in zip(SIZES, fitted):
            assert len(rows) == len(set(rows)) == size
            assert set(rows) <= set(X.index[tr])
            assert not set(rows) & set(X.index[val])
        for small, big in zip(fitted, fitted[1:]):  # nested: a prefix of the same permutation
            if len(big) < len(tr):
                np.testing.assert_array_equal(big[: len(small)], small)
            else:  # the whole fold: its rows in their own order (a CV fit of the fold)
                np.testing.assert_array_equal(big, X.index[tr])
    # the recorder predicts the prior: its CV error is the incumbent's
    np.testing.assert_allclose(c.cv_error, c.incumbent_error)


def test_same_seed_gives_identical_numbers(train, curve):
    X, y = train
    again = augmented_learning_curve(_estimator(), X, y, train_sizes=SIZES, cv=5,
                                     random_state=0)
    for name in ("n_train_rows", "train_error", "cv_error", "incumbent_error"):
        np.testing.assert_array_equal(getattr(again, name), getattr(curve, name))
    other = augmented_learning_curve(_estimator(), X, y, train_sizes=SIZES, cv=5,
                                     random_state=1)
    assert not np.array_equal(other.cv_error, curve.cv_error)


class FailsAbove(RegressorMixin, BaseEstimator):
    """A basis that cannot fit more than ``max_rows`` rows."""

    def __init__(self, max_rows=30):
        self.max_rows = max_rows

    def fit(self, X, y):
        if len(X) > self.max_rows:
            raise RuntimeError(f"cannot fit {len(X)} rows")
        self.mean_ = float(np.mean(y))
        return self

    def predict(self, X):
        return np.full(len(X), self.mean_)


def test_a_failing_basis_gives_nan_and_a_fit_failed_warning(train):
    X, y = train
    with pytest.warns(FitFailedWarning, match="10 of 15 candidate fits .* cannot fit 40 rows"):
        c = augmented_learning_curve(_estimator(FailsAbove(30)), X, y, train_sizes=SIZES, cv=5,
                                     random_state=0)
    assert np.isfinite(c.cv_error[0]).all() and np.isfinite(c.train_error[0]).all()
    assert np.isnan(c.cv_error[1:]).all() and np.isnan(c.train_error[1:]).all()
    assert np.isfinite(c.incumbent_error).all()
    assert (c.n_train_rows == np.array(SIZES)[:, None]).all()
    assert len(c.fit_errors) == 10 and c.fit_errors[0].startswith("size=40, fold=0")
    assert np.isnan(c.cv_error_mean[1:]).all()
    d = json.loads(json.dumps(c.to_dict(), allow_nan=False))  # NaN -> null, strict JSON
    assert d["cv_error"][1] == [None] * 5 and d["n_train_rows"][0] == [20] * 5


def test_to_dict_is_json_ready(curve):
    d = json.loads(json.dumps(curve.to_dict(), allow_nan=False))
    assert d["train_sizes"] == SIZES
    assert np.array(d["cv_error"]).shape == (3, 5)
    assert d["scoring"] == "neg_mean_absolute_error"


def test_importing_curves_loads_no_experiment_dependencies():
    code = ("import sys, workbench.curves\n"
            "print([m for m in sys.modules if m.split('.')[0] in "
            "('matplotlib', 'mlflow', 'optuna', 'shap') or m.startswith('workbench.experiment')])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


# --------------------------------------------------------------------------- the figures

from workbench.experiment import figures  # noqa: E402  (a missing dependency fails, never skips)


def _png(fig, tmp_path, name):
    import matplotlib.image

    path = figures.save_figure(fig, tmp_path / "nested" / "dir" / name)
    assert path.is_file() and path.suffix == ".png"
    img = matplotlib.image.imread(path)
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    return path


def _no_pyplot_figures():
    import matplotlib.pyplot as plt

    return plt.get_fignums() == []


PRIOR_MAE = [2.417, 1.400, 0.819, 0.972, 1.098]
MODEL_MAE = [1.750, 1.036, 0.802, 0.801, 1.004]


def test_mae_bars(tmp_path):
    from matplotlib.figure import Figure

    fig = figures.mae_bars(["Y1", "Y2", "Y3", "Y4", "Y5"], PRIOR_MAE, MODEL_MAE,
                           unit="MHz", setting="paper settings")
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert ax.get_ylabel() == "MAE (MHz)"
    assert [t.get_text() for t in ax.get_xticklabels()][-1] == "average"
    legend = ax.get_legend()
    assert legend is not None
    assert [t.get_text() for t in legend.get_texts()] == ["prior", "base boosting"]
    assert "paper settings" in ax.get_title()
    annotations = [t.get_text() for t in ax.texts]
    assert "1.34" in annotations and "1.08" in annotations  # the averages are annotated
    _png(fig, tmp_path, "bars.png")
    assert _no_pyplot_figures()
    with pytest.raises(ValueError, match="one value per target"):
        figures.mae_bars(["Y1", "Y2"], [1.0], [1.0, 2.0])


def _interval_rows(values, half):
    values = [*values, float(np.mean(values))]
    return [[v - half, v + 1.5 * half] for v in values]


def test_mae_bars_with_intervals_draws_capped_error_bars(tmp_path):
    prior_ci, model_ci = _interval_rows(PRIOR_MAE, 0.3), _interval_rows(MODEL_MAE, 0.2)
    fig = figures.mae_bars(["Y1", "Y2", "Y3", "Y4", "Y5"], PRIOR_MAE, MODEL_MAE,
                           setting="paper settings", prior_ci=prior_ci, model_ci=model_ci)
    ax = fig.axes[0]
    bars = [c for c in ax.containers if hasattr(c, "patches")]
    assert len(bars) == 2
    for container, rows in zip(bars, (prior_ci, model_ci), strict=True):
        assert container.errorbar is not None
        line_collection = container.errorbar.lines[2][0]
        segments = line_collection.get_segments()
        ends = [[seg[:, 1].min(), seg[:, 1].max()] for seg in segments]
        np.testing.assert_allclose(ends, rows)  # every target's interval and the average's
        assert line_collection.get_linewidth()[0] == pytest.approx(0.8)  # thin
        assert len(container.errorbar.lines[1]) == 2  # caps below and above
        # each bar's value is written above its error bar
        centers = [bar.get_x() + bar.get_width() / 2 for bar in container]
        for x, (_, high) in zip(centers, rows, strict=True):
            label = min((t for t in ax.texts if t.xy[0] == pytest.approx(x)),
                        key=lambda t: t.xy[1])
            assert label.xy[1] == pytest.approx(high)
    assert ax.get_ylim()[1] > max(r[1] for r in prior_ci + model_ci)
    # the legend as without intervals; a note says what the error bars are
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["prior", "base boosting"]
    assert any("95% bootstrap intervals" in t.get_text() for t in ax.texts)
    _png(fig, tmp_path, "bars_ci.png")
    assert _no_pyplot_figures()
    # one system alone; without an average the targets' rows are enough
    fig = figures.mae_bars(["Y1", "Y2"], [1.0, 2.0], [0.5, 1.0], model_ci=[[0.4, 0.7],
                                                                         [0.8, 1.3]],
                           average=False, ci_note=None)
    ax = fig.axes[0]
    assert [c.errorbar is None for c in ax.containers if hasattr(c, "patches")] == [True, False]
    assert not any("bootstrap" in t.get_text() for t in ax.texts)


def test_error_bars_draw_a_result_s_errors_and_intervals():
    from workbench.experiment.scoring.results import Result
    from workbench.experiment.scoring.scores import ModelScores, Scores

    ci = [[0.5, 1.5], [1.0, 3.0]]
    prior = Scores(test_mae=[1.0, 2.0], test_mse=[1.5, 5.0], cv_mae=[], cv_mse=[],
                   test_mse_ci=ci, test_mse_avg_ci=[1.0, 4.0])
    model = ModelScores(test_mae=[0.5, 1.0], test_mse=[0.4, 1.2], cv_mae=[], cv_mse=[])
    result = Result(name="r", config=None, family="eigenvalue", targets=["E1", "E2"],
                    n_train=10, n_test=5, prior=prior, model=model)
    fig = figures.error_bars(result, "MSE", unit="MHz", targets=["a", "b"], setting="s")
    ax = fig.axes[0]
    assert ax.get_ylabel() == "MSE (MHz²)"  # the unit squared for an MSE
    assert [t.get_text() for t in ax.get_xticklabels()] == ["a", "b", "average"]
    prior_bars, model_bars = [c for c in ax.containers if hasattr(c, "patches")]
    assert [b.get_height() for b in prior_bars] == pytest.approx([1.5, 5.0, 3.25])
    assert [b.get_height() for b in model_bars] == pytest.approx([0.4, 1.2, 0.8])
    assert prior_bars.errorbar is not None and model_bars.errorbar is None  # intervals given
    fig = figures.error_bars(result, unit="MHz")  # MAE, the result's targets
    assert fig.axes[0].get_ylabel() == "MAE (MHz)"
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()][:2] == ["E1", "E2"]


def test_mae_bars_without_intervals_draws_no_error_bars():
    fig = figures.mae_bars(["Y1", "Y2", "Y3", "Y4", "Y5"], PRIOR_MAE, MODEL_MAE)
    ax = fig.axes[0]
    assert len(ax.containers) == 2 and all(c.errorbar is None for c in ax.containers)
    assert not any("bootstrap" in t.get_text() for t in ax.texts)


@pytest.mark.parametrize("ci, match", [
    (_interval_rows(MODEL_MAE, 0.2)[:5], r"the 5 targets' and the average's \[low, high\]"),
    ([[0.0, 1.0]] * 5 + [[1.0, 0.5]], "low <= high"),
    ([[0.0, np.nan]] * 6, "finite"),
])
def test_mae_bars_refuses_bad_intervals(ci, match):
    with pytest.raises(ValueError, match=match):
        figures.mae_bars(["Y1", "Y2", "Y3", "Y4", "Y5"], PRIOR_MAE, MODEL_MAE, model_ci=ci)


def test_learning_curve_figure(curve, tmp_path):
    fig = figures.learning_curve_figure(curve, target="eeig3", unit="MHz", setting="ridge basis")
    ax = fig.axes[0]
    assert "MHz" in ax.get_ylabel() and "MAE" in ax.get_ylabel()
    assert figures.learning_curve_figure(curve, target="eeig3").axes[0].get_ylabel() == "MAE"
    assert "rows" in ax.get_xlabel()
    assert "eeig3" in ax.get_title() and "ridge basis" in ax.get_title()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert {"training error", "CV error", "incumbent (prior) CV error"} <= set(labels)
    cv_line = next(line for line in ax.get_lines() if line.get_label() == "CV error")
    np.testing.assert_array_equal(cv_line.get_xdata(), curve.mean_train_rows)
    np.testing.assert_allclose(cv_line.get_ydata(), curve.cv_error_mean)
    _png(fig, tmp_path, "curve")  # a suffix-less path gets .png
    assert _no_pyplot_figures()


def test_figures_are_deterministic(curve, tmp_path):
    for i in range(2):
        figures.save_figure(figures.learning_curve_figure(curve, target="eeig3"),
                            tmp_path / f"curve{i}.png")
        figures.save_figure(figures.mae_bars(["Y1", "Y2", "Y3", "Y4", "Y5"], PRIOR_MAE,
                                             MODEL_MAE), tmp_path / f"bars{i}.png")
    for name in ("curve", "bars"):
        assert (tmp_path / f"{name}0.png").read_bytes() == (tmp_path / f"{name}1.png").read_bytes()


def test_save_figure_refuses_other_formats(tmp_path):
    fig = figures.mae_bars(["Y1"], [1.0], [0.5])
    with pytest.raises(ValueError, match="PNG"):
        figures.save_figure(fig, tmp_path / "bars.pdf")


def test_shap_summary(google_5q, tmp_path):
    X_train, _, y_train, _ = google_5q.split()
    X = X_train[google_5q.feature_names]  # the 9 voltages
    model = Ridge(alpha=1e-3).fit(X.to_numpy(), y_train["eeig3"].to_numpy())
    seen = []

    def predict(a):
        seen.append(type(a))
        return model.predict(a)

    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # e.g. feature-name mismatches
        fig, values = figures.shap_summary(predict, X, target="eeig3", unit="MHz",
                                           setting="ridge on voltages")
    assert set(seen) == {np.ndarray}  # plain arrays, as documented
    assert values.shape == (len(X), 9) and np.isfinite(values).all()
    # a linear model's SHAP values are coef_j * (x_j - background mean): the row sums differ
    # from the prediction by one constant
    offset = values.sum(axis=1) - model.predict(X.to_numpy())
    assert np.ptp(offset) < 1e-6 * max(1.0, np.abs(offset).max())

    ax = fig.axes[0]
    assert "MHz" in ax.get_xlabel() and "eeig3" in ax.get_xlabel()
    assert "eeig3" in ax.get_title() and "ridge on voltages" in ax.get_title()
    assert {t.get_text() for t in ax.get_yticklabels()} == set(google_5q.feature_names)
    first = _png(fig, tmp_path, "shap0.png")
    assert _no_pyplot_figures()

    # exact values by hand with the whole set as background, on a few rows; and determinism
    rows = X.iloc[:12]
    fig1, v1 = figures.shap_summary(lambda a: model.predict(a), rows, target="eeig3",
                                    background_size=len(rows))
    np.testing.assert_allclose(v1, model.coef_ * (rows.to_numpy() - rows.to_numpy().mean(0)),
                               atol=1e-6 * np.abs(v1).max())
    fig2, v2 = figures.shap_summary(lambda a: model.predict(a), rows, target="eeig3",
                                    background_size=len(rows))
    np.testing.assert_array_equal(v1, v2)
    a = figures.save_figure(fig1, tmp_path / "shap1.png").read_bytes()
    b = figures.save_figure(fig2, tmp_path / "shap2.png").read_bytes()
    assert a == b and first.stat().st_size > 0
