"""Product covariates (bias crosstalk) in the parameter-space model and its candidate pool."""

import numpy as np
import pandas as pd
import pytest

from workbench._covariates import term
from workbench.hamiltonian import CouplingGraph, graph_spectrum
from workbench.param_boost import default_library
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.param_select import candidate_pool, crosstalk_candidates, forward_select
from workbench.simulate import Mismatch, simulate

N = 4
ONSITE = [f"model_f{i}" for i in range(1, N + 1)]
COUPLINGS = [f"model_g{i}" for i in range(1, N)]
TARGETS = [f"measured_E{i}" for i in range(1, N + 1)]
PRIOR = [f"model_E{i}" for i in range(1, N + 1)]
QV = [f"v_q{i}" for i in range(1, N + 1)]
CV = [f"v_c{i}" for i in range(1, N)]


def _synthetic(rng, n):
    """A 3-site chain whose f1 is corrected by 3 (a - mean a)(b - mean b) exactly."""
    f = rng.normal(6000, 40, (n, 3))
    g = rng.normal(-30, 10, (n, 2))
    a, b = rng.uniform(-1, 1, n), rng.uniform(2, 4, n)
    X = pd.DataFrame(np.column_stack([f, g, a, b]), columns=["f1", "f2", "f3", "g1", "g2",
                                                              "a", "b"])
    shift = 3.0 * (a - a.mean()) * (b - b.mean())
    y = graph_spectrum(f + np.column_stack([shift, 0 * a, 0 * a]), g, None, -1,
                       jacobian=False)
    return X, y, shift


def test_product_covariate_is_recovered_exactly():
    X, y, shift = _synthetic(np.random.default_rng(0), 200)
    model = HamiltonianParameterRegressor(onsite=["f1", "f2", "f3"], couplings=["g1", "g2"],
                                          covariates={"f1": ["a*b"]}, alpha=0.0)
    model.fit(X, y)
    assert model.products_ == {"a*b": ("a", "b")}
    assert model.factor_mean_ == pytest.approx({"a": X["a"].mean(), "b": X["b"].mean()})
    assert model.covariate_names_["f1"] == ["intercept", "a*b"]
    corrected = model.corrected_parameters(X)["f1"] - X["f1"]
    assert np.abs(corrected - shift).max() < 1e-6
    # new rows are centred with the training means: one row alone predicts the same
    assert np.allclose(model.predict(X.iloc[[7]]), model.predict(X)[[7]], atol=1e-9)
    table = model.coefficient_table()
    assert list(table[table["parameter"] == "f1"]["covariate"]) == ["intercept", "a*b"]


def test_product_names_parse():
    """The Hamiltonian regressor reads its covariates as the parametric one does
    (:mod:`workbench._covariates`): products, differences and geometric means of columns."""
    columns = {"f1", "f2", "g1", "g2", "v_q1", "v_c1", "a*b"}
    assert term("v_q1*v_c1", columns) == ("v_q1*v_c1", 1)
    assert term("v_q1*v_c1^2", columns) == ("v_q1*v_c1", 2)
    assert term("f1-f2^2", columns) == ("f1-f2", 2)
    assert term("sqrt|g1*g2|", columns) == ("sqrt|g1*g2|", 1)
    assert term("a*b", columns) == ("a*b", 1)  # a column whose name has a '*'
    with pytest.raises(ValueError, match=r"unknown covariate 'v_q1\*v_q9'.*a product 'a\*b'"):
        term("v_q1*v_q9", columns)
    with pytest.raises(ValueError, match=r"unknown covariate 'sqrt\|g1\*g2\|\*f1'"):
        term("sqrt|g1*g2|*f1", columns)  # a product of two columns only


def test_crosstalk_candidates_follow_the_graph():
    on, co = ["f1", "f2", "f3"], ["g12", "g23"]
    qv, cv = ["q1", "q2", "q3"], ["c12", "c23"]
    pool = candidate_pool(on, co, qv, cv, base=None, crosstalk=True)
    assert pool["f1"][-2:] == ["q1*c12", "q1*q2"]
    assert pool["f2"][-4:] == ["q2*c12", "q2*c23", "q2*q1", "q2*q3"]
    assert pool["g23"][-2:] == ["c23*q2", "c23*q3"]
    local = candidate_pool(on, co, qv, cv, base=None, neighbours=False, crosstalk=True)
    assert [t for t in local["f2"] if "*" in t] == ["q2*c12", "q2*c23"]
    assert "q1*c12" not in candidate_pool(on, co, qv, cv, base=None)["f1"]
    grid = CouplingGraph.grid(2, 2)  # edges (0,1), (2,3), (0,2), (1,3)
    cands = crosstalk_candidates(["f0", "f1", "f2", "f3"], ["ga", "gb", "gc", "gd"],
                                 ["q0", "q1", "q2", "q3"], ["ca", "cb", "cc", "cd"], grid)
    assert cands["f0"] == ["q0*ca", "q0*cc", "q0*q1", "q0*q2"]
    assert cands["gd"] == ["cd*q1", "cd*q3"]
    assert crosstalk_candidates(["f0", "f1"], ["g"], [], [], CouplingGraph.chain(2)) == {}


@pytest.fixture(scope="module")
def crosstalk_chain():
    mm = Mismatch(crosstalk=Mismatch.default().crosstalk, noise_sd=0.05)
    return simulate(N, 160, device_seed=2, mismatch=mm).data


def test_crosstalk_products_capture_simulated_flux_crosstalk(crosstalk_chain):
    d = crosstalk_chain
    train, test = d.iloc[:110], d.iloc[110:]
    base = default_library(ONSITE, COUPLINGS)
    plain = candidate_pool(ONSITE, COUPLINGS, QV, CV)
    rich = candidate_pool(ONSITE, COUPLINGS, QV, CV, crosstalk=True)

    def test_mae(pool):
        onsite = {p: v for p, v in pool.items() if p in ONSITE}
        model = HamiltonianParameterRegressor(onsite=ONSITE, couplings=COUPLINGS, alpha=0.1,
                                              covariates={**base, **onsite})
        model.fit(train, train[TARGETS])
        return np.abs(model.predict(test) - test[TARGETS].to_numpy()).mean()

    prior = np.abs(test[PRIOR].to_numpy() - test[TARGETS].to_numpy()).mean()
    with_products, without = test_mae(rich), test_mae(plain)
    assert with_products < 0.5 * without < 0.5 * prior
    assert with_products < 0.15  # the noise (sd 0.05) and a little estimation error


@pytest.mark.parametrize("method", ["refit", "linearised"])
def test_selection_picks_a_crosstalk_product_first(crosstalk_chain, method):
    d = crosstalk_chain.iloc[:110]
    pool = candidate_pool(ONSITE, COUPLINGS, QV, CV, base=None, crosstalk=True)
    res = forward_select(d, d[TARGETS], candidates=pool, start=default_library(ONSITE, COUPLINGS),
                         cv=3, max_steps=1, random_state=0, method=method, onsite=ONSITE,
                         couplings=COUPLINGS, loss="huber", huber_delta=0.5)
    assert "*" in res.selected[0][1]
    assert res.path["cv_mae"].iloc[-1] < res.path["cv_mae"].iloc[0]
    model = res.estimator().fit(d, d[TARGETS])
    assert model.products_ and model.predict(crosstalk_chain.iloc[110:]).shape == (50, N)


def test_config_key_offers_crosstalk(tmp_path):
    from workbench.experiment.config import ConfigError, load_dataset
    from workbench.experiment.families.hamiltonian import make_hamiltonian
    from workbench.experiment.runs.prepare import parse_config
    from workbench.simulate import write_simulation

    write_simulation(simulate(N, 40, device_seed=1), tmp_path / "d.csv")
    data = {"csv": "d.csv", "prior": PRIOR, "targets": TARGETS, "features": QV + CV,
            "test_fraction": 0.3,
            "hamiltonian": {"onsite": ONSITE, "couplings": COUPLINGS, "qubit_features": QV,
                            "coupler_features": CV}}
    raw = {"name": "x", "data": data,
           "model": {"family": "hamiltonian", "hamiltonian": {"crosstalk": True}}}
    cfg = parse_config(raw, tmp_path / "x.toml")
    model = make_hamiltonian(cfg.family_settings, load_dataset(cfg), random_state=0)
    assert "v_q2*v_c1" in model.candidates["model_f2"]
    assert "v_c1*v_q1" in model.candidates["model_g1"]
    raw["model"]["hamiltonian"]["crosstalk"] = "yes please"
    with pytest.raises(ConfigError, match=r"model\.hamiltonian\.crosstalk") as err:
        parse_config(raw, tmp_path / "x.toml")
    assert "\n" not in str(err.value)
