"""One engine: the Hamiltonian as a parametric model, fitted by the same Gauss-Newton as a
user's model."""

import numpy as np
import pandas as pd
import pytest

from workbench.hamiltonian import CouplingGraph, HamiltonianModel, graph_spectrum
from workbench.param_regressor import HamiltonianParameterRegressor, ParametricRegressor
from workbench.parametric import FD_STEP, ModelError, ParametricModel, check_model
from workbench.parametric_boost import ParametricBoostRegressor
from workbench.simulate import Mismatch, simulate

ONSITE = [f"model_f{k}" for k in range(1, 5)]
COUPLINGS = [f"model_g{k}" for k in range(1, 4)]
TARGETS = [f"measured_E{k}" for k in range(1, 5)]


@pytest.fixture(scope="module")
def device():
    """A 4-site chain whose parameters drift with the bias voltages."""
    sim = simulate(4, 120, device_seed=5,
                   mismatch=Mismatch(drift=0.3, crosstalk=0.05, noise_sd=0.2))
    return sim.data


def test_the_hamiltonian_is_a_parametric_model(device):
    graph = CouplingGraph.chain(4).with_edges([(0, 2)])
    model = HamiltonianModel(tuple(ONSITE), tuple(COUPLINGS), graph, ("f1~f3",))
    assert model.names == ONSITE + COUPLINGS + ["f1~f3"]
    assert model.parameters == {**{p: p for p in ONSITE + COUPLINGS}, "f1~f3": 0.0}
    start = model.start(device)
    assert np.array_equal(start[:, :7], device[ONSITE + COUPLINGS].to_numpy())
    assert np.all(start[:, 7] == 0.0)
    # at the start the model is the control model's spectrum (the parasitic coupling is 0)
    control = graph_spectrum(device[ONSITE], device[COUPLINGS])[0]
    assert np.allclose(model.predict(start, device, 4), control, rtol=0, atol=1e-9)
    # the analytic (Hellmann-Feynman) Jacobian is the central differences' within their error
    theta = start + np.random.default_rng(0).normal(0, 5, start.shape)
    value, jac = check_model(model, device, 4, theta)
    fd = ParametricModel.from_functions(*model.file_functions()).jacobian(theta, device, 4)
    assert jac.shape == (120, 4, 8)
    assert np.abs(jac - fd).max() < 1e3 * FD_STEP ** 2
    assert np.array_equal(value, model.predict(theta))
    with pytest.raises(ModelError, match="4 eigenvalues, not 3 targets"):
        model.predict(start, device, 3)
    with pytest.raises(ModelError, match="lack the parameter column"):
        model.start(device.drop(columns=ONSITE[0]))


def test_one_engine_fits_both_families_alike(device):
    """The Hamiltonian regressor and the parametric regressor with the Hamiltonian model are
    the same fit: same covariates, loss and penalties, same coefficients and predictions."""
    covariates = {"model_f1": ["model_f1", "v_q1", "v_q1^2"],
                  "model_f2": ["v_q2", "model_f1-model_f2", "v_q1*v_q2"],
                  "model_g2": ["model_g2^2", "v_c2"]}
    train, test = device.iloc[:90], device.iloc[90:]
    hamiltonian = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS,
                                                covariates=covariates, alpha=0.5)
    hamiltonian.fit(train, train[TARGETS])
    model = HamiltonianModel.chain(ONSITE, COUPLINGS)
    parametric = ParametricRegressor(model=model, covariates=covariates, calibrate=False,
                                     loss="squared_error", alpha=0.5)
    parametric.fit(train, train[TARGETS].to_numpy())
    assert isinstance(hamiltonian.model_, HamiltonianModel)
    assert hamiltonian.n_iter_ == parametric.n_iter_ > 1
    assert np.allclose(hamiltonian.coef_["coef"], parametric.coef_["coef"], rtol=1e-9,
                       atol=1e-9)
    assert np.allclose(hamiltonian.predict(test), parametric.predict(test), rtol=0, atol=1e-9)
    # one core: the Gauss-Newton information of the coefficients is the same too
    info = hamiltonian.information(test)
    assert info.shape == (len(parametric.coef_),) * 2
    assert np.allclose(info, parametric.information(test), rtol=1e-7, atol=1e-7)
    # the model file written from the model object (finite differences) fits the same
    from_file = ParametricModel.from_functions(*model.file_functions()[:2])
    again = ParametricRegressor(model=from_file, covariates=covariates, calibrate=False,
                                loss="squared_error", alpha=0.5).fit(train, train[TARGETS])
    assert np.abs(again.predict(test) - parametric.predict(test)).max() < 1e-4


def test_the_parametric_family_boosts_the_hamiltonian_model(device):
    """The parametric family's choice (prior, calibrated, drift by CV) on the Hamiltonian
    model object: the drift wins where the parameters drift."""
    columns = ONSITE + COUPLINGS + ["v_q1", "v_q2", "v_c2"]
    est = ParametricBoostRegressor(model=HamiltonianModel.chain(ONSITE, COUPLINGS),
                                   features=["v_q1", "v_q2", "v_c2"], cv=3, max_steps=3,
                                   products=False, random_state=0)
    est.fit(device[columns], device[TARGETS])
    assert est.choice_ == "drift"
    scores = est.choices_.set_index("candidate")["cv_mae"]
    assert scores["drift"] < scores["calibrated"] < scores["prior"]
    assert isinstance(est.estimator_.model, HamiltonianModel)
    assert est.predict(device[columns]).shape == (120, 4)
    assert pd.Index(est.corrected_parameters(device[columns]).columns).equals(
        pd.Index(ONSITE + COUPLINGS))
