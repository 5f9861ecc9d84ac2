"""Covariate selection for the parameter-space regressor (workbench.param_select)."""

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.model_selection import KFold, cross_val_predict

from workbench.param_boost import default_library
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.param_select import HamiltonianSelectionCV, candidate_pool, cv_mae, forward_select
from workbench.simulate import Mismatch, simulate

N = 5
ONSITE = [f"model_f{i}" for i in range(1, N + 1)]
COUPLINGS = [f"model_g{i}" for i in range(1, N)]
MEASURED = [f"measured_E{i}" for i in range(1, N + 1)]
QV = [f"v_q{i}" for i in range(1, N + 1)]
CV = [f"v_c{i}" for i in range(1, N)]


@pytest.fixture(scope="module")
def crosstalk():
    data = simulate(N, 300, device_seed=0, mismatch=Mismatch.only("crosstalk")).data
    return data.iloc[:150], data.iloc[150:]


class _Spy:
    """Records the index labels of every frame the regressor is fitted / predicted on."""

    def __init__(self, monkeypatch):
        self.seen = set()
        cls = HamiltonianParameterRegressor
        fit, predict = cls.fit, cls.predict
        spy = self

        def fit_spy(model, X, y, coef_init=None):
            spy.seen.update(X.index)
            return fit(model, X, y, coef_init=coef_init)

        def predict_spy(model, X):
            spy.seen.update(X.index)
            return predict(model, X)

        monkeypatch.setattr(cls, "fit", fit_spy)
        monkeypatch.setattr(cls, "predict", predict_spy)


def _monotone(path):
    values = path["cv_mae"].to_numpy()
    return np.all(np.diff(values) <= 0)


def test_explicit_covariates_restrict_library(crosstalk):
    train, test = crosstalk
    default = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS)
    explicit = clone(default).set_params(covariates=default_library(ONSITE, COUPLINGS))
    default.fit(train, train[MEASURED])
    explicit.fit(train, train[MEASURED])
    assert explicit.covariate_names_ == default.covariate_names_
    assert np.allclose(explicit.predict(test), default.predict(test), atol=1e-9)
    covariates = {"model_f1": ["v_q1", "v_c1^2"],
                  "model_g2": ["model_f2-model_f3", "model_g2^2"]}
    model = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS,
                                          covariates=covariates).fit(train, train[MEASURED])
    assert model.covariate_names_["model_f1"] == ["intercept", "v_q1", "v_c1^2"]
    assert model.covariate_names_["model_g2"] == ["intercept", "model_f2-model_f3",
                                                  "model_g2^2"]
    assert model.covariate_names_["model_f3"] == ["intercept"]
    assert len(model.coef_) == 9 + 2 + 2
    # only the columns the covariates name are read
    assert model.predict(test[ONSITE + COUPLINGS + ["v_q1", "v_c1"]]).shape == (len(test), N)


def test_candidate_pool_benchmark_layout():
    on, co = ["f1", "f2", "f3", "f4", "f5"], ["g12", "g23", "g34", "g45"]
    qv, cv = [f"qvolt{i}" for i in range(5, 10)], [f"cvolt{i}" for i in range(5, 9)]
    pool = candidate_pool(on, co, qv, cv, neighbours=False)
    assert pool["f1"] == ["f1", "f1^2", "g12", "g12^2", "qvolt5", "qvolt5^2", "cvolt5",
                          "cvolt5^2"]
    assert pool["f3"][-6:] == ["qvolt7", "qvolt7^2", "cvolt6", "cvolt6^2", "cvolt7",
                               "cvolt7^2"]
    assert pool["g23"] == ["g23", "g23^2", "f2-f3", "cvolt6", "cvolt6^2"]
    assert sum(map(len, pool.values())) == 72
    near = candidate_pool(on, co, qv, cv, base=None)
    assert near["f3"] == ["qvolt7", "qvolt7^2", "cvolt6", "cvolt6^2", "cvolt7", "cvolt7^2",
                          "f2", "f4", "f2-f3", "f2-f3^2", "f3-f4", "f3-f4^2", "qvolt6",
                          "qvolt6^2", "qvolt8", "qvolt8^2"]
    assert near["g12"] == ["cvolt5", "cvolt5^2", "f1", "f2", "f1-f2^2", "qvolt5",
                           "qvolt5^2", "qvolt6", "qvolt6^2"]
    with pytest.raises(ValueError, match="qubit_features needs 5"):
        candidate_pool(on, co, qv[:4])
    # every candidate is a valid covariate of its parameter
    X = pd.DataFrame(np.random.default_rng(0).normal(size=(40, 18)), columns=on + co + qv + cv)
    X[on] += 6000
    y = np.sort(np.random.default_rng(1).normal(-6000, 30, (40, 5)), axis=1)
    model = HamiltonianParameterRegressor(onsite=on, couplings=co,
                                          covariates=candidate_pool(on, co, qv, cv),
                                          max_iter=1).fit(X, y)
    assert sum(len(v) - 1 for v in model.covariate_names_.values()) == sum(
        map(len, candidate_pool(on, co, qv, cv).values()))


def test_forward_select_simulated_picks_voltages(crosstalk, monkeypatch):
    train, _ = crosstalk
    spy = _Spy(monkeypatch)
    pool = candidate_pool(ONSITE, COUPLINGS, QV, CV, squares=False, base=None)
    res = forward_select(train, train[MEASURED], candidates=pool, onsite=ONSITE,
                         couplings=COUPLINGS, max_steps=5)
    assert spy.seen <= set(train.index)
    assert res.n_rows == len(train) and res.index.equals(train.index)
    assert _monotone(res.path) and len(res.path) >= 2
    assert all(c.startswith("v_") for _, c in res.selected)
    default = cv_mae(HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS),
                     train, train[MEASURED].to_numpy(), cv=5, random_state=0)
    assert res.cv_mae < default, (res.cv_mae, default)
    # the path's last value is the CV MAE of the refit estimator on the same splits
    again = cv_mae(res.estimator(), train, train[MEASURED].to_numpy(), cv=5, random_state=0)
    assert again == pytest.approx(res.cv_mae, rel=1e-4)


def test_benchmark_selection_on_training_rows(google_5q, monkeypatch):
    """The selection only ever sees training rows and improves on the default library."""
    ham = google_5q.hamiltonian
    X = pd.concat([google_5q.features, ham.onsite, ham.couplings], axis=1)
    rows = google_5q.train_index
    X, y = X.loc[rows], google_5q.targets.loc[rows].to_numpy()
    prior_mae = np.abs(google_5q.prior.loc[rows].to_numpy() - y).mean()
    on, co = list(ham.onsite.columns), list(ham.couplings.columns)
    pool = candidate_pool(on, co, [f"qvolt{i}" for i in range(5, 10)],
                          [f"cvolt{i}" for i in range(5, 9)], base=None)
    spy = _Spy(monkeypatch)
    res = forward_select(X, y, candidates=pool, start=default_library(on, co), onsite=on,
                         couplings=co, sign=ham.sign, n_jobs=2,
                         max_steps=2)  # 4 steps: 17 s instead of 7, the same checks
    assert spy.seen <= set(rows)
    assert _monotone(res.path)
    assert res.cv_mae <= res.path["cv_mae"].iloc[0] < 0.5 * prior_mae
    other_seed = cv_mae(res.estimator(), X, y, cv=5, random_state=100)
    print(f"\nselection CV MAE {res.cv_mae:.3f}, other-seed CV MAE {other_seed:.3f}, "
          f"prior {prior_mae:.3f}, selected {res.selected}")
    assert other_seed < 0.5 * prior_mae, (other_seed, prior_mae)


def test_selection_cv_is_an_estimator_for_nested_cv(crosstalk, monkeypatch):
    train, _ = crosstalk
    pool = candidate_pool(ONSITE, COUPLINGS, QV, CV, squares=False, base=None,
                          neighbours=False)
    model = HamiltonianSelectionCV(
        HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS), candidates=pool,
        max_steps=2, cv=3, random_state=0)
    twin = clone(model)
    assert twin.get_params(deep=False).keys() == model.get_params(deep=False).keys()
    assert twin.regressor is not model.regressor  # cloned, with the same parameters
    assert twin.regressor.get_params() == model.regressor.get_params()
    outer = list(KFold(3, shuffle=True, random_state=1).split(train))
    seen_per_fold = []
    spy = _Spy(monkeypatch)
    pred = np.empty((len(train), N))
    for fit_rows, val_rows in outer:
        spy.seen.clear()
        fitted = clone(model).fit(train.iloc[fit_rows], train[MEASURED].iloc[fit_rows])
        seen_per_fold.append(set(spy.seen))
        pred[val_rows] = fitted.predict(train.iloc[val_rows])
        assert len(fitted.selection_.selected) <= 2
    for (fit_rows, _), seen in zip(outer, seen_per_fold):
        assert seen == set(train.index[fit_rows])  # the selection never saw its outer fold
    again = cross_val_predict(model, train, train[MEASURED], cv=outer)
    assert np.allclose(again, pred)
    prior = train[[f"model_E{i}" for i in range(1, N + 1)]].to_numpy()
    y = train[MEASURED].to_numpy()
    assert np.abs(pred - y).mean() < np.abs(prior - y).mean()
    with pytest.raises(ValueError, match=r"'cv' parameter of HamiltonianSelectionCV must be "
                                         r"an int in the range \[2"):
        clone(model).set_params(cv=1).fit(train, train[MEASURED])


def test_linear_scores_rank_candidates_as_refits_do(crosstalk):
    """One Gauss-Newton step of the enlarged model (the linearised selection's score) orders
    the candidates as their exact refits do, and picks the same best one; with the Newton
    solver's weights the scores are close to the refits' held-out errors themselves."""
    from scipy.stats import spearmanr

    from workbench.param_linear import linear_scores

    train, _ = crosstalk
    fit, val = train.iloc[:110], train.iloc[110:]
    start = default_library(ONSITE, COUPLINGS)
    pool = candidate_pool(ONSITE, COUPLINGS, QV, CV, base=None)
    cands = [(p, c) for p, names in pool.items() for c in names]
    y_val = val[MEASURED].to_numpy()
    common = dict(onsite=ONSITE, couplings=COUPLINGS, loss="huber", huber_delta=0.5,
                  solver="newton", tol=1e-8, max_iter=50)
    est = HamiltonianParameterRegressor(covariates=start, **common).fit(fit, fit[MEASURED])
    lin = linear_scores(est, fit, fit[MEASURED], val, y_val, cands) / y_val.size
    exact = []
    for p, c in cands:
        lib = {q: list(v) for q, v in start.items()}
        lib[p] = lib[p] + [c]
        refit = HamiltonianParameterRegressor(covariates=lib, **common).fit(
            fit, fit[MEASURED], coef_init=est.coef_dict())
        exact.append(np.abs(refit.predict(val) - y_val).mean())
    exact = np.asarray(exact)
    assert spearmanr(lin, exact)[0] > 0.97
    assert np.argmin(lin) == np.argmin(exact)
    assert np.median(np.abs(lin - exact)) < 1e-3
    # the held-out predictions are made in blocks of candidates: any block size, same scores
    small = linear_scores(est, fit, fit[MEASURED], val, y_val, cands, chunk_elements=1)
    assert np.allclose(small, lin * y_val.size, rtol=1e-12)


def test_linearised_selection_recovers_the_injected_covariates():
    """On a small simulated grid whose mismatch is a coupler nonlinearity (true g_e gains
    kappa_e * ((V_c,e - 0.16) / 0.06)^2), the linearised selection adds each coupling's own
    coupler voltage, and the same seed gives the same selection with or without threads."""
    sim = simulate(None, 240, device_seed=2, topology="grid", shape=(2, 3),
                   mismatch=Mismatch(coupler_nonlinearity=1.5, noise_sd=0.1))
    d, g = sim.data, sim.truth["graph"]
    n, e = g["n_sites"], len(g["edges"])
    on = [f"model_f{i}" for i in range(1, n + 1)]
    co = [f"model_g{i}" for i in range(1, e + 1)]
    qv, cv = [f"v_q{i}" for i in range(1, n + 1)], [f"v_c{i}" for i in range(1, e + 1)]
    pool = candidate_pool(on, co, qv, cv, base=None, edges=g["edges"])
    common = dict(onsite=on, couplings=co, edges=g["edges"], loss="huber", huber_delta=0.5)
    y = d[[f"measured_E{i}" for i in range(1, n + 1)]]
    runs = [forward_select(d, y, candidates=pool, start=default_library(on, co, g["edges"]),
                           cv=3, max_steps=4, method="linearised", random_state=0,
                           n_jobs=jobs, **common) for jobs in (1, 2)]
    res = runs[0]
    assert runs[1].selected == res.selected and runs[1].cv_mae == res.cv_mae
    assert len(res.selected) == 4
    for p, c in res.selected:  # model_g<e> <- v_c<e> or v_c<e>^2
        assert p in co and c.split("^")[0] == "v_c" + p.removeprefix("model_g"), (p, c)
    assert res.path["cv_mae"].iloc[-1] < 0.9 * res.path["cv_mae"].iloc[0]
