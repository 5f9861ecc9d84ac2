"""The device simulator: schema, determinism, mismatch mechanisms, I/O, and boosting on it."""

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import workbench
from workbench.simulate import MECHANISMS, Mismatch, Simulation, measure, simulate, write_simulation


def _cols(d, prefix, n):
    return d[[f"{prefix}{k}" for k in range(1, n + 1)]].to_numpy()


def prior_mae(sim: Simulation) -> float:
    n, d = sim.truth["n_sites"], sim.data
    return float(np.abs(_cols(d, "model_E", n) - _cols(d, "measured_E", n)).mean())


def test_same_seed_is_identical_and_other_seed_differs():
    a, b = simulate(5, 50, device_seed=3), simulate(5, 50, device_seed=3)
    pd.testing.assert_frame_equal(a.data, b.data, check_exact=True)
    assert a.truth == b.truth
    c = simulate(5, 50, device_seed=4)
    assert not np.allclose(a.data.to_numpy(), c.data.to_numpy())
    assert a.truth["device"] != c.truth["device"]


@pytest.mark.parametrize("n", [2, 5, 7])
def test_columns_and_shape(n):
    sim = simulate(n, 11, device_seed=1)
    expected = ([f"v_q{k}" for k in range(1, n + 1)] + [f"v_c{k}" for k in range(1, n)]
                + [f"model_f{k}" for k in range(1, n + 1)] + [f"model_g{k}" for k in range(1, n)]
                + [f"model_E{k}" for k in range(1, n + 1)]
                + [f"measured_E{k}" for k in range(1, n + 1)])
    assert list(sim.data.columns) == expected
    assert sim.data.shape == (11, len(expected))
    assert np.isfinite(sim.data.to_numpy()).all()
    assert sim.truth["n_sites"] == n and sim.truth["n_experiments"] == 11
    assert sim.truth["sign"] == -1 and sim.truth["device_seed"] == 1


def test_invalid_arguments():
    with pytest.raises(ValueError, match="n_sites"):
        simulate(1, 10)
    with pytest.raises(ValueError) as err:
        Mismatch.only("crosstalk", "gremlins")
    assert "gremlins" in str(err.value)
    assert all(name in str(err.value) for name in MECHANISMS)
    with pytest.raises(ValueError):
        Mismatch(noise_sd=-1.0)


def test_mismatch_constructors():
    assert all(v == 0 for v in dataclasses.asdict(Mismatch.none()).values())
    assert all(v > 0 for v in dataclasses.asdict(Mismatch.default()).values())
    sub = Mismatch.only("crosstalk", "noise")
    assert sub.crosstalk == Mismatch.default().crosstalk
    assert sub.noise_sd == Mismatch.default().noise_sd
    assert sub.drift == sub.misidentified_rate == 0
    assert simulate(5, 5, device_seed=0).truth["mismatch"] == Mismatch.default().to_dict()


def test_no_mismatch_means_the_prior_is_exact():
    sim = simulate(5, 200, device_seed=2, mismatch=Mismatch.none())
    assert prior_mae(sim) < 1e-9


@pytest.mark.parametrize("name", list(MECHANISMS))
def test_each_mechanism_alone_makes_the_prior_wrong(name):
    sim = simulate(5, 500, device_seed=5, mismatch=Mismatch.only(name))
    assert prior_mae(sim) > 1e-3


@pytest.mark.parametrize("field", ["drift", "crosstalk", "coupler_nonlinearity",
                                   "coupler_frequency_shift", "next_nearest_coupling",
                                   "noise_sd"])
def test_prior_error_grows_with_strength(field):
    one = Mismatch(**{field: getattr(Mismatch.default(), field)})
    three = Mismatch(**{field: 3 * getattr(Mismatch.default(), field)})
    mae1 = prior_mae(simulate(5, 500, device_seed=6, mismatch=one))
    mae3 = prior_mae(simulate(5, 500, device_seed=6, mismatch=three))
    assert mae3 > 1.5 * mae1 > 0


def test_default_prior_error_is_realistic_and_values_in_range():
    sim = simulate(5, 1000, device_seed=0)
    assert 0.3 < prior_mae(sim) < 5
    d = sim.data
    for prefix in ("model_E", "measured_E"):
        assert (np.diff(_cols(d, prefix, 5), axis=1) >= 0).all()
    f, g = _cols(d, "model_f", 5), _cols(d, "model_g", 4)
    assert 5800 < f.min() and f.max() < 6100
    assert -80 < g.min() and g.max() < 0
    assert (-6200 < _cols(d, "model_E", 5)).all() and (_cols(d, "model_E", 5) < -5700).all()
    assert (np.abs(_cols(d, "v_q", 5)) <= 0.015).all()
    assert ((0.10 <= _cols(d, "v_c", 4)) & (_cols(d, "v_c", 4) <= 0.22)).all()


def test_truth_records_misidentified_peaks():
    sim = simulate(5, 400, device_seed=7, mismatch=Mismatch(misidentified_rate=0.1))
    peaks = sim.truth["mechanisms"]["misidentified_peaks"]
    rows = np.array(peaks["rows"])
    assert 10 < len(rows) < 80 and len(peaks["level"]) == len(rows)
    assert all(1 <= k <= 5 for k in peaks["level"])
    err = np.abs(_cols(sim.data, "model_E", 5) - _cols(sim.data, "measured_E", 5)).sum(axis=1)
    assert (err[rows] > 2.9).all()
    assert np.delete(err, rows).max() < 1e-9


def test_write_simulation_round_trips(tmp_path):
    sim = simulate(5, 30, device_seed=8)
    csv, truth = write_simulation(sim, tmp_path / "dev.csv")
    assert csv == tmp_path / "dev.csv" and truth == tmp_path / "dev.truth.json"
    back = pd.read_csv(csv)
    assert list(back.columns) == list(sim.data.columns)
    np.testing.assert_allclose(back.to_numpy(), sim.data.to_numpy(), rtol=0, atol=1e-9)
    loaded = json.loads(truth.read_text())
    assert loaded == sim.truth
    assert set(loaded["mechanisms"]) == set(MECHANISMS)
    assert not [p for p in tmp_path.iterdir() if p.name not in ("dev.csv", "dev.truth.json")]


def test_large_simulations_have_the_schema():
    """Their time and memory are measured by benchmarks/simulate_scaling.py, not here."""
    big = simulate(5, 100_000, device_seed=0)
    wide = simulate(50, 1_000, device_seed=0)
    assert big.data.shape == (100_000, 28) and wide.data.shape == (1_000, 298)
    assert (np.diff(_cols(wide.data, "measured_E", 50), axis=1) >= 0).all()


def test_base_boosting_beats_the_prior_on_simulated_data():
    d = simulate(5, 300, device_seed=0).data
    features = [c for c in d.columns if c.startswith("v_")] + [f"model_E{j}" for j in range(1, 6)]
    X = d[features]
    train, test = slice(0, 200), slice(200, 300)
    boosted, prior = [], []
    for j in range(1, 6):
        y = d[f"measured_E{j}"]
        # the voltages are ~0.01 V: ridge's default alpha=1 would shrink them away
        model = workbench.BaseBoostCV(workbench.BaseBoostRegressor(
            prior=f"model_E{j}", basis=workbench.make_basis("ridge", alpha=1e-6),
            basis_features=features, n_stages=3, random_state=0), cv=5)
        model.fit(X.iloc[train], y.iloc[train])
        boosted.append(np.abs(model.predict(X.iloc[test]) - y.iloc[test]).mean())
        prior.append(np.abs(X[f"model_E{j}"].iloc[test] - y.iloc[test]).mean())
    boosted, prior = np.array(boosted), np.array(prior)
    assert (boosted < prior).sum() >= 4, (boosted, prior)
    assert boosted.mean() < prior.mean()


# ---------------------------------------------------------------- measure(): chosen settings

NO_READOUT = dataclasses.replace(Mismatch.default(), noise_sd=0.0, misidentified_rate=0.0)


def test_measure_without_mismatch_reproduces_simulate_exactly():
    sim = simulate(5, 40, device_seed=3, mismatch=Mismatch.none())
    got = measure(sim.data, device_seed=3, mismatch=Mismatch.none())
    pd.testing.assert_frame_equal(got.data, sim.data, check_exact=True)
    assert got.truth == sim.truth


@pytest.mark.parametrize("kw", [dict(n_sites=5), dict(n_sites=4, topology="ring"),
                                dict(topology="grid", shape=(3, 3))])
def test_measure_has_the_same_true_physics_as_simulate(kw):
    sim = simulate(kw.get("n_sites"), 40, device_seed=4, mismatch=NO_READOUT,
                   **{k: v for k, v in kw.items() if k != "n_sites"})
    got = measure(sim.data[[c for c in sim.data.columns if c.startswith("v_")]], device_seed=4,
                  mismatch=NO_READOUT, **kw)
    assert list(got.data.columns) == list(sim.data.columns)
    np.testing.assert_allclose(got.data.to_numpy(), sim.data.to_numpy(), rtol=0, atol=1e-9)
    assert prior_mae(got) > 0.1  # the mismatch is on
    assert got.truth["device"] == sim.truth["device"]
    assert got.truth["mechanisms"] == sim.truth["mechanisms"]
    # default mismatch: the same device as simulate(seed)'s
    assert measure(sim.data, device_seed=4, **kw).truth["device"] == \
        simulate(kw.get("n_sites"), 3, device_seed=4,
                 **{k: v for k, v in kw.items() if k != "n_sites"}).truth["device"]


def test_measure_keeps_row_order_and_index_and_ignores_other_columns():
    sim = simulate(3, 12, device_seed=1, mismatch=NO_READOUT)
    settings = sim.data.iloc[::-1].set_axis([f"r{i}" for i in range(12)]).assign(note="x")
    got = measure(settings, device_seed=1, mismatch=NO_READOUT)
    assert list(got.data.index) == list(settings.index)
    np.testing.assert_allclose(got.data.to_numpy(), sim.data.iloc[::-1].to_numpy(), atol=1e-9)
    assert got.truth["n_experiments"] == 12


def test_measure_noise_is_repeatable_per_settings_and_independent_across_them():
    settings = simulate(4, 20, device_seed=2).data
    noisy = Mismatch.only("noise")
    a, b = (measure(settings, device_seed=2, mismatch=noisy),
            measure(settings, device_seed=2, mismatch=noisy))
    pd.testing.assert_frame_equal(a.data, b.data, check_exact=True)
    residual = _cols(a.data, "measured_E", 4) - _cols(a.data, "model_E", 4)
    assert 0.1 < residual.std() < 0.6
    other = settings.copy()
    other.loc[19, "v_q1"] += 1e-4  # one row changed: every row's noise is new
    c = measure(other, device_seed=2, mismatch=noisy)
    residual_c = _cols(c.data, "measured_E", 4) - _cols(c.data, "model_E", 4)
    assert not np.isclose(residual[:19], residual_c[:19]).any()
    assert not np.allclose(measure(settings, device_seed=3, mismatch=noisy).data, a.data)
    d = measure(settings, device_seed=2, mismatch=noisy, noise_seed=7)
    e = measure(other, device_seed=2, mismatch=noisy, noise_seed=7)
    pd.testing.assert_frame_equal(d.data, measure(settings, device_seed=2, mismatch=noisy,
                                                  noise_seed=7).data, check_exact=True)
    residual_e = _cols(e.data, "measured_E", 4) - _cols(e.data, "model_E", 4)
    np.testing.assert_allclose(residual_e[:19], (_cols(d.data, "measured_E", 4)
                                                 - _cols(d.data, "model_E", 4))[:19], atol=1e-9)


def test_measure_records_its_misidentified_rows_and_allows_any_voltage():
    settings = pd.DataFrame({"v_q1": np.linspace(-0.05, 0.05, 200), "v_q2": 0.03,
                             "v_q3": -0.02, "v_c1": 0.3, "v_c2": np.linspace(0.0, 0.3, 200)})
    got = measure(settings, device_seed=0, mismatch=Mismatch(misidentified_rate=0.2))
    assert np.isfinite(got.data.to_numpy()).all()
    peaks = got.truth["mechanisms"]["misidentified_peaks"]
    rows = np.array(peaks["rows"])
    assert 15 < len(rows) < 70 and got.truth["n_experiments"] == 200
    err = np.abs(_cols(got.data, "model_E", 3) - _cols(got.data, "measured_E", 3)).sum(axis=1)
    assert (err[rows] > 2.9).all() and np.delete(err, rows).max() < 1e-9


@pytest.mark.parametrize("change, match", [
    (lambda d: d.drop(columns=["v_c2", "v_q4"]),
     "v_q4, v_c2: the device has 5 sites (v_q1..v_q5) and 4 couplings (v_c1..v_c4)"),
    (lambda d: d.assign(v_q2=np.nan), "v_q2 hold NaN or infinite"),
    (lambda d: d.assign(v_c1=np.inf), "v_c1 hold NaN or infinite"),
    (lambda d: d.iloc[:0], "no rows"),
    (lambda d: d.assign(v_q3="a"), "v_q3 are not numeric"),
])
def test_measure_rejects_bad_settings(change, match):
    settings = simulate(5, 4, device_seed=0).data
    with pytest.raises(ValueError, match=re.escape(match)):
        measure(change(settings), n_sites=5)
    with pytest.raises(ValueError, match=re.escape("v_q1, v_q2, ... (a chain of >= 2 sites); "
                                                   "found 0")):
        measure(pd.DataFrame({"x": [1.0]}))


# ---------------------------------------------------------------- the command line

def test_simulate_command_mismatch_choices(tmp_path, capsys):
    from workbench.experiment.cli import main

    exact = tmp_path / "exact.csv"
    assert main(["simulate", "--sites", "3", "--experiments", "30", "--mismatch", "none",
                 "--out", str(exact)]) == 0
    assert "prior MAE 0.000 MHz" in capsys.readouterr().out
    data = pd.read_csv(exact)
    assert np.allclose(_cols(data, "model_E", 3), _cols(data, "measured_E", 3), atol=1e-9)
    two = tmp_path / "two.csv"
    assert main(["simulate", "--sites", "3", "--experiments", "30", "--mismatch", "crosstalk",
                 "noise", "--out", str(two)]) == 0
    truth = json.loads((tmp_path / "two.truth.json").read_text())
    on = {k for k, v in truth["mismatch"].items() if v}
    assert on == {MECHANISMS["crosstalk"], MECHANISMS["noise"]}


@pytest.mark.parametrize("args, match", [
    (["--mismatch", "gremlins"], "unknown mismatch mechanism(s) ['gremlins']; valid names are:"),
    (["--sites", "1"], "n_sites must be an integer >= 2"),
    (["--experiments", "0"], "n_experiments must be an integer >= 1"),
])
def test_simulate_command_bad_arguments_are_one_line(tmp_path, capsys, args, match):
    from workbench.experiment.cli import main

    out = tmp_path / "x.csv"
    assert main(["simulate", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("workbench: error:") and match in err[0]
    assert not list(tmp_path.iterdir())  # nothing written


def test_the_simulated_device_config_runs_as_documented(tmp_path, capsys):
    """experiments/simulated_device.toml reads ../data/simulated_device.csv, as the README's
    two commands make it."""
    import shutil

    from workbench.experiment.cli import main
    EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"

    (tmp_path / "experiments").mkdir()
    shutil.copy(EXPERIMENTS / "simulated_device.toml", tmp_path / "experiments")
    assert main(["simulate", "--sites", "5", "--experiments", "300", "--device-seed", "0", "--out",
                 str(tmp_path / "data" / "simulated_device.csv")]) == 0
    out = tmp_path / "out.json"
    assert main(["evaluate", str(tmp_path / "experiments" / "simulated_device.toml"),
                 "--json", str(out), "--no-track"]) == 0
    res = json.loads(out.read_text())
    assert res["n_train"] == 210 and res["n_test"] == 90
    assert res["model"]["test_mae_avg"] < res["prior"]["test_mae_avg"]


def test_pinned_values_of_the_current_simulator():
    """Numbers the simulator gave before measure() shared its physics: any refactor keeps them."""
    d = simulate(5, 7, device_seed=3).data
    sums = {"v_q1": 0.024524932, "v_c3": 0.977632862, "model_f2": 41973.356418756,
            "model_g4": -139.241730479, "model_E1": -42321.006186408,
            "measured_E1": -42306.020342683, "measured_E5": -41580.644049286}
    np.testing.assert_allclose(d[list(sums)].sum().to_numpy(), list(sums.values()),
                               rtol=0, atol=1e-8)
    np.testing.assert_allclose(d.iloc[2].to_numpy(), [
        0.008223144489309553, -0.003190056210174423, -0.014411987443451714,
        0.0008324979964050988, -0.008843025226497363, 0.14678258487762635, 0.18479828933204615,
        0.11057594125724629, 0.12027498069519968, 5977.11662958491, 5999.768427310657,
        5982.938518460515, 6012.192027437908, 5989.956322836172, -18.615257816019707,
        -46.93832944370361, -2.882447008943977, -5.913723071559096, -6042.344819115152,
        -6013.65035290917, -5988.4896674782685, -5977.904098411203, -5939.582987716369,
        -6039.9514544890635, -6012.357920373651, -5989.840723935878, -5978.172193460187,
        -5940.731543592296], rtol=1e-12, atol=0)
    grid = simulate(None, 4, device_seed=1, topology="grid", shape=(3, 3))
    np.testing.assert_allclose(grid.data.filter(like="measured_E").sum().to_numpy(), [
        -24330.456883837367, -24197.494771832604, -24126.808707688782, -24042.054374198637,
        -23984.205174797487, -23907.590898299906, -23792.9279891536, -23690.842536547014,
        -23566.454076465358], rtol=1e-12, atol=0)
    np.testing.assert_allclose(grid.data.filter(like="model_E").iloc[1].to_numpy(), [
        -6123.131589790042, -6056.01093868448, -6038.750024717391, -6023.280360878772,
        -6006.994996285831, -5979.199151816335, -5935.8990581843445, -5928.290930774677,
        -5878.351802471527], rtol=1e-12, atol=0)
    np.testing.assert_allclose(grid.truth["mechanisms"]["next_nearest_coupling"]["eta"], [
        0.01637961542011547, 0.020245066136928707, 0.02075396150170699, 0.03110916238715378,
        0.028531166585141734, 0.043718831017606125, 0.043624540105999275,
        0.03889638331405291], rtol=1e-12, atol=0)
    bad = simulate(4, 12, device_seed=11, mismatch=Mismatch(misidentified_rate=0.3, noise_sd=0.3,
                                                      drift=0.6))
    peaks = bad.truth["mechanisms"]["misidentified_peaks"]
    assert peaks["rows"] == [1, 6, 9, 10, 11] and peaks["level"] == [4, 1, 1, 3, 4]
    np.testing.assert_allclose(peaks["shift_MHz"], [4.451520493109941, -9.068838111256635,
                               5.838578633819728, -8.162310344559463, 9.795142402690537],
                               rtol=1e-12, atol=0)
    np.testing.assert_allclose(bad.data.filter(like="measured_E").sum().to_numpy(), [
        -72453.99782001805, -71944.03263243735, -71615.54130196582, -71024.39304592136],
        rtol=1e-12, atol=0)


def test_simulate_command_measures_settings(tmp_path, capsys):
    from workbench.experiment.cli import main

    first, again = tmp_path / "first.csv", tmp_path / "again.csv"
    common = ["--device-seed", "5", "--mismatch", "drift", "crosstalk"]
    assert main(["simulate", "--sites", "4", "--experiments", "30", *common,
                 "--out", str(first)]) == 0
    capsys.readouterr()
    assert main(["simulate", "--settings", str(first), *common, "--out", str(again)]) == 0
    line = capsys.readouterr().out
    assert "measured 30 settings, 4 sites, chain; prior MAE" in line
    a, b = pd.read_csv(first), pd.read_csv(again)
    assert list(a.columns) == list(b.columns)
    np.testing.assert_allclose(_cols(b, "model_E", 4), _cols(a, "model_E", 4), rtol=0, atol=1e-9)
    np.testing.assert_allclose(_cols(b, "measured_E", 4), _cols(a, "measured_E", 4), rtol=0,
                               atol=1e-9)
    assert np.abs(_cols(b, "measured_E", 4) - _cols(b, "model_E", 4)).mean() > 0.01
    truth_a = json.loads((tmp_path / "first.truth.json").read_text())
    truth_b = json.loads((tmp_path / "again.truth.json").read_text())
    assert truth_b["device"] == truth_a["device"] and truth_b["n_experiments"] == 30
    noisy = tmp_path / "noisy.csv"
    for _ in range(2):
        assert main(["simulate", "--settings", str(first), "--device-seed", "5",
                     "--noise-seed", "9", "--out", str(noisy)]) == 0
        assert np.isfinite(pd.read_csv(noisy).to_numpy()).all()


@pytest.mark.parametrize("content, extra, match", [
    (None, ["--experiments", "10"], "--settings measures the rows of its CSV; drop --experiments"),
    ("", [], "settings.csv is empty: expected a header row"),
    ("v_q1,v_q2,v_c1\n", [], "settings.csv has a header but no rows"),
    ("v_q1,v_q2,v_c1\n0,0,0.1\n0,0,0.1,5,6\n", [], "is not a well-formed CSV file"),
    ("v_q1;v_q2;v_c1\n0;0;0.1\n", [], "wrong delimiter?"),
    ("\x00\x93binary\n", [], "does not look like a CSV file"),
    ("v_q1,v_q2,v_c1\n0,0,0.1\n0,zero,0.1\n", [], "column 'v_q2' has non-numeric values"),
    ("v_q1,v_q2,v_q3\n0,0,0\n", [], "v_c1, v_c2: the device has 3 sites (v_q1..v_q3) and 2 "
     "couplings"),
    ("v_q1,v_q2,v_c1\n0,0,0.1\n0,,0.1\n", [],
     "NaN or infinite values in column(s) ['v_q2'] at line 3"),
    ("v_q1,v_q2,v_c1\n0,0,0.1\n", ["--sites", "3"], "lack the bias column(s) v_q3, v_c2"),
    ("v_q1,v_q2,v_c1\n0,0,0.1\n", ["--noise-seed", "-1"],
     "noise_seed must be an integer >= 0, got -1"),
    ("v_q1,v_q2,v_c1\n0,0,0.1\n", ["--settings", "missing.csv"], "CSV file not found"),
])
def test_simulate_command_bad_settings_are_one_line(tmp_path, capsys, content, extra, match):
    from workbench.experiment.cli import main

    settings = tmp_path / "settings.csv"
    if content is not None:
        settings.write_text(content)
    out = tmp_path / "x.csv"
    assert main(["simulate", "--settings", str(settings), *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("workbench: error:") and match in err[0], err
    assert not out.exists() and not (tmp_path / "x.truth.json").exists()


def test_simulate_command_noise_seed_needs_settings(tmp_path, capsys):
    from workbench.experiment.cli import main

    assert main(["simulate", "--noise-seed", "1", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--noise-seed needs --settings" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
