"""CSV datasets: schema, split, and a message that names the problem for every bad input."""

import json

import numpy as np
import pandas as pd
import pytest

from workbench.datasets import DatasetError, load_csv_dataset
from workbench.experiment.cli import main
from workbench.simulate import simulate, write_simulation

PRIOR = ["p1", "p2"]
TARGETS = ["t1", "t2"]


def _frame(n=20):
    rng = np.random.default_rng(0)
    t = rng.normal(size=(n, 2))
    return pd.DataFrame({"v1": rng.normal(size=n), "p1": t[:, 0] + 0.1, "p2": t[:, 1] - 0.1,
                         "t1": t[:, 0], "t2": t[:, 1],
                         "split": ["train"] * (n - 5) + ["test"] * 5})


@pytest.fixture
def csv_file(tmp_path):
    path = tmp_path / "lab.csv"
    _frame().to_csv(path, index=False)
    return path


def _load(path, **kw):
    args = dict(prior=PRIOR, targets=TARGETS, features=["v1"], split_column="split")
    args.update(kw)
    return load_csv_dataset(path, **args)


def test_schema_and_split_column(csv_file):
    ds = _load(csv_file)
    assert ds.prior_names == PRIOR and ds.target_names == TARGETS and ds.feature_names == ["v1"]
    assert len(ds.train_index) == 15 and len(ds.test_index) == 5
    assert list(ds.X.columns) == ["v1", "p1", "p2"]
    assert ds.hamiltonian is None and ds.name == "lab"


def test_seeded_test_fraction(csv_file):
    a = _load(csv_file, split_column=None, test_fraction=0.25, split_seed=3)
    b = _load(csv_file, split_column=None, test_fraction=0.25, split_seed=3)
    c = _load(csv_file, split_column=None, test_fraction=0.25, split_seed=4)
    assert len(a.test_index) == 5 and len(a.train_index) == 15
    np.testing.assert_array_equal(a.test_index, b.test_index)
    assert not np.array_equal(a.test_index, c.test_index)
    assert set(a.test_index).isdisjoint(a.train_index)


def test_numbers_read_at_once_equal_the_text_reading(tmp_path, monkeypatch):
    """A clean file is read by pandas' parser at once; its dataset is the one the checked text
    reading (which names problems) makes, to the last bit; ragged spaces and cells such as
    "nan" or "" fall back to the text reading and its messages."""
    from workbench.datasets import csv as csv_module

    path = tmp_path / "sim.csv"
    write_simulation(simulate(3, 200, device_seed=1), path)
    args = dict(prior=["model_E1", "model_E2", "model_E3"],
                targets=["measured_E1", "measured_E2", "measured_E3"],
                features=["v_q1", "v_q2", "v_q3", "v_c1", "v_c2"], test_fraction=0.3)
    fast = load_csv_dataset(path, **args)
    monkeypatch.setattr(csv_module, "_read_numbers", lambda *a: None)
    slow = load_csv_dataset(path, **args)
    for part in ("features", "prior", "targets"):
        pd.testing.assert_frame_equal(getattr(fast, part), getattr(slow, part),
                                      check_exact=True)
    np.testing.assert_array_equal(fast.test_index, slow.test_index)
    monkeypatch.undo()
    assert csv_module._read_numbers(path, ["v_q1"], []) is not None
    frame = _frame()
    frame.loc[3, "p1"] = np.nan  # written as an empty cell: not a number, no fast read
    frame.to_csv(path, index=False)
    assert csv_module._read_numbers(path, PRIOR, ["split"]) is None


def _write(tmp_path, text):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    return path


@pytest.mark.parametrize("mutate, kwargs, match", [
    (None, dict(prior=["p1"]), r"1 prior column\(s\) \['p1'\] for 2 target\(s\)"),
    (None, dict(targets=["t1", "t9"]), r"missing column\(s\) \['t9'\]; the file has columns"),
    (None, dict(features=["v1", "volts"]), r"missing column\(s\) \['volts'\]"),
    (None, dict(features=["p1"]), r"column\(s\) \['p1'\] named in more than one role"),
    (None, dict(split_column="fold"), r"missing column\(s\) \['fold'\]"),
    (None, dict(split_column=None), "give exactly one of test_fraction or split_column"),
    (None, dict(split_column=None, test_fraction=0.01), "the test split is empty"),
    (lambda f: f.assign(split="train"), {}, "the test split is empty"),
    (lambda f: f.assign(split=["train"] * 19 + ["validate"]), {},
     r"must hold 'train' or 'test'; other values at line 21$"),
    (lambda f: f.assign(t2=["abc"] + list(f.t2[1:])), {},
     r"column 't2' has non-numeric values at line 2$"),
    (lambda f: f.assign(p1=list(f.p1[:3]) + [np.nan] + list(f.p1[4:])), {},
     r"NaN or infinite values in column\(s\) \['p1'\] at line 5"),
    (lambda f: f.assign(t1=list(f.t1[:6]) + [1e308] + list(f.t1[7:])), {},
     r"column\(s\) \['t1'\] hold values beyond \+-1e\+150 at line 8: .*check the units"),
    (lambda f: f.assign(v1=[np.inf] + list(f.v1[1:])), {},
     r"NaN or infinite values in column\(s\) \['v1'\] at line 2"),
    (None, dict(onsite=["p1", "p2"]), "give both onsite and couplings"),
    (None, dict(onsite=["p1", "p2"], couplings=["t1", "t2"]),
     "a chain of 2 sites has 1 couplings, got 2"),
])
def test_bad_input_is_named(tmp_path, mutate, kwargs, match):
    frame = _frame()
    if mutate is not None:
        frame = mutate(frame)
    path = tmp_path / "lab.csv"
    frame.to_csv(path, index=False)
    before = path.read_bytes()
    with pytest.raises(DatasetError, match=match):
        _load(path, **kwargs)
    assert path.read_bytes() == before  # nothing touched


@pytest.mark.parametrize("text, match", [
    ("", "is empty"),
    ("p1,p2,t1,t2,v1,split\n", "has a header but no rows"),
    ("p1,p1,t1,t2,v1,split\n1,2,3,4,5,train\n", r"duplicated column names \['p1'\]"),
    ('p1,p2,t1,t2,v1,split\n1,2,3,4,5,train,9,9\n"1,2\n', "not a well-formed CSV"),
])
def test_empty_duplicated_and_malformed_files(tmp_path, text, match):
    with pytest.raises(DatasetError, match=match):
        _load(_write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(DatasetError, match="CSV file not found: .*nope.csv"):
        _load(tmp_path / "nope.csv")


def _config(tmp_path, csv_name, extra_data="", cv=5):
    cfg = tmp_path / "sim.toml"
    cfg.write_text(f"""
name = "sim"
random_state = 0
[data]
csv = "{csv_name}"
prior = ["model_E1", "model_E2", "model_E3"]
targets = ["measured_E1", "measured_E2", "measured_E3"]
features = ["v_q1", "v_q2", "v_q3", "v_c1", "v_c2"]
{extra_data}
[data.hamiltonian]
onsite = ["model_f1", "model_f2", "model_f3"]
couplings = ["model_g1", "model_g2"]
[model]
basis = "kernel_ridge"
basis_params = {{ alpha = 0.1, gamma = 0.05 }}
n_stages = 2
basis_inputs = "prior+features"
input_transform = "standard"
[selection]
cv = {cv}
""")
    return cfg


def test_simulated_csv_evaluates_through_a_config(tmp_path, capsys):
    assert main(["simulate", "--sites", "3", "--experiments", "200", "--device-seed", "1",
                 "--out", str(tmp_path / "dev.csv")]) == 0
    assert (tmp_path / "dev.truth.json").is_file()
    cfg = _config(tmp_path, "dev.csv", "test_fraction = 0.3")
    out = tmp_path / "out.json"
    assert main(["evaluate", str(cfg), "--json", str(out), "--no-track"]) == 0
    res = json.loads(out.read_text())
    assert res["targets"] == ["measured_E1", "measured_E2", "measured_E3"]
    assert res["n_train"] == 140 and res["n_test"] == 60
    assert len(res["prior"]["test_mae"]) == len(res["model"]["test_mae"]) == 3
    assert res["model"]["test_mae_avg"] < res["prior"]["test_mae_avg"]
    assert "measured_E3" in capsys.readouterr().out


@pytest.mark.parametrize("extra, cv, match", [
    ("test_fraction = 0.3", 50, r"training split has 14 rows, too few for \[selection\] cv = 50"),
    ("test_fraction = 0.0", 5, r"data\.test_fraction = 0\.0: Input should be greater than 0"),
    ('split_column = "nope"', 5, r"missing column\(s\) \['nope'\]"),
])
def test_bad_data_from_the_command_line_is_one_line(tmp_path, capsys, extra, cv, match):
    write_simulation(simulate(3, 20, device_seed=0), tmp_path / "small.csv")
    cfg = _config(tmp_path, "small.csv", extra, cv=cv)
    out = tmp_path / "out.json"
    assert main(["evaluate", str(cfg), "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("workbench: error:")
    assert pd.Series(err).str.contains(match).all(), err
    assert not out.exists()


def test_config_rejects_incomplete_csv_data(tmp_path):
    from workbench.experiment.config import ConfigError
    from workbench.experiment.runs.prepare import load_config

    cfg = tmp_path / "c.toml"
    cfg.write_text('[data]\ncsv = "x.csv"\ntargets = ["a"]\ntest_fraction = 0.2\n')
    with pytest.raises(ConfigError, match="needs 'prior'"):
        load_config(cfg)
    cfg.write_text('[data]\ncsv = "x.csv"\nprior = ["a", "b"]\ntargets = ["c"]\n'
                   'test_fraction = 0.2\n')
    with pytest.raises(ConfigError, match=r"2 prior column\(s\) for 1 target\(s\)"):
        load_config(cfg)
    cfg.write_text('[data]\nsource = "google_5q"\ncsv = "x.csv"\n')
    with pytest.raises(ConfigError, match="apply to source = \"csv\" only"):
        load_config(cfg)
