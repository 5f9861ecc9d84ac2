"""Family hamiltonian end to end: config, evaluate (CLI), tables, figures and MLflow."""

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from workbench.experiment.cli import main
from workbench.experiment.config import ConfigError, load_dataset
from workbench.experiment.runs.evaluate import evaluate
from workbench.experiment.runs.prepare import load_config, parse_config
from workbench.experiment.tracking.runs import Tracker
from workbench.fitted_prior import FittedPriorBoost
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.param_select import HamiltonianSelectionCV
from workbench.simulate import Mismatch, simulate, write_simulation

N = 5
DATA = {
    "csv": "device.csv",
    "prior": [f"model_E{i}" for i in range(1, N + 1)],
    "targets": [f"measured_E{i}" for i in range(1, N + 1)],
    "features": [f"v_q{i}" for i in range(1, N + 1)] + [f"v_c{i}" for i in range(1, N)],
    "test_fraction": 0.3,
    "hamiltonian": {"onsite": [f"model_f{i}" for i in range(1, N + 1)],
                    "couplings": [f"model_g{i}" for i in range(1, N)], "sign": -1,
                    "qubit_features": [f"v_q{i}" for i in range(1, N + 1)],
                    "coupler_features": [f"v_c{i}" for i in range(1, N)]},
}
FAST = {"candidates": "local", "max_steps": 3, "selection_cv": 3}


@pytest.fixture(scope="module")
def device(tmp_path_factory):
    folder = tmp_path_factory.mktemp("device")
    mismatch = Mismatch(coupler_frequency_shift=1.0, crosstalk=0.01, noise_sd=0.1)
    write_simulation(simulate(N, 150, device_seed=1, mismatch=mismatch), folder / "device.csv")
    return folder


def _raw(hamiltonian=None, evaluation=None, **model):
    raw = {"name": "ham", "random_state": 0, "data": dict(DATA),
           "model": {"family": "hamiltonian", "basis": "ridge",
                     "basis_inputs": "prior+features", "input_transform": "standard",
                     "hamiltonian": {**FAST, **(hamiltonian or {})}, **model},
           "selection": {"cv": 3}}
    if evaluation is not None:
        raw["evaluation"] = evaluation
    return raw


def _toml(path: Path, raw: dict) -> Path:
    def value(v):
        return json.dumps(v) if not isinstance(v, bool) else str(v).lower()

    lines = [f"{k} = {value(v)}" for k, v in raw.items() if not isinstance(v, dict)]
    tables = [("data", raw["data"]), ("model", raw["model"]), ("selection", raw["selection"])]
    for extra in ("evaluation", "intervals"):
        if extra in raw:
            tables.append((extra, raw[extra]))
    for name, table in tables:
        lines.append(f"[{name}]")
        lines += [f"{k} = {value(v)}" for k, v in table.items() if not isinstance(v, dict)]
        for sub, inner in table.items():
            if isinstance(inner, dict):
                lines.append(f"[{name}.{sub}]")
                lines += [f"{k} = {value(v)}" for k, v in inner.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def build_model(cfg, ds):
    return cfg.family.build(cfg, ds)


def test_config_builds_the_parameter_space_model(device):
    cfg = parse_config(_raw(), device / "config.toml")
    assert cfg.family.name == "hamiltonian" and cfg.family_settings.candidates == "local"
    ds = load_dataset(cfg)
    assert ds.hamiltonian.qubit_features == tuple(DATA["hamiltonian"]["qubit_features"])
    model = build_model(cfg, ds)
    assert isinstance(model, FittedPriorBoost)
    assert isinstance(model.physics, HamiltonianSelectionCV)
    assert model.physics.get_params()["max_steps"] == 3
    assert set(model.physics.candidates["model_f1"]) == {"v_q1", "v_q1^2", "v_c1", "v_c1^2"}
    fixed = build_model(parse_config(_raw({"selection": "none"}), device / "c.toml"), ds)
    assert isinstance(fixed.physics, HamiltonianParameterRegressor)
    assert "v_q1" in fixed.physics.covariates["model_f1"]  # start and pool together
    assert "model_f1^2" in fixed.physics.covariates["model_f1"]


@pytest.mark.parametrize("change, match", [
    (lambda r: r["model"].update(family="hamiltonain"),
     r"model\.family = 'hamiltonain': unknown family"),
    (lambda r: r["model"].update(family="eigenvalue"),
     r"\[model.hamiltonian\]: applies to family = \"hamiltonian\" only"),
    (lambda r: r["model"]["hamiltonian"].update(candidate="local"),
     r"unknown key\(s\) \['candidate'\]"),
    (lambda r: r["model"]["hamiltonian"].update(loss="quantile"),
     r"model\.hamiltonian\.loss = 'quantile': The 'loss' parameter of "
     r"HamiltonianParameterRegressor must be a str among \{('(squared_error|absolute_error|"
     r"huber)'(, )?){3}\}\. Got 'quantile' instead\."),
    (lambda r: r["model"]["hamiltonian"].update(selection_cv=1),
     r"model\.hamiltonian\.selection_cv = 1: The 'cv' parameter of HamiltonianSelectionCV "
     r"must be an int in the range \[2, inf\)\. Got 1 instead\."),
    (lambda r: r["model"]["hamiltonian"].update(huber_delta=0),
     r"model\.hamiltonian\.huber_delta = 0: The 'huber_delta' parameter of "
     r"HamiltonianParameterRegressor must be a float in the range \(0\.0, inf\)\. Got 0\.0 "
     r"instead\."),
    (lambda r: r["model"]["hamiltonian"].update(selection_repeats=0),
     r"model\.hamiltonian\.selection_repeats = 0: The 'n_repeats' parameter of "
     r"HamiltonianSelectionCV"),
    (lambda r: r["model"]["hamiltonian"].update(boost_stage="yes"),
     r"model\.hamiltonian\.boost_stage = 'yes'"),
    (lambda r: r["data"].pop("hamiltonian"), r"needs the Hamiltonian's columns"),
    (lambda r: r.update(evaluation={"nested_folds": 1}), "nested_folds = 1: give 0"),
    (lambda r: r.update(evaluation={"cv_repeat": 1}), r"unknown key\(s\) \['cv_repeat'\]"),
])
def test_bad_hamiltonian_configs_raise(device, change, match):
    raw = json.loads(json.dumps(_raw()))
    change(raw)
    with pytest.raises(ConfigError, match=match) as info:
        parse_config(raw, device / "config.toml")
    assert str(info.value).startswith(f"{device / 'config.toml'}: ")


def test_qubit_features_must_match_the_chain(device):
    raw = _raw()
    raw["data"]["hamiltonian"] = {**DATA["hamiltonian"], "qubit_features": ["v_q1", "v_q2"]}
    cfg = parse_config(raw, device / "config.toml")
    with pytest.raises(ValueError, match="qubit_features needs 5 column"):
        load_dataset(cfg)


@pytest.fixture(scope="module")
def cli_run(device, tmp_path_factory, new_store):
    out = tmp_path_factory.mktemp("run")
    cfg = _toml(device / "ham.toml", _raw(evaluation={"cv_repeats": 2, "cv_folds": 3,
                                                      "nested_folds": 2}))
    store = new_store(out / "mlflow.db")
    code = main(["evaluate", str(cfg), "--json", str(out / "out.json"), "--out",
                 str(out / "tables"), "--tracking-uri", store])
    return code, json.loads((out / "out.json").read_text()), out, store, cfg


def test_evaluate_reports_every_estimate(cli_run):
    code, result, _, _, _ = cli_run
    assert code == 0
    assert result["family"] == "hamiltonian"
    prior, model = result["prior"], result["model"]
    assert model["test_mae_avg"] < 0.5 * prior["test_mae_avg"]
    assert all(s in ("hamiltonian", "hamiltonian+boosted") for s in model["selected"])
    ham = result["hamiltonian"]
    assert 1 <= ham["selection"]["steps"] <= 3
    assert len(ham["selection"]["path"]) == ham["selection"]["steps"] + 1
    assert {r["parameter"] for r in ham["coefficients"]} <= set(
        DATA["hamiltonian"]["onsite"] + DATA["hamiltonian"]["couplings"])
    rep, nested = result["repeated_cv"], result["nested_cv_all"]
    assert rep["repeats"] == 2 and len(rep["model_mae_avg_per_repeat"]) == 2
    assert model["cv_mae"] == rep["model_mae"]  # the table shows the repeated CV
    assert rep["model_mae_avg"] < 0.5 * rep["prior_mae_avg"]
    assert nested["n_rows"] == 150 and nested["folds"] == 2
    assert nested["model_mae_avg"] < 0.5 * nested["prior_mae_avg"]


def test_evaluate_writes_tables_and_figures(cli_run):
    _, result, out, _, _ = cli_run
    tables = out / "tables"
    coef = pd.read_csv(tables / "coefficients.csv")
    assert list(coef.columns) == ["parameter", "covariate", "coef", "covariate_sd"]
    params = pd.read_csv(tables / "corrected_parameters.csv", index_col=0)
    assert len(params) == 150 and set(params["split"]) == {"train", "test"}
    assert (params["split"] == "train").sum() == result["n_train"]
    assert np.allclose(params["model_f1_corrected"] - params["model_f1_control"],
                       params["model_f1_correction"])
    path = pd.read_csv(tables / "selection_path.csv")
    assert path["cv_mae"].is_monotonic_decreasing
    for name in ("parameter_corrections", "selection_path"):
        with Image.open(tables / f"{name}.png") as im:
            assert im.size[0] > 300 and im.size[1] > 200


def test_evaluate_is_tracked_and_the_model_serves(cli_run):
    _, result, _, store, cfg = cli_run
    tracker = Tracker(store, "ham")
    run = tracker.client.get_run(result["mlflow"]["run_id"])
    assert run.data.params["family"] == "hamiltonian"
    assert run.data.metrics["nested_cv_all_mae_avg"] == pytest.approx(
        result["nested_cv_all"]["model_mae_avg"])
    arts = {a.path for a in tracker.client.list_artifacts(run.info.run_id, "hamiltonian")}
    assert arts == {"hamiltonian/coefficients.csv", "hamiltonian/corrected_parameters.csv",
                    "hamiltonian/selection_path.csv"}
    plots = {a.path for a in tracker.client.list_artifacts(run.info.run_id, "plots")}
    assert {"plots/parameter_corrections.png", "plots/selection_path.png",
            "plots/mae_bars.png"} <= plots
    served = tracker.load_model(result["mlflow"]["model_uri"])
    run = evaluate(parse_config_from(cfg), return_model=True)
    model, ds = run.model, run.dataset
    X = ds.X_physics.loc[ds.test_index]
    got = served.predict(X)  # the targets, then their intervals
    assert np.allclose(got[ds.target_names].to_numpy(), model.predict(X).to_numpy())
    lower = model.predict_interval(X)[..., 0]
    assert np.allclose(got[[f"{t}_lower" for t in ds.target_names]].to_numpy(), lower)


@pytest.mark.slow  # 23 s; test_run_outputs checks a tracked run logs the very files --out wrote
def test_evaluate_without_tracking_writes_the_same_outputs(cli_run, tmp_path):
    """``--out`` with and without tracking: the same files, byte for byte, and the same
    numbers; the tracked run logged those very files (figures and tables)."""
    _, result, out, store, cfg = cli_run
    assert main(["evaluate", str(cfg), "--json", str(tmp_path / "out.json"), "--out",
                 str(tmp_path / "tables"), "--no-track"]) == 0
    untracked = json.loads((tmp_path / "out.json").read_text())
    assert "mlflow" not in untracked

    def numbers(r):  # without the timings and where the outputs went
        r = json.loads(json.dumps(r))
        del r["hamiltonian"]["selection"]["seconds"]
        return {k: v for k, v in r.items() if k not in ("wall_s", "mlflow", "outputs")}

    assert numbers(untracked) == numbers(result)
    files = sorted(p.name for p in (out / "tables").iterdir())
    assert files == sorted(p.name for p in (tmp_path / "tables").iterdir())
    for name in files:
        assert (out / "tables" / name).read_bytes() == (tmp_path / "tables" / name).read_bytes()
    client = Tracker(store, "ham").client
    run_id = result["mlflow"]["run_id"]
    logged = {"plots/intervals.png": "intervals.png",
              "intervals/test_intervals.csv": "test_intervals.csv",
              "plots/parameter_corrections.png": "parameter_corrections.png",
              "plots/selection_path.png": "selection_path.png",
              "hamiltonian/coefficients.csv": "coefficients.csv",
              "hamiltonian/corrected_parameters.csv": "corrected_parameters.csv",
              "hamiltonian/selection_path.csv": "selection_path.csv"}
    assert set(logged.values()) == set(files)
    for artifact, name in logged.items():
        local = client.download_artifacts(run_id, artifact, str(tmp_path / "logged"))
        assert Path(local).read_bytes() == (out / "tables" / name).read_bytes(), artifact


def test_evaluate_reports_and_writes_prediction_intervals(cli_run):
    """[intervals] absent: 90% "oof" intervals (the model's own out-of-fold residuals). The
    JSON has per-target coverage and width on the test rows and in CV (with averages), --out
    writes the figure and the test rows' intervals, MLflow has them as metrics and artifacts,
    and the logged model carries predict_interval."""
    _, result, out, store, _ = cli_run
    assert result["intervals"] == {"method": "oof", "alpha": 0.1, "level": 0.9}
    m = result["model"]
    for key in ("test_coverage", "test_width", "cv_coverage", "cv_width"):
        assert len(m[key]) == 5 and m[f"{key}_avg"] == pytest.approx(np.mean(m[key])), key
    assert all(0 <= c <= 1 for c in m["test_coverage"])
    assert all(0.75 <= c <= 1 for c in m["cv_coverage"])  # 105 training rows, 90% nominal
    assert all(w > 0 for w in m["test_width"] + m["cv_width"])
    table = pd.read_csv(out / "tables" / "test_intervals.csv")
    assert len(table) == 5 * result["n_test"]
    assert list(table.columns) == ["experiment", "target", "measured", "predicted", "lower",
                                   "upper", "covered"]
    by_target = table.groupby("target", sort=False)
    assert by_target["covered"].mean().tolist() == pytest.approx(m["test_coverage"])
    assert (by_target.apply(lambda t: (t["upper"] - t["lower"]).mean()).tolist()
            == pytest.approx(m["test_width"]))
    with Image.open(out / "tables" / "intervals.png") as im:
        assert im.size[0] > 600 and im.size[1] > 300
    tracker = Tracker(store, "ham")
    run = tracker.client.get_run(result["mlflow"]["run_id"])
    assert run.data.metrics["test_coverage_avg"] == pytest.approx(m["test_coverage_avg"])
    assert run.data.metrics["cv_width/measured_E2"] == pytest.approx(m["cv_width"][1])
    assert run.data.params["intervals.method"] == "oof"
    assert "plots/intervals.png" in {a.path for a in
                                     tracker.client.list_artifacts(run.info.run_id, "plots")}
    assert {a.path for a in tracker.client.list_artifacts(run.info.run_id, "intervals")} == {
        "intervals/test_intervals.csv"}
    logged = tracker.load_model(result["mlflow"]["model_uri"]).unwrap_python_model().model
    X = load_dataset(load_config(cli_run[4])).X_physics.iloc[:4]
    assert logged.predict_interval(X).shape == (4, 5, 2)
    assert logged.target_names_ == result["targets"]


def parse_config_from(path: Path):
    """The config of ``path`` without its extra CV estimates (the same fitted model)."""
    cfg = load_config(path)
    return dataclasses.replace(cfg, evaluation=cfg.evaluation.model_copy(
        update={"cv_repeats": 0, "nested_folds": 0}))


def test_same_seed_same_numbers(device, caplog):
    """The same seed gives the same numbers, with the progress lines shown (the first run:
    the selection's steps, the out-of-fold priors and the stage, on the ``workbench``
    logger a command prints) or not (the second)."""
    import logging

    # one selection step (a CV over every candidate, then the refit): 2 s of CPU per evaluate
    # instead of 5 with FAST's three
    cfg = parse_config(_raw(hamiltonian={"max_steps": 1}), device / "config.toml")
    with caplog.at_level(logging.INFO, logger="workbench"):
        first = evaluate(cfg).to_json()
    lines = [r.getMessage() for r in caplog.records]
    for want in ("hamiltonian: selection start: cv_mae=", "hamiltonian: selection step 1: ",
                 "stage: out-of-fold priors: ", "stage: kept on "):
        assert any(line.startswith(want) for line in lines), (want, lines)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="workbench"):
        second = evaluate(cfg).to_json()
    assert not [r for r in caplog.records if r.getMessage().startswith("hamiltonian: ")]
    for key in ("test_mae", "cv_mae"):
        assert first["model"][key] == second["model"][key]
    assert first["hamiltonian"]["coefficients"] == second["hamiltonian"]["coefficients"]
    assert os.environ["MLFLOW_DISABLE_TELEMETRY"] == "true"
