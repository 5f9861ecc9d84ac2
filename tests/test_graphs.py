"""Coupling graphs: spectra and Jacobians on rings and grids, parasitic couplings, bad graphs,
the simulator's topologies and covariate selection on a small grid."""

import json

import numpy as np
import pandas as pd
import pytest

from workbench.datasets import DatasetError, load_csv_dataset
from workbench.experiment.cli import main
from workbench.hamiltonian import (
    CouplingGraph,
    _hellmann_feynman,
    graph_hamiltonian,
    graph_spectrum,
    make_graph,
)
from workbench.param_boost import default_library
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.param_select import HamiltonianSelectionCV, candidate_pool, forward_select
from workbench.simulate import Mismatch, simulate, write_simulation

GRAPHS = {"ring5": CouplingGraph.ring(5), "grid2x3": CouplingGraph.grid(2, 3),
          "grid3x3": CouplingGraph.grid(3, 3),
          "edges": CouplingGraph.from_edges(4, [[0, 2], [2, 1], [1, 3], [0, 3], [0, 1]])}


def _random(rng, n, graph):
    return (rng.normal(0, 50, (n, graph.n_sites)) + 6000,
            rng.normal(-30, 20, (n, graph.n_edges)))


def test_graph_structure():
    g = CouplingGraph.grid(2, 3)
    assert g.n_sites == 6 and g.n_edges == 7 and g.shape == (2, 3)
    assert g.edges == ((0, 1), (1, 2), (3, 4), (4, 5), (0, 3), (1, 4), (2, 5))
    assert g.neighbours(1) == [0, 2, 4] and g.site_edges(1) == [0, 1, 5]
    assert g.edge_neighbours(0) == [1, 4, 5]
    assert g.parasitic_edges("diagonal") == [(0, 4), (1, 3), (1, 5), (2, 4)]
    assert set(g.parasitic_edges("next_nearest")) >= {(0, 2), (3, 5), (0, 4)}
    assert CouplingGraph.chain(5).parasitic_edges("next_nearest") == [(0, 2), (1, 3), (2, 4)]
    assert CouplingGraph.ring(4).edges[-1] == (3, 0)
    assert CouplingGraph.chain(4).edges == make_graph(4).edges


@pytest.mark.parametrize("name", list(GRAPHS))
@pytest.mark.parametrize("sign", [-1, 1])
def test_spectrum_and_jacobian_on_any_graph(name, sign):
    graph = GRAPHS[name]
    rng = np.random.default_rng(len(name))
    f, g = _random(rng, 6, graph)
    h = graph_hamiltonian(f, g, graph)
    assert np.allclose(h, np.swapaxes(h, 1, 2))
    assert np.count_nonzero(np.triu(h[0], 1)) == graph.n_edges
    lam, jac = graph_spectrum(f, g, graph, sign, chunk_elements=40)  # several chunks
    assert np.allclose(lam, np.linalg.eigh(sign * h)[0], rtol=0, atol=1e-9)
    assert np.allclose(graph_spectrum(f, g, graph, sign, jacobian=False), lam, atol=1e-9)
    N, theta, eps = graph.n_sites, np.hstack([f, g]), 1e-4
    fd = np.empty_like(jac)
    for p in range(theta.shape[1]):
        up, down = theta.copy(), theta.copy()
        up[:, p] += eps
        down[:, p] -= eps
        fd[:, :, p] = (np.linalg.eigvalsh(sign * graph_hamiltonian(up[:, :N], up[:, N:], graph))
                       - np.linalg.eigvalsh(sign * graph_hamiltonian(down[:, :N], down[:, N:],
                                                                     graph))) / (2 * eps)
    assert np.abs(jac - fd).max() <= 1e-5 * max(1.0, np.abs(fd).max())
    assert np.allclose(jac[:, :, :N].sum(axis=2), sign)
    # written into a given array; the Hellmann-Feynman products over any row blocks
    buffer = np.full_like(jac, np.nan)
    again = graph_spectrum(f, g, graph, sign, out=buffer)[1]
    assert again is buffer and np.array_equal(again, graph_spectrum(f, g, graph, sign)[1])
    vec = np.linalg.eigh(sign * h)[1]
    a, b = (np.array([e[k] for e in graph.edges]) for k in (0, 1))
    blocks = _hellmann_feynman(vec, sign, a, b, np.empty_like(jac), block_elements=1)
    assert np.array_equal(blocks, _hellmann_feynman(vec, sign, a, b, np.empty_like(jac)))
    assert np.allclose(blocks, jac, atol=1e-9)


@pytest.mark.parametrize("build, match", [
    (lambda: CouplingGraph.from_edges(3, [[0, 3]]), r"edge 0 \[0, 3\] is out of range: "
     r"sites are 0..2"),
    (lambda: CouplingGraph.from_edges(3, [[1, 1]]), "self-loop"),
    (lambda: CouplingGraph.from_edges(3, [[0, 1], [1, 0]]), r"edge 1 \[1, 0\] is a duplicate"),
    (lambda: CouplingGraph.from_edges(3, [[0, 1, 2]]), "must be a pair of site indices"),
    (lambda: CouplingGraph.from_edges(3, "0-1"), "edges must be a list"),
    (lambda: CouplingGraph.ring(2), "ring's number of sites must be an integer >= 3"),
    (lambda: make_graph(8, "grid", (3, 3)), "grid shape 3x3 has 9 sites, but there are 8"),
    (lambda: make_graph(4, "grid"), "topology grid needs shape"),
    (lambda: make_graph(4, "chain", (2, 2)), "shape is only for topology grid"),
    (lambda: make_graph(4, "star"), "unknown topology 'star'; valid: chain, ring, grid"),
    (lambda: CouplingGraph.grid(2, 2).parasitic_edges("third"), "unknown parasitic"),
    (lambda: graph_spectrum(np.zeros((2, 4)), np.zeros((2, 3)), CouplingGraph.ring(4)),
     r"couplings must have shape \(n_examples, n_edges\) = \(2, 4\)"),
    (lambda: graph_spectrum(np.zeros((2, 3)), np.zeros((2, 4)), CouplingGraph.ring(4)),
     "the graph has 4 sites but onsite has 3 columns"),
])
def test_bad_graphs_fail_with_one_line(build, match):
    with pytest.raises(ValueError, match=match) as err:
        build()
    assert "\n" not in str(err.value)


def _csv(tmp_path, sim):
    path = tmp_path / "device.csv"
    write_simulation(sim, path)
    return path


def _names(sim):
    n, e = sim.truth["n_sites"], len(sim.truth["graph"]["edges"])
    return dict(onsite=[f"model_f{k}" for k in range(1, n + 1)],
                couplings=[f"model_g{k}" for k in range(1, e + 1)],
                prior=[f"model_E{k}" for k in range(1, n + 1)],
                targets=[f"measured_E{k}" for k in range(1, n + 1)],
                qubit=[f"v_q{k}" for k in range(1, n + 1)],
                coupler=[f"v_c{k}" for k in range(1, e + 1)])


def test_csv_dataset_on_a_grid(tmp_path):
    sim = simulate(None, 30, device_seed=1, topology="grid", shape=(2, 3))
    path, c = _csv(tmp_path, sim), _names(sim)
    common = dict(prior=c["prior"], targets=c["targets"], features=c["qubit"] + c["coupler"],
                  test_fraction=0.3, onsite=c["onsite"], couplings=c["couplings"],
                  qubit_features=c["qubit"], coupler_features=c["coupler"])
    ds = load_csv_dataset(path, topology="grid", shape=[2, 3], **common)
    assert ds.hamiltonian.graph.edges == CouplingGraph.grid(2, 3).edges
    lam = graph_spectrum(ds.hamiltonian.onsite, ds.hamiltonian.couplings, ds.hamiltonian.graph)[0]
    assert np.abs(lam - ds.prior.to_numpy()).max() < 1e-6
    explicit = load_csv_dataset(path, edges=sim.truth["graph"]["edges"], **common)
    assert explicit.hamiltonian.edge_list == sim.truth["graph"]["edges"]
    for kwargs, match in [(dict(topology="grid", shape=[3, 3]), "grid shape 3x3 has 9 sites"),
                          (dict(), "a chain of 6 sites has 5 couplings, got 7"),
                          (dict(edges=[[0, 1], [1, 9]]), "out of range"),
                          (dict(topology="ring"), "a ring of 6 sites has 6 couplings, got 7")]:
        with pytest.raises(DatasetError, match=match) as err:
            load_csv_dataset(path, **{**common, **kwargs})
        assert "\n" not in str(err.value)


def test_simulator_topologies_and_truth(tmp_path):
    ring = simulate(6, 20, device_seed=2, topology="ring")
    assert ring.truth["graph"]["edges"][-1] == [5, 0]
    assert ring.truth["mechanisms"]["next_nearest_coupling"]["pairs"][0] == [0, 2]
    grid = simulate(None, 20, device_seed=2, topology="grid", shape=(3, 3))
    pairs = grid.truth["mechanisms"]["next_nearest_coupling"]["pairs"]
    assert pairs == [list(p) for p in CouplingGraph.grid(3, 3).parasitic_edges("diagonal")]
    assert "v_c12" in grid.data.columns and "model_g12" in grid.data.columns
    c = _names(grid)
    prior = graph_spectrum(grid.data[c["onsite"]], grid.data[c["couplings"]],
                           CouplingGraph.grid(3, 3))[0]
    assert np.abs(prior - grid.data[c["prior"]].to_numpy()).max() < 1e-9
    out = tmp_path / "g.csv"
    assert main(["simulate", "--topology", "grid", "--shape", "2x3", "--experiments", "12",
                 "--out", str(out)]) == 0
    truth = json.loads((tmp_path / "g.truth.json").read_text())
    assert truth["graph"]["shape"] == [2, 3] and truth["n_sites"] == 6
    assert main(["simulate", "--topology", "grid", "--shape", "2by3", "--out", str(out)]) == 2


@pytest.fixture(scope="module")
def parasitic_grid():
    """A 3x3 grid whose only departure from the control model is diagonal couplings."""
    mm = Mismatch(next_nearest_coupling=0.05, noise_sd=0.05)
    sim = simulate(None, 300, device_seed=3, topology="grid", shape=(3, 3), mismatch=mm)
    return sim


def test_injected_parasitic_coupling_is_recovered(parasitic_grid):
    sim = parasitic_grid
    c, d = _names(sim), sim.data
    train, test = d.iloc[:200], d.iloc[200:]
    edges = sim.truth["graph"]["edges"]
    model = HamiltonianParameterRegressor(onsite=c["onsite"], couplings=c["couplings"],
                                          edges=edges, parasitic="diagonal", alpha=0.1)
    model.fit(train, train[c["targets"]])
    mech = sim.truth["mechanisms"]["next_nearest_coupling"]
    graph = CouplingGraph.grid(3, 3)
    corrected = model.corrected_parameters(test)
    table = model.coefficient_table()
    g = test[c["couplings"]].to_numpy()
    for (i, j), eta in zip(mech["pairs"], mech["eta"]):
        bridge = np.mean([np.sqrt(np.abs(g[:, a] * g[:, b])) for a, b in graph.paths2(i, j)],
                         axis=0)
        true = -eta * bridge
        name = f"{c['onsite'][i]}~{c['onsite'][j]}"
        assert name in model.parameter_names_ and name in set(table["parameter"])
        fitted = corrected[name].to_numpy()
        assert np.abs(fitted - true).mean() < 0.1 * np.abs(true).mean(), name
    control = model.control_parameters(test)
    assert (control[model.parasitic_] == 0).all().all()
    mae = np.abs(model.predict(test) - test[c["targets"]].to_numpy()).mean()
    prior_mae = np.abs(test[c["prior"]].to_numpy() - test[c["targets"]].to_numpy()).mean()
    assert mae < 0.3 * prior_mae


def test_linearised_selection_on_a_small_grid_keeps_the_parasitic_couplings(parasitic_grid):
    sim = parasitic_grid
    c, d = _names(sim), sim.data.iloc[:200]
    edges = sim.truth["graph"]["edges"]
    common = dict(onsite=c["onsite"], couplings=c["couplings"], edges=edges,
                  parasitic="diagonal", alpha=0.1)
    pool = candidate_pool(c["onsite"], c["couplings"], c["qubit"], c["coupler"], base=None,
                          edges=edges, parasitic="diagonal")
    assert pool["model_f1~model_f5"][:2] == ["sqrt|model_g1*model_g8|",
                                              "sqrt|model_g7*model_g3|"]
    start = default_library(c["onsite"], c["couplings"], edges)
    res = forward_select(d, d[c["targets"]], candidates=pool, start=start, cv=3,
                         method="linearised", max_steps=4, random_state=0, **common)
    chosen = {p for p, _ in res.selected}
    assert any("~" in p for p in chosen)  # CV keeps parasitic couplings
    assert res.path["cv_mae"].iloc[-1] < res.path["cv_mae"].iloc[0]
    model = HamiltonianSelectionCV(HamiltonianParameterRegressor(**common), candidates=pool,
                                   start=start, cv=3, max_steps=2, method="linearised",
                                   random_state=0)
    model.fit(d, d[c["targets"]])
    assert model.estimator_.parasitic_ and model.predict(d).shape == (len(d), 9)


def test_linearised_selection_on_the_chain_matches_refit_closely():
    sim = simulate(4, 90, device_seed=5, mismatch=Mismatch.only("crosstalk", "noise"))
    c, d = _names(sim), sim.data
    common = dict(onsite=c["onsite"], couplings=c["couplings"], loss="huber", huber_delta=0.5)
    pool = candidate_pool(c["onsite"], c["couplings"], c["qubit"], c["coupler"], base=None)
    start = default_library(c["onsite"], c["couplings"])
    runs = {m: forward_select(d, d[c["targets"]], candidates=pool, start=start, cv=3,
                              max_steps=2, random_state=0, method=m, **common)
            for m in ("refit", "linearised")}
    assert runs["linearised"].cv_mae <= runs["refit"].cv_mae + 0.02
    assert runs["linearised"].selected[0] == runs["refit"].selected[0]
    with pytest.raises(ValueError, match="unknown selection method 'greedy'"):
        forward_select(d, d[c["targets"]], candidates=pool, method="greedy", **common)


def test_regressor_on_a_ring_and_bad_parasitic():
    sim = simulate(5, 160, device_seed=4, topology="ring",
                   mismatch=Mismatch.only("coupler_frequency_shift"))
    c, d = _names(sim), sim.data
    edges = sim.truth["graph"]["edges"]
    model = HamiltonianParameterRegressor(onsite=c["onsite"], couplings=c["couplings"],
                                          edges=edges)
    model.fit(d.iloc[:120], d.iloc[:120][c["targets"]])
    assert model.covariate_names_["model_f1"] == [
        "intercept", "model_f1", "model_f1^2", "model_g1", "model_g1^2", "model_g5",
        "model_g5^2"]
    assert model.covariate_names_["model_g5"] == ["intercept", "model_g5", "model_g5^2",
                                                       "model_f1-model_f5"]
    test = d.iloc[120:]
    mae = np.abs(model.predict(test) - test[c["targets"]].to_numpy()).mean()
    prior = np.abs(test[c["prior"]].to_numpy() - test[c["targets"]].to_numpy()).mean()
    assert mae < 0.25 * prior
    for kwargs, match in [(dict(parasitic="third"), "'parasitic' parameter .* Got 'third'"),
                          (dict(parasitic=[[0, 1]]), "duplicate"),
                          (dict(edges=edges[:-1]), "couplings must name len\\(edges\\) = 4")]:
        with pytest.raises(ValueError, match=match):
            HamiltonianParameterRegressor(onsite=c["onsite"], couplings=c["couplings"],
                                          **{"edges": edges, **kwargs}).fit(d, d[c["targets"]])
    assert isinstance(model.coef_, pd.DataFrame)


def test_config_keys_for_graphs_and_parasitic_couplings(tmp_path):
    from workbench.experiment.config import ConfigError, load_dataset
    from workbench.experiment.families.hamiltonian import make_hamiltonian
    from workbench.experiment.runs.prepare import parse_config
    sim = simulate(None, 60, device_seed=6, topology="grid", shape=(2, 3))
    write_simulation(sim, tmp_path / "grid.csv")
    c = _names(sim)
    data = {"csv": "grid.csv", "prior": c["prior"], "targets": c["targets"],
            "features": c["qubit"] + c["coupler"], "test_fraction": 0.3,
            "hamiltonian": {"onsite": c["onsite"], "couplings": c["couplings"],
                            "qubit_features": c["qubit"], "coupler_features": c["coupler"],
                            "topology": "grid", "shape": [2, 3]}}
    raw = {"name": "grid", "random_state": 0, "data": data,
           "model": {"family": "hamiltonian", "basis": "ridge",
                     "hamiltonian": {"parasitic": "diagonal", "selection": "linearised",
                                     "max_steps": 1, "selection_cv": 3}},
           "selection": {"cv": 3}}
    cfg = parse_config(raw, tmp_path / "grid.toml")
    ds = load_dataset(cfg)
    model = make_hamiltonian(cfg.family_settings, ds, random_state=0)
    assert model.method == "linearised" and model.regressor.parasitic == "diagonal"
    assert model.regressor.edges == sim.truth["graph"]["edges"]
    assert "model_f1~model_f5" in model.candidates
    for ham, match in [({"shape": [3, 3]}, "grid shape 3x3 has 9 sites"),
                       ({"topology": "ring", "shape": None}, None),
                       ({"topology": "chain", "shape": None, "edges": [[0, 7]]}, "out of range"),
                       ({"topology": "star"}, r"data\.hamiltonian\.topology = 'star'")]:
        bad = {**raw, "data": {**data, "hamiltonian": {**data["hamiltonian"], **ham}}}
        bad["data"]["hamiltonian"] = {k: v for k, v in bad["data"]["hamiltonian"].items()
                                      if v is not None}
        if match is None:  # a valid graph whose coupling count does not match the columns
            match = r"couplings: the ring graph of 6 sites has 6 edges, got 7 column"
        with pytest.raises(ConfigError, match=match) as err:
            parse_config(bad, tmp_path / "grid.toml")
        assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match=r"model\.hamiltonian\.parasitic.*'third'"):
        parse_config({**raw, "model": {**raw["model"], "hamiltonian": {"parasitic": "third"}}},
                     tmp_path / "grid.toml")
