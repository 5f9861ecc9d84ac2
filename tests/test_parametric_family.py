"""Family ``parametric``: ``workbench init --model``, a CSV without prior columns, evaluate."""

import json

import numpy as np
import pandas as pd
import pytest

from workbench.experiment.cli import main

DECAY = """import numpy as np

PARAMETERS = {"amplitude": 2.0, "tau": 1.0, "offset": 0.0}


def predict(params, data):
    t = data["t"].to_numpy()
    return params["amplitude"] * np.exp(-t / params["tau"]) + params["offset"]
"""


@pytest.fixture
def decay_csv(tmp_path):
    """Decay whose lifetime drifts with temp; the CSV has no prior column."""
    rng = np.random.default_rng(0)
    n = 70
    t, temp = rng.uniform(0, 3, n), rng.normal(size=n)
    y = 2.5 * np.exp(-t / (1.5 + 0.3 * temp)) + 0.1 + rng.normal(0, 0.01, n)
    pd.DataFrame({"t": t, "temp": temp, "y": y}).to_csv(tmp_path / "decay.csv", index=False)
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "decay.py").write_text(DECAY)
    return tmp_path / "decay.csv"


def test_init_with_a_model_file_then_evaluate(decay_csv, tmp_path, capsys):
    config = tmp_path / "decay.toml"
    assert main(["init", str(decay_csv), "--model", str(tmp_path / "models" / "decay.py"),
                 "--target", "y", "--out", str(config)]) == 0
    text = config.read_text()
    assert 'family = "parametric"' in text and 'model = "models/decay.py"' in text
    assert "prior =" not in text  # the model is the prior
    out = tmp_path / "result.json"
    assert main(["evaluate", str(config), "--no-track", "--json", str(out),
                 "--out", str(tmp_path / "tables"), "--jobs", "1",
                 "--set", "model.parametric.max_steps=1",
                 "--set", "model.parametric.products=false",
                 "--set", "model.parametric.boost_stage=false"]) == 0
    result = json.loads(out.read_text())
    assert result["model"]["selected"] == ["parametric:drift"]
    info = result["parametric"]
    assert info["choice"] == "drift" and info["selection"]["path"][1]["parameter"] == "tau"
    assert result["model"]["test_mae"][0] < 0.2 * result["prior"]["test_mae"][0]
    choices = pd.read_csv(tmp_path / "tables" / "choices.csv")
    assert list(choices["candidate"]) == ["prior", "calibrated", "drift"]
    for table in ("calibration", "coefficients", "corrected_parameters", "selection_path"):
        assert (tmp_path / "tables" / f"{table}.csv").exists()


def test_a_bad_model_file_is_one_line(decay_csv, tmp_path, capsys):
    (tmp_path / "models" / "broken.py").write_text("PARAMETERS = {'a': 1.0}\n")
    config = tmp_path / "c.toml"
    config.write_text('[data]\ncsv = "decay.csv"\ntargets = ["y"]\nfeatures = ["t", "temp"]\n'
                      'test_fraction = 0.3\n[model]\nfamily = "parametric"\n'
                      '[model.parametric]\nmodel = "models/broken.py"\n')
    assert main(["evaluate", str(config), "--no-track"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "defines no predict" in err[0] and "broken.py" in err[0]


def test_init_needs_prior_or_model_not_both(decay_csv, tmp_path, capsys):
    args = ["init", str(decay_csv), "--target", "y", "--out", str(tmp_path / "x.toml")]
    assert main(args) == 2
    assert main([*args, "--prior", "t", "--model", str(tmp_path / "models" / "decay.py")]) == 2
    err = capsys.readouterr().err
    assert err.count("give either --prior") == 2
    assert not (tmp_path / "x.toml").exists()


def test_other_families_still_need_prior_columns(decay_csv, tmp_path, capsys):
    config = tmp_path / "c.toml"
    config.write_text('[data]\ncsv = "decay.csv"\ntargets = ["y"]\ntest_fraction = 0.3\n')
    assert main(["evaluate", str(config), "--no-track"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs 'prior'" in err[0] and "'eigenvalue'" in err[0]


def test_the_chain_model_file_is_the_control_program(google_5q):
    """experiments/models/chain.py at its start values (the control program's parameters)
    predicts the benchmark's prior; parametric_chain.toml reads it."""
    from pathlib import Path

    from workbench.experiment.runs.prepare import load_config
    from workbench.parametric import check_model, load_model

    root = Path(__file__).resolve().parents[1]
    model = load_model(root / "experiments" / "models" / "chain.py")
    X = google_5q.X_physics
    value, jac = check_model(model, X, 5)  # every parameter moves some eigenvalue
    np.testing.assert_allclose(value, google_5q.prior.to_numpy(), atol=1e-6)
    # Hellmann-Feynman: an onsite frequency's derivatives over the eigenvalues sum to -1
    np.testing.assert_allclose(jac[:, :, :5].sum(axis=1), -1.0, atol=1e-5)
    cfg = load_config(root / "experiments" / "parametric_chain.toml")
    assert cfg.family.name == "parametric"
    assert set(cfg.family_settings.candidates) == set(model.names)
