"""BaseBoostRegressor: the algorithm (hand-computed stages), priors, transforms, seeds, errors."""

import numpy as np
import pandas as pd
import pytest
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.dummy import DummyRegressor
from sklearn.frozen import FrozenEstimator
from sklearn.linear_model import LinearRegression, Ridge
from sklearn.model_selection import GridSearchCV
from sklearn.neural_network import MLPRegressor
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler

from workbench import BaseBoostRegressor, make_basis
from workbench.bases import NormalQuantileTransformer
from workbench.line_search import line_search


class RecordingRegressor(RegressorMixin, BaseEstimator):
    """A ridge basis that records the inputs and targets it was fitted on."""

    def __init__(self, alpha=1.0):
        self.alpha = alpha

    def fit(self, X, y):
        self.X_seen_, self.y_seen_ = np.array(X, copy=True), np.array(y, copy=True)
        self.model_ = Ridge(alpha=self.alpha).fit(X, y)
        return self

    def predict(self, X):
        return self.model_.predict(X)


class FailingRegressor(RegressorMixin, BaseEstimator):
    def fit(self, X, y):
        raise RuntimeError("basis exploded")

    def predict(self, X):  # pragma: no cover - never fitted
        raise RuntimeError("never fitted")


@pytest.fixture
def data():
    rng = np.random.RandomState(0)
    X = rng.normal(size=(120, 4))
    truth = X[:, 0] + np.sin(2 * X[:, 1]) + 0.5 * X[:, 2] ** 2
    X[:, 3] = truth + 0.3 * X[:, 0] - 0.4 + 0.05 * rng.normal(size=120)  # a biased prior
    y = truth + 0.05 * rng.normal(size=120)
    return X, y


def test_two_stages_equal_hand_computation(data):
    X, y = data
    Xtr, Xte, ytr = X[:90], X[90:], y[:90]
    model = BaseBoostRegressor(prior=3, basis=LinearRegression(), n_stages=2, loss="squared_error",
                               line_search_loss="absolute_error", line_search_penalty=0.1)
    model.fit(Xtr, ytr)

    F0 = Xtr[:, 3]
    b1 = LinearRegression().fit(Xtr, ytr - F0)
    a1 = line_search(ytr, F0, b1.predict(Xtr), "absolute_error", 0.1)
    F1 = F0 + a1 * b1.predict(Xtr)
    b2 = LinearRegression().fit(Xtr, ytr - F1)  # residual of y against the current model
    a2 = line_search(ytr, F1, b2.predict(Xtr), "absolute_error", 0.1)
    expected = Xte[:, 3] + a1 * b1.predict(Xte) + a2 * b2.predict(Xte)

    np.testing.assert_allclose(model.coefs_, [a1, a2], rtol=1e-10)
    np.testing.assert_allclose(model.predict(Xte), expected, rtol=1e-10)
    staged = list(model.staged_predict(Xte))
    assert len(staged) == 2
    np.testing.assert_allclose(staged[0], Xte[:, 3] + a1 * b1.predict(Xte), rtol=1e-10)
    np.testing.assert_allclose(staged[1], expected, rtol=1e-10)


def test_later_stages_fit_residuals_of_y_against_current_model(data):
    X, y = data
    model = BaseBoostRegressor(prior=3, basis=RecordingRegressor(), n_stages=3,
                               line_search_loss="squared_error", line_search_penalty=0.0)
    model.fit(X, y)
    current = X[:, 3].copy()
    for est, coef in zip(model.estimators_, model.coefs_):
        np.testing.assert_allclose(est.y_seen_, y - current, atol=1e-10)
        current = current + coef * est.predict(X)
    # with the same loss in the line search (and a = 0 allowed), training loss never increases
    assert np.all(np.diff(model.train_score_) <= 1e-12)
    assert model.train_score_[-1] < 0.5 * model.train_score_[0]


@pytest.mark.parametrize("loss", ["squared_error", "absolute_error", "huber", "quantile"])
def test_every_loss_improves_on_the_prior(data, loss):
    X, y = data
    model = BaseBoostRegressor(prior=3, basis=make_basis("ridge"), n_stages=3, loss=loss,
                               line_search_loss=loss if loss != "quantile" else "absolute_error")
    model.fit(X[:90], y[:90])
    prior_mae = np.mean(np.abs(y[90:] - X[90:, 3]))
    assert np.mean(np.abs(y[90:] - model.predict(X[90:]))) < prior_mae


def test_input_transform_never_touches_the_prior(data):
    X, y = data
    X = X.copy()
    X[:, 3] += 1e4  # a prior on a scale the transform would squash
    zero_basis = DummyRegressor(strategy="constant", constant=0.0)
    model = BaseBoostRegressor(prior=3, basis=zero_basis,
                               input_transform=NormalQuantileTransformer()).fit(X, y)
    np.testing.assert_array_equal(model.predict_prior(X), X[:, 3])
    np.testing.assert_array_equal(model.predict(X), X[:, 3])
    np.testing.assert_array_equal(model.prior_values_, X[:, 3])

    rec = BaseBoostRegressor(prior=3, basis=RecordingRegressor(), basis_features=[0, 3],
                             input_transform=StandardScaler()).fit(X, y)
    Z = StandardScaler().fit_transform(X[:, [0, 3]])
    np.testing.assert_allclose(rec.estimators_[0].X_seen_, Z)  # the basis sees transformed inputs
    np.testing.assert_array_equal(rec.predict_prior(X), X[:, 3])  # the prior term stays raw


def test_prior_kinds(data):
    X, y = data
    df = pd.DataFrame(X, columns=["a", "b", "c", "physics"])
    by_name = BaseBoostRegressor(prior="physics", basis=make_basis("ridge")).fit(df, y)
    by_index = BaseBoostRegressor(prior=3, basis=make_basis("ridge")).fit(X, y)
    by_callable = BaseBoostRegressor(prior=lambda A: np.asarray(A)[:, 3],
                                     basis=make_basis("ridge")).fit(X, y)
    np.testing.assert_allclose(by_name.predict(df), by_index.predict(X))
    np.testing.assert_allclose(by_callable.predict(X), by_index.predict(X))

    const = BaseBoostRegressor(basis=make_basis("ridge")).fit(X, y)
    np.testing.assert_allclose(const.prior_values_, np.full(len(y), y.mean()))

    fitted = LinearRegression().fit(X[:, :3], y)
    calls = []

    class Physics(RegressorMixin, BaseEstimator):
        def fit(self, A, t):
            calls.append(len(A))
            self.lr_ = LinearRegression().fit(np.asarray(A)[:, :3], t)
            return self

        def predict(self, A):
            return self.lr_.predict(np.asarray(A)[:, :3])

    est_prior = BaseBoostRegressor(prior=Physics(), basis=make_basis("ridge")).fit(X[:60], y[:60])
    assert calls == [60]  # an estimator prior is cloned and fitted on the training rows
    frozen = FrozenEstimator(Pipeline([("cols", _FirstThree()), ("lr", fitted)]))
    est_frozen = BaseBoostRegressor(prior=frozen, basis=make_basis("ridge")).fit(X[:60], y[:60])
    np.testing.assert_allclose(est_frozen.predict_prior(X), fitted.predict(X[:, :3]))
    assert est_prior.predict(X).shape == (120,)


class _FirstThree(BaseEstimator):
    def fit(self, X, y=None):
        return self

    def transform(self, X):
        return np.asarray(X)[:, :3]


def test_same_seed_same_numbers_and_seed_reaches_the_basis(data):
    X, y = data
    mlp = MLPRegressor(hidden_layer_sizes=(5,), solver="lbfgs", max_iter=200)

    def fit(seed):
        return BaseBoostRegressor(prior=3, basis=mlp, n_stages=2, random_state=seed).fit(X, y)

    np.testing.assert_array_equal(fit(7).predict(X), fit(7).predict(X))
    assert not np.allclose(fit(7).predict(X), fit(8).predict(X))
    stage_seeds = [e.random_state for e in fit(7).estimators_]
    assert len(set(stage_seeds)) == 2 and all(isinstance(s, int) for s in stage_seeds)


def test_scikit_learn_composition(data):
    X, y = data
    est = BaseBoostRegressor(prior=3, basis=make_basis("ridge"), n_stages=2)
    params = est.get_params()
    assert {"prior", "basis", "n_stages", "loss", "line_search_loss", "line_search_penalty",
            "basis_features", "input_transform", "random_state"} <= set(params)
    twin = clone(est).set_params(n_stages=3)
    assert twin.n_stages == 3 and est.n_stages == 2
    pipe = Pipeline([("scale", StandardScaler()), ("bb", est)]).fit(X, y)
    assert pipe.predict(X).shape == (120,)
    search = GridSearchCV(est, {"n_stages": [1, 2], "line_search_penalty": [0.0, 0.1]}, cv=3,
                          scoring="neg_mean_absolute_error").fit(X, y)
    assert search.best_params_["n_stages"] in (1, 2)
    assert np.isfinite(search.best_score_)


@pytest.mark.parametrize("kwargs, fit_X, match, exc", [
    (dict(n_stages=0), None, r"'n_stages' parameter of BaseBoostRegressor must be an int "
     r"in the range \[1, inf\)\. Got 0", ValueError),
    (dict(n_stages=1.5), None, "'n_stages' parameter .* Got 1.5", ValueError),
    (dict(loss="lad"), None, r"'loss' parameter .* must be a str among \{.*'absolute_error'.*\} "
     r"or an instance of 'workbench.losses.Loss'. Got 'lad'", ValueError),
    (dict(line_search_loss="l1"), None, "'line_search_loss' parameter .* Got 'l1'", ValueError),
    (dict(line_search_penalty=-1), None, r"'line_search_penalty' parameter .* range \[0(\.0)?, "
     r"inf\)", ValueError),
    (dict(prior="missing"), "frame", "prior column 'missing' is not a column of X", ValueError),
    (dict(prior="physics"), "array", "is a column name, but X has no column names", ValueError),
    (dict(prior=9), None, "prior column 9 is out of range for X with 4 columns", ValueError),
    (dict(prior=lambda A: np.full(len(A), np.nan)), None, "prior callable output contains NaN",
     ValueError),
    (dict(prior=lambda A: np.zeros(3)), None, r"prior callable output must give one value per "
     r"row: expected shape \(120,\), got \(3,\)", ValueError),
    (dict(prior=object()), None, "'prior' parameter of BaseBoostRegressor must be None, an "
     "instance of 'str'", TypeError),
    (dict(basis="ridge"), None, "'basis' parameter .* implementing 'fit' and 'predict'",
     TypeError),
    (dict(basis_features=["zz"]), "frame", "basis feature 'zz' is not a column of X", ValueError),
    (dict(input_transform=Ridge()), None, "'input_transform' parameter .* implementing 'fit' "
     "and 'transform'", TypeError),
    (dict(basis=FailingRegressor()), None, "basis exploded", RuntimeError),
])
def test_bad_parameters_say_what_is_wrong(data, kwargs, fit_X, match, exc):
    X, y = data
    Xin = pd.DataFrame(X, columns=["a", "b", "c", "physics"]) if fit_X == "frame" else X
    with pytest.raises(exc, match=match):
        BaseBoostRegressor(**kwargs).fit(Xin, y)


def test_bad_data_says_what_is_wrong(data):
    X, y = data
    Xn = X.copy()
    Xn[5, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        BaseBoostRegressor(prior=3).fit(Xn, y)
    yn = y.copy()
    yn[2] = np.inf
    with pytest.raises(ValueError, match="infinity|NaN"):
        BaseBoostRegressor(prior=3).fit(X, yn)
    with pytest.raises(ValueError, match="inconsistent numbers of samples"):
        BaseBoostRegressor(prior=3).fit(X, y[:-1])
    model = BaseBoostRegressor(prior=3).fit(X, y)
    with pytest.raises(ValueError, match="features"):
        model.predict(X[:, :3])
