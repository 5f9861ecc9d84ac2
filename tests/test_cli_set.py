"""``--set SECTION.KEY=VALUE`` on evaluate, sweep and design: typed and checked by the config
schema, logged as run params and in the logged config; and the Python API with overrides."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from mlflow import MlflowClient

from workbench.experiment.cli import main

ROOT = Path(__file__).resolve().parents[1]
CONFIG = """\
name = "set_test"
random_state = 0

[data]
source = "google_5q"

[model]
basis = "ridge"
n_stages = 1
line_search_penalty = 0.1
input_transform = "quantile_normal"

[intervals]
enabled = false
"""


@pytest.fixture()
def cfg(tmp_path, google_5q_dir, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    path = tmp_path / "c.toml"
    path.write_text(CONFIG)
    return path


def _json(tmp_path, cfg, tag, *extra):
    out = tmp_path / f"{tag}.json"
    assert main(["evaluate", str(cfg), "--json", str(out), "--no-track", *extra]) == 0
    return json.loads(out.read_text())


def _edited(cfg, tmp_path, old, new):
    path = tmp_path / "edited.toml"
    path.write_text(cfg.read_text().replace(old, new))
    return path


def test_set_is_the_same_as_editing_the_file(cfg, tmp_path, capsys):
    """Two stages by --set give the numbers of a file that says two stages."""
    by_set = _json(tmp_path, cfg, "set", "--set", "model.n_stages=2",
                   "--set", "model.line_search_penalty=0.0")
    edited = _edited(cfg, tmp_path, "n_stages = 1\nline_search_penalty = 0.1",
                     "n_stages = 2\nline_search_penalty = 0.0")
    by_file = _json(tmp_path, edited, "file")
    plain = _json(tmp_path, cfg, "plain")
    assert by_set["model"] == by_file["model"]
    assert by_set["model"]["test_mae"] != plain["model"]["test_mae"]


@pytest.mark.parametrize("override, needles", [
    ("model.n_stagse=2", ["with --set model.n_stagse=2:", "unknown key(s) ['n_stagse']",
                          "valid keys are"]),
    ("model.n_stages=two", ["model.n_stages = 'two'", "valid integer"]),
    ("selection.cv=1", ["with --set selection.cv=1:", "selection.cv"]),
    ("model.n_stages", ["give SECTION.KEY=VALUE"]),
])
def test_bad_override_is_one_line(cfg, tmp_path, capsys, override, needles):
    out = tmp_path / "out.json"
    try:
        rc = main(["evaluate", str(cfg), "--json", str(out), "--no-track", "--set", override])
    except SystemExit as exc:  # argparse's own usage errors
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and not out.exists()
    lines = [line for line in err.strip().splitlines() if "error" in line]
    assert len(lines) == 1, err
    for needle in needles:
        assert needle in err, (needle, err)


def test_logged_as_params_and_config(cfg, tmp_path, capsys, monkeypatch, new_store):
    # without the family's learning curves and SHAP figures (most of the command's time; an
    # evaluate's are checked by test_cli.py): this test is about the params and the config
    from workbench.experiment.families import Artifacts
    from workbench.experiment.families.eigenvalue import EigenvalueFamily

    monkeypatch.setattr(EigenvalueFamily, "begin_artifacts",
                        lambda *args, **kwargs: lambda emit=None: Artifacts())
    uri = new_store(tmp_path / "mlflow.db")
    assert main(["evaluate", str(cfg), "--tracking-uri", uri,
                 "--set", "model.n_stages=2", "--set", 'model.loss="huber"']) == 0
    client = MlflowClient(uri)
    (run,) = client.search_runs([e.experiment_id for e in client.search_experiments()])
    assert run.data.params["set.model.n_stages"] == "2"
    assert run.data.params["set.model.loss"] == '"huber"'
    assert run.data.params["eeig1.loss"] == "huber"
    path = client.download_artifacts(run.info.run_id, "c.toml", str(tmp_path / "dl"))
    logged = Path(path).read_text()
    assert logged.startswith(f"# {cfg} with --set model.n_stages=2 model.loss=\"huber\"")
    assert tomllib.loads(logged)["model"]["n_stages"] == 2
    # the test rows' predictions and measured targets, what `workbench compare` pairs
    arts = {a.path for a in client.list_artifacts(run.info.run_id, "predictions")}
    assert arts == {"predictions/test.csv", "predictions/test_measured.csv"}


def test_sweep_and_design_take_set(cfg, tmp_path, capsys):
    parser_help = []
    for command in ("sweep", "design"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        parser_help.append(capsys.readouterr().out)
    assert all("--set SECTION.KEY=VALUE" in text for text in parser_help)
    # design with an override that breaks the config: checked before anything is read
    candidates = tmp_path / "cand.csv"
    candidates.write_text("x\n1\n")
    assert main(["design", str(cfg), "--candidates", str(candidates), "--n", "1",
                 "--out", str(tmp_path / "next.csv"), "--set", "model.basis=nope"]) == 2
    assert "basis" in capsys.readouterr().err and not (tmp_path / "next.csv").exists()


def test_python_api(cfg):
    """The API example: load_config with overrides, evaluate, the typed result."""
    from workbench.experiment.api import evaluate, load_config

    config = load_config(cfg, overrides={"model.n_stages": 2, "intervals.enabled": False})
    assert config.overrides == {"model.n_stages": 2, "intervals.enabled": False}
    result = evaluate(config)
    assert result.targets == [f"eeig{i}" for i in range(1, 6)]
    assert np.isfinite(result.model.avg("test_mae"))
