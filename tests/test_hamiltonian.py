"""Chain spectra, their Hellmann-Feynman Jacobian and the parameter-space regressor."""

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.model_selection import KFold

from workbench import BaseBoostCV, BaseBoostRegressor, make_basis, make_transform
from workbench.hamiltonian import chain_hamiltonian, chain_spectrum
from workbench.param_boost import default_library
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.simulate import Mismatch, simulate


def _random_chain(rng, n, N):
    return rng.normal(0, 50, (n, N)) + 6000, rng.normal(-30, 20, (n, N - 1))


@pytest.mark.parametrize("sign", [-1, 1])
def test_spectrum_is_eigvalsh_of_signed_hamiltonian(sign):
    f, g = _random_chain(np.random.default_rng(0), 7, 4)
    h = chain_hamiltonian(f, g)
    assert h.shape == (7, 4, 4)
    assert np.allclose(h, np.swapaxes(h, 1, 2))
    assert np.array_equal(np.diagonal(h, axis1=1, axis2=2), f)
    assert np.array_equal(np.diagonal(h, 1, axis1=1, axis2=2), g)
    assert np.count_nonzero(np.triu(h, 2)) == 0
    lam, jac = chain_spectrum(f, g, sign)
    assert lam.shape == (7, 4) and jac.shape == (7, 4, 7)
    assert np.allclose(lam, np.linalg.eigvalsh(sign * h), rtol=0, atol=1e-9)
    assert np.all(np.diff(lam, axis=1) >= 0)


def test_spectrum_reproduces_benchmark_prior(google_5q):
    ham = google_5q.hamiltonian
    lam, _ = chain_spectrum(ham.onsite, ham.couplings, ham.sign)
    assert np.abs(lam - google_5q.prior.to_numpy()).max() < 1e-3


@pytest.mark.parametrize("N", [2, 3, 5])
@pytest.mark.parametrize("sign", [-1, 1])
def test_jacobian_matches_central_finite_differences(N, sign):
    rng = np.random.default_rng(N)
    f, g = _random_chain(rng, 6, N)
    _, jac = chain_spectrum(f, g, sign)
    theta, eps = np.hstack([f, g]), 1e-4
    fd = np.empty_like(jac)
    for p in range(2 * N - 1):
        up, down = theta.copy(), theta.copy()
        up[:, p] += eps
        down[:, p] -= eps
        lam_up = chain_spectrum(up[:, :N], up[:, N:], sign)[0]
        lam_down = chain_spectrum(down[:, :N], down[:, N:], sign)[0]
        fd[:, :, p] = (lam_up - lam_down) / (2 * eps)
    # relative to the derivatives' scale (|d lambda / d f| <= 1, |d lambda / d g| <= 1)
    assert np.abs(jac - fd).max() <= 1e-5 * max(1.0, np.abs(fd).max())
    # the onsite derivatives of each eigenvalue sum to sign (eigenvectors are unit vectors)
    assert np.allclose(jac[:, :, :N].sum(axis=2), sign)


def test_degenerate_spectrum_is_finite():
    f = np.array([[6000.0, 6000.0, 6000.0], [5000.0, 5000.0, 5000.0]])
    g = np.array([[0.0, 0.0], [0.0, 3.0]])  # triple / double degeneracy
    lam, jac = chain_spectrum(f, g)
    assert np.all(np.isfinite(lam)) and np.all(np.isfinite(jac))
    assert np.allclose(lam[0], -6000.0)


@pytest.mark.parametrize("onsite, couplings, match", [
    (np.zeros((3, 4)), np.zeros((3, 2)), "couplings must have shape"),
    (np.zeros((3, 4)), np.zeros((2, 3)), "couplings must have shape"),
    (np.zeros(4), np.zeros(3), "onsite must be 2-D"),
    (np.zeros((3, 4)), np.zeros(3), "couplings must be 2-D"),
    (np.zeros((3, 1)), np.zeros((3, 0)), "at least 2 sites"),
    (np.array([[1.0, np.nan]]), np.zeros((1, 1)), "onsite contains NaN"),
    (np.zeros((1, 2)), np.array([[np.inf]]), "couplings contains NaN"),
])
def test_bad_chains_raise(onsite, couplings, match):
    with pytest.raises(ValueError, match=match):
        chain_spectrum(onsite, couplings)
    with pytest.raises(ValueError, match="sign"):
        chain_spectrum(np.zeros((1, 2)), np.zeros((1, 1)), sign=2)


# ---------------------------------------------------------------- the regressor

N_SIM = 5
ONSITE = [f"model_f{i}" for i in range(1, N_SIM + 1)]
COUPLINGS = [f"model_g{i}" for i in range(1, N_SIM)]
MEASURED = [f"measured_E{i}" for i in range(1, N_SIM + 1)]
PRIOR = [f"model_E{i}" for i in range(1, N_SIM + 1)]


@pytest.fixture(scope="module")
def coupler_shift():
    sim = simulate(N_SIM, 300, device_seed=0, mismatch=Mismatch.only("coupler_frequency_shift"))
    return sim.data.iloc[:200], sim.data.iloc[200:], sim.truth


def test_regressor_learns_coupler_frequency_shift(coupler_shift):
    train, test, truth = coupler_shift
    # the simulator pulls qubit frequencies down (f -= coef * g^2, coef > 0)
    mech = truth["mechanisms"]["coupler_frequency_shift"]
    assert mech["sign"] == -1 and min(mech["coef_per_MHz"]) > 0
    model = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS)
    model.fit(train, train[MEASURED])
    pred = model.predict(test)
    assert pred.shape == (len(test), N_SIM) and np.all(np.diff(pred, axis=1) >= 0)
    mae = np.abs(pred - test[MEASURED].to_numpy()).mean()
    prior_mae = np.abs(test[PRIOR].to_numpy() - test[MEASURED].to_numpy()).mean()
    assert mae < 0.25 * prior_mae, (mae, prior_mae)
    corrected = model.corrected_parameters(test)
    assert list(corrected.columns) == ONSITE + COUPLINGS
    assert corrected.index.equals(test.index)
    shift = (corrected[ONSITE] - test[ONSITE]).to_numpy()
    assert shift.mean() < 0
    # the injected pull on each onsite frequency, from the truth sidecar
    coef, g = np.asarray(mech["coef_per_MHz"]), test[COUPLINGS].to_numpy()
    pull = np.zeros_like(shift)
    pull[:, :-1] -= coef * g**2
    pull[:, 1:] -= coef * g**2
    assert np.corrcoef(shift.ravel(), pull.ravel())[0, 1] > 0.9
    assert model.train_loss_[-1] < model.train_loss_[0]
    assert list(model.coef_.index.get_level_values("parameter").unique()) == ONSITE + COUPLINGS


def test_parameter_space_recovers_the_shift_and_beats_eigenvalue_boosting(coupler_shift):
    """The injected pull f_i, f_i+1 -= coef_i * g_i^2: the corrected frequencies recover its
    size (regression slope ~1) and the parameter-space model beats base boosting in
    eigenvalue space (per-target BaseBoostCV on the priors and voltages) several times over."""
    train, test, truth = coupler_shift
    mech = truth["mechanisms"]["coupler_frequency_shift"]
    model = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS)
    model.fit(train, train[MEASURED])
    shift = (model.corrected_parameters(test)[ONSITE] - test[ONSITE]).to_numpy()
    coef, g = np.asarray(mech["coef_per_MHz"]), test[COUPLINGS].to_numpy()
    pull = np.zeros_like(shift)
    pull[:, :-1] -= coef * g**2
    pull[:, 1:] -= coef * g**2
    slope = np.polyfit(pull.ravel(), shift.ravel(), 1)[0]
    assert 0.8 < slope < 1.2, slope
    assert shift.mean() == pytest.approx(pull.mean(), rel=0.2)
    y = test[MEASURED].to_numpy()
    param_mae = np.abs(model.predict(test) - y).mean()
    voltages = [f"v_q{i}" for i in range(1, N_SIM + 1)] + [f"v_c{i}" for i in range(1, N_SIM)]
    for basis in (make_basis("kernel_ridge", alpha=0.1, gamma=0.05), make_basis("lightgbm")):
        maes = []
        for j in range(N_SIM):
            booster = BaseBoostRegressor(prior=PRIOR[j], basis=basis, n_stages=2, loss="huber",
                                         basis_features=PRIOR + voltages,
                                         input_transform=make_transform("standard"))
            fitted = BaseBoostCV(booster, cv=5).fit(train, train[MEASURED[j]].to_numpy())
            maes.append(np.abs(fitted.predict(test) - y[:, j]).mean())
        assert param_mae < 0.25 * np.mean(maes), (param_mae, np.mean(maes))


def test_regressor_huber_and_library(coupler_shift):
    train, test, _ = coupler_shift
    model = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS,
                                          features=["v_c1", "v_q1"], loss="huber",
                                          huber_delta=0.5, alpha=0.1)
    model.fit(train, train[MEASURED].to_numpy())
    assert model.covariate_names_["model_f1"] == [
        "intercept", "model_f1", "model_f1^2", "model_g1", "model_g1^2",
        "v_c1", "v_c1^2", "v_q1", "v_q1^2"]
    assert model.covariate_names_["model_g2"] == [
        "intercept", "model_g2", "model_g2^2", "model_f2-model_f3",
        "v_c1", "v_c1^2", "v_q1", "v_q1^2"]
    assert len(model.coef_) == sum(len(v) for v in model.covariate_names_.values())
    mae = np.abs(model.predict(test) - test[MEASURED].to_numpy()).mean()
    prior_mae = np.abs(test[PRIOR].to_numpy() - test[MEASURED].to_numpy()).mean()
    assert mae < 0.25 * prior_mae


def _mae(model, frame):
    return np.abs(model.predict(frame) - frame[MEASURED].to_numpy()).mean()


def test_regressor_warm_start_reaches_the_same_fit(coupler_shift):
    train, test, _ = coupler_shift
    cold = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS, tol=1e-10,
                                         max_iter=50).fit(train, train[MEASURED])
    warm = clone(cold).fit(train, train[MEASURED], coef_init=cold.coef_)
    assert warm.n_iter_ < cold.n_iter_
    assert np.allclose(warm.predict(test), cold.predict(test), atol=1e-6)
    # a covariate the start lacks starts at 0; one the model lacks is ignored
    bigger = {p: names + (["v_q1"] if p == "model_f1" else [])
              for p, names in default_library(ONSITE, COUPLINGS).items()}
    grown = clone(cold).set_params(covariates=bigger).fit(train, train[MEASURED],
                                                          coef_init=cold.coef_)
    assert grown.train_loss_[0] == pytest.approx(cold.train_loss_[-1], rel=1e-9)
    assert grown.train_loss_[-1] <= cold.train_loss_[-1]
    with pytest.raises(ValueError, match="coef_init"):
        clone(cold).fit(train, train[MEASURED], coef_init=np.zeros(3))


def test_regressor_newton_solver_reaches_the_irls_optimum(coupler_shift):
    """The Newton weighting (Huber's curvature) minimises the same objective as IRLS; with
    squared error the two are the same algorithm, with absolute error Newton keeps IRLS."""
    train, test, _ = coupler_shift
    d = simulate(N_SIM, 200, device_seed=1, mismatch=Mismatch.only("crosstalk", "noise")).data
    base = dict(onsite=ONSITE, couplings=COUPLINGS, features=["v_q1", "v_c2"], tol=1e-12,
                max_iter=200)
    for frame in (train, d):
        irls = HamiltonianParameterRegressor(**base, loss="huber", huber_delta=0.5).fit(
            frame, frame[MEASURED])
        newton = clone(irls).set_params(solver="newton").fit(frame, frame[MEASURED])
        assert newton.train_loss_[-1] <= irls.train_loss_[-1] * (1 + 1e-9)
        assert np.allclose(newton.predict(test), irls.predict(test), atol=1e-4)
        assert np.all(np.diff(newton.train_loss_) <= 0)
    # with noise, IRLS converges linearly and the Newton steps take far fewer iterations
    assert newton.n_iter_ < 0.5 * irls.n_iter_, (newton.n_iter_, irls.n_iter_)
    for loss in ("squared_error", "absolute_error"):
        irls = HamiltonianParameterRegressor(**base | dict(tol=1e-6), loss=loss).fit(
            train, train[MEASURED])
        newton = clone(irls).set_params(solver="newton").fit(train, train[MEASURED])
        assert np.array_equal(newton.coef_.to_numpy(), irls.coef_.to_numpy())


def test_regressor_absolute_loss_and_l1(coupler_shift):
    train, test, _ = coupler_shift
    prior_mae = np.abs(test[PRIOR].to_numpy() - test[MEASURED].to_numpy()).mean()
    base = dict(onsite=ONSITE, couplings=COUPLINGS, features=["v_c1", "v_q1", "v_q2"])
    l1 = HamiltonianParameterRegressor(**base, loss="absolute_error").fit(
        train, train[MEASURED])
    assert np.all(np.diff(l1.train_loss_) <= 0)
    assert _mae(l1, test) < 0.25 * prior_mae
    ridge = HamiltonianParameterRegressor(**base, alpha=1.0).fit(train, train[MEASURED])
    sparse = HamiltonianParameterRegressor(**base, alpha=1.0, alpha_l1=20.0).fit(
        train, train[MEASURED])
    n_terms = (ridge.coef_.index.get_level_values("covariate") != "intercept").sum()
    table = sparse.coefficient_table()
    kept = (table["covariate"] != "intercept").sum()
    assert 0 < kept < n_terms  # the L1 penalty zeroes coefficients exactly
    assert set(table.columns) == {"parameter", "covariate", "coef", "covariate_sd"}
    assert len(ridge.coefficient_table()) == len(ridge.coef_)
    assert _mae(sparse, test) < 0.5 * prior_mae


def test_regressor_clone_and_params():
    model = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS, alpha=3.0,
                                          loss="huber")
    params = model.get_params()
    assert params["alpha"] == 3.0 and params["onsite"] == ONSITE and params["sign"] == -1
    twin = clone(model)
    assert twin.get_params() == params and twin is not model


@pytest.mark.parametrize("kwargs, match", [
    (dict(couplings=COUPLINGS), "onsite must name at least 2"),
    (dict(onsite=ONSITE, couplings=COUPLINGS[:2]), "couplings must name"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, loss="quantile"),
     r"'loss' parameter of HamiltonianParameterRegressor must be a str among "
     r"\{('(squared_error|absolute_error|huber)'(, )?){3}\}\. Got 'quantile'"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, alpha_l1=-0.1), "alpha_l1"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, covariates={"nope": ["v_q1"]}),
     "unknown parameter"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, covariates={"model_f1": ["v_x9"]}),
     "unknown covariate 'v_x9'"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, covariates={"model_f1": ["v_q1^x"]}),
     "unknown covariate"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, alpha=-1), "alpha"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, solver="lbfgs"),
     r"'solver' parameter .* among \{'(irls|newton)', '(irls|newton)'\}\. Got 'lbfgs'"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, covariates="cubic"),
     r"'covariates' parameter .* must be a str among \{'default'\} or an instance of 'dict'"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, sign=0), "sign"),
    (dict(onsite=ONSITE, couplings=COUPLINGS, features=["nope"]), "not columns of X"),
])
def test_regressor_bad_params_raise(coupler_shift, kwargs, match):
    train = coupler_shift[0]
    with pytest.raises(ValueError, match=match):
        HamiltonianParameterRegressor(**kwargs).fit(train, train[MEASURED])


def test_regressor_bad_inputs_raise(coupler_shift):
    train = coupler_shift[0]
    model = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS)
    with pytest.raises(ValueError, match="y must have shape"):
        model.fit(train, train[MEASURED[:3]])
    with pytest.raises(ValueError, match="DataFrame"):
        model.fit(train.to_numpy(), train[MEASURED])
    with pytest.raises(ValueError, match="not columns of X"):
        model.fit(train.drop(columns="model_g2"), train[MEASURED])


def test_benchmark_cv_beats_prior(google_5q):
    """5-fold CV on the benchmark's training rows (measured: ~0.69 MHz with the voltages,
    ~0.44 MHz without, prior 1.45 MHz)."""
    ham = google_5q.hamiltonian
    X = pd.concat([google_5q.features, ham.onsite, ham.couplings], axis=1)
    rows = google_5q.train_index
    X, y = X.loc[rows], google_5q.targets.loc[rows].to_numpy()
    prior_mae = np.abs(google_5q.prior.loc[rows].to_numpy() - y).mean()
    for features, bound in [(google_5q.feature_names, prior_mae), (None, 0.5 * prior_mae)]:
        model = HamiltonianParameterRegressor(onsite=list(ham.onsite.columns),
                                              couplings=list(ham.couplings.columns),
                                              sign=ham.sign, features=features)
        err = np.empty_like(y)
        for fit_rows, val_rows in KFold(5, shuffle=True, random_state=0).split(X):
            fitted = clone(model).fit(X.iloc[fit_rows], y[fit_rows])
            err[val_rows] = fitted.predict(X.iloc[val_rows]) - y[val_rows]
        assert np.abs(err).mean() < bound, (features, np.abs(err).mean(), prior_mae)
