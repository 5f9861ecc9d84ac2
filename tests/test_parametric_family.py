"""Family ``parametric``: ``workbench init --model``, a CSV without prior columns, evaluate."""

import json
from pathlib import Path

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
    assert 'stage_priors = "candidates"' in text  # benchmarks/decisions/stage_candidates.md
    assert "stage_mean = false" in text  # benchmarks/decisions/stage_mean_fresh_fields.md
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
    for figure in ("parameter_corrections", "parameter_drift", "selection_path"):
        assert (tmp_path / "tables" / f"{figure}.png").exists()


def test_the_drift_figure_draws_each_parameter_against_its_strongest_covariate():
    from workbench.experiment.families.parametric_figures import (
        covariate_axis,
        drift_axes,
        parameter_drift_figure,
    )

    X = pd.DataFrame({"a": [1.0, 2.0, 3.0], "b": [0.5, 0.0, -1.0]})
    assert covariate_axis("a^2", X)[0] == "a"
    np.testing.assert_array_equal(covariate_axis("a*b", X)[1], [0.5, 0.0, -3.0])
    np.testing.assert_array_equal(covariate_axis("a-b^2", X)[1], [0.5, 2.0, 4.0])
    assert covariate_axis("c", X) is None
    coefficients = pd.DataFrame({"parameter": ["p", "p", "p", "q"],
                                 "covariate": ["intercept", "a", "b^2", "intercept"],
                                 "coef": [1.0, 0.1, -0.3, 2.0]})
    axes_by = drift_axes(coefficients, X)
    assert list(axes_by) == ["p"] and axes_by["p"][0] == "b"  # q has no drift
    corrected = pd.DataFrame({"p": [1.0, 1.1, 1.3], "q": [2.0, 2.0, 2.0]})
    fig = parameter_drift_figure(corrected, axes_by, calibrated={"p": 1.1},
                                 groups={"train": [0, 1], "test": [2]})
    ax = fig.axes[0]
    assert ax.get_xlabel() == "b" and ax.get_ylabel() == "corrected p"
    with pytest.raises(ValueError, match="missing"):
        parameter_drift_figure(corrected, {"r": ("a", X["a"].to_numpy())})


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



def test_a_ridge_drift_through_evaluate(decay_csv, tmp_path):
    """``drift = "ridge"``: the whole pool at once, its penalty chosen by CV, in the tables."""
    config = tmp_path / "decay.toml"
    assert main(["init", str(decay_csv), "--model", str(tmp_path / "models" / "decay.py"),
                 "--target", "y", "--out", str(config)]) == 0
    out = tmp_path / "result.json"
    assert main(["evaluate", str(config), "--no-track", "--json", str(out),
                 "--out", str(tmp_path / "tables"), "--jobs", "1",
                 "--set", 'model.parametric.drift="ridge"',
                 "--set", "model.parametric.ridge_alphas=[1.0, 0.01]",
                 "--set", "model.parametric.selection_cv=3",
                 "--set", "model.parametric.boost_stage=false"]) == 0
    result = json.loads(out.read_text())
    assert result["model"]["selected"] == ["parametric:ridge_drift"]
    info = result["parametric"]
    assert "selection" not in info and [r["alpha"] for r in info["ridge_path"]] == [1.0, 0.01]
    ridge = pd.read_csv(tmp_path / "tables" / "ridge_path.csv")
    assert ridge["chosen"].sum() == 1
    assert result["model"]["test_mae"][0] < 0.2 * result["prior"]["test_mae"][0]
    for bad in ('model.parametric.drift="lasso"', "model.parametric.ridge_alphas=[-1.0]"):
        assert main(["evaluate", str(config), "--no-track", "--set", bad]) != 0


SMALL = {"n_jobs": 1, "max_steps": 1, "selection_cv": 3, "boost_stage": False}


#: The project's configs.
EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def _device_library(google_5q, parametric_toml, parasitic):
    """The device config, checked: its start and candidates tables are the Hamiltonian
    family's library ("default" start, "physical" pool, the parasitic couplings')."""
    from workbench.param_boost import default_library
    from workbench.param_select import candidate_pool

    cfg = _small(EXPERIMENTS / parametric_toml, "parametric")
    ham = google_5q.hamiltonian
    on, co = list(ham.onsite.columns), list(ham.couplings.columns)
    assert cfg.family_settings.start == default_library(on, co)
    assert cfg.family_settings.candidates == candidate_pool(
        on, co, ham.qubit_features, ham.coupler_features, base=None, parasitic=parasitic)
    return cfg


def _small(path, table):
    from workbench.experiment.runs.prepare import load_config

    return load_config(path, {k if k == "n_jobs" else f"model.{table}.{k}": v
                              for k, v in SMALL.items()})


@pytest.mark.parametrize("hamiltonian_toml, parametric_toml, parasitic", [
    ("hamiltonian.toml", "parametric_device.toml", None),
    # its estimators' fit: tests/test_parametric_optional.py (cheap); its tables: below
    pytest.param("hamiltonian_parasitic.toml", "parametric_parasitic.toml", "next_nearest",
                 marks=pytest.mark.slow)])
def test_the_hamiltonian_family_is_the_parametric_family_on_the_device_model_file(
        google_5q, hamiltonian_toml, parametric_toml, parasitic):
    """One engine: experiments/models/hamiltonian_device.py (HamiltonianModel's file functions,
    its Hellmann-Feynman jacobian) through family = "parametric" (parametric_device.toml, with
    the Hamiltonian family's Gauss-Newton settings) fits what family = "hamiltonian"
    (hamiltonian.toml) fits: the same library, the same covariates chosen on the same CV
    scores, the same corrected parameters and predictions (to rounding: the file's predict
    and jacobian diagonalise separately, the family's model object once). The same with the
    parasitic couplings (hamiltonian_device_parasitic.py's OPTIONAL parameters)."""
    ham_cfg = _small(EXPERIMENTS / hamiltonian_toml, "hamiltonian")
    par_cfg = _device_library(google_5q, parametric_toml, parasitic)
    ham = google_5q.hamiltonian
    on, co = list(ham.onsite.columns), list(ham.couplings.columns)
    rows = google_5q.train_index[:48]  # a small slice of the training rows
    X = ham_cfg.family.inputs(ham_cfg, google_5q).loc[rows]
    assert X.equals(par_cfg.family.inputs(par_cfg, google_5q).loc[rows])
    Y = google_5q.targets.loc[rows].to_numpy()
    hamiltonian = ham_cfg.family.build(ham_cfg, google_5q).physics.fit(X, Y)
    parametric = par_cfg.family.build(par_cfg, google_5q).physics.fit(X, Y)
    assert parametric.choice_ == "drift"
    steps = ["parameter", "covariate"]
    assert hamiltonian.selection_.path[steps].equals(parametric.selection_.path[steps])
    assert len(parametric.selection_.path) == 2  # a covariate added
    np.testing.assert_allclose(parametric.selection_.path["cv_mae"],
                               hamiltonian.selection_.path["cv_mae"], rtol=0, atol=1e-9)
    h_theta = hamiltonian.corrected_parameters(X).to_numpy()
    p_theta = parametric.corrected_parameters(X).to_numpy()
    control = google_5q.X_physics.loc[rows, on + co].to_numpy()
    # the drift moves the parameters by MHz; the two fits agree to rounding
    assert np.abs(h_theta - control).max() > 1.0
    assert np.abs(h_theta - p_theta).max() < 1e-8
    assert np.abs(hamiltonian.predict(X) - parametric.predict(X)).max() < 1e-8
    h_coef = hamiltonian.estimator_.coef_["coef"]
    np.testing.assert_allclose(parametric.estimator_.coef_["coef"].to_numpy(),
                               h_coef.to_numpy(), rtol=0, atol=1e-8)
    assert list(parametric.estimator_.coef_.index) == list(h_coef.index)


def test_the_parasitic_device_config_has_the_hamiltonian_familys_library(google_5q):
    """parametric_parasitic.toml's tables are hamiltonian_parasitic.toml's library (start
    "default", pool "physical" with the parasitic next-nearest couplings), and its model
    file's OPTIONAL parameters are those couplings."""
    from workbench.parametric import load_model

    _device_library(google_5q, "parametric_parasitic.toml", "next_nearest")
    ham = google_5q.hamiltonian
    on, co = list(ham.onsite.columns), list(ham.couplings.columns)
    model = load_model(EXPERIMENTS / "models" / "hamiltonian_device_parasitic.py")
    assert model.optional == ("f1~f3", "f2~f4", "f3~f5")
    assert model.names == on + co + list(model.optional)


#: A small LightGBM stage on top, for the tests of the stage's priors.
STAGE = ('[model]\nfamily = "parametric"\nbasis = "lightgbm"\n'
         'basis_inputs = "prior+features"\nline_search_penalty = 0.0\n'
         '[model.basis_params]\nn_estimators = 30\nnum_leaves = 4\n'
         'min_child_samples = 5\nverbose = -1\n[selection]\ncv = 3\nshuffle = true\n')


def _decay_config(tmp_path, extra=""):
    config = tmp_path / "c.toml"
    config.write_text('random_state = 0\n[data]\ncsv = "decay.csv"\ntargets = ["y"]\n'
                      'features = ["t", "temp"]\ntest_fraction = 0.3\n[model]\n'
                      'family = "parametric"\n[model.parametric]\nmodel = "models/decay.py"\n'
                      'loss = "squared_error"\nmax_steps = 1\nproducts = false\n'
                      'boost_stage = false\nprior_cv = 2\nselection_cv = 3\n' + extra)
    return config


def test_new_rows_need_only_the_features_when_the_model_is_the_prior(decay_csv, tmp_path):
    """The prior the family computed is no input: workbench predict and serving take the
    features alone (it used to ask new rows for the column model_y)."""
    from workbench.experiment.runs.prepare import load_config, prepare

    run = prepare(load_config(_decay_config(tmp_path)))
    ds = run.dataset
    X = run.family.inputs(run.config, ds)
    assert list(X.columns) == ["t", "temp"] and ds.prior_names == ["model_y"]
    model = run.family.build(run.config, ds).fit(X.loc[ds.train_index],
                                                 ds.targets.loc[ds.train_index])
    new = pd.DataFrame({"t": [1.0, 2.0], "temp": [0.5, -0.3]})
    pred = np.asarray(model.predict(new), dtype=float)
    truth = 2.5 * np.exp(-new["t"] / (1.5 + 0.3 * new["temp"])) + 0.1
    np.testing.assert_allclose(pred.ravel(), truth, atol=0.05)


def test_a_sweep_varies_the_parametric_settings(decay_csv, tmp_path):
    """[search.parametric] is checked key by key: the model file the search does not vary
    is no error (it used to be 'Field required'); a bad value or key still is."""
    from optuna.trial import FixedTrial

    from workbench.experiment.config.space import SpaceError
    from workbench.experiment.runs.prepare import load_config

    search = ('[search.parametric]\nalpha = { low = 0.1, high = 10.0, log = true }\n'
              'loss = ["huber", "squared_error"]\n')
    cfg = load_config(_decay_config(tmp_path, search))
    trial = FixedTrial({"parametric.alpha": 3.0, "parametric.loss": "huber"})
    chosen = cfg.family.with_trial(cfg, trial, ["y"]).family_settings
    assert (chosen.alpha, chosen.loss, chosen.model) == (3.0, "huber", "models/decay.py")
    for bad, message in (('loss = ["cubic"]', "parametric.loss"),
                         ("max_stepz = [1, 2]", "unknown key")):
        with pytest.raises((SpaceError, ValueError), match=message):
            load_config(_decay_config(tmp_path, f"[search.parametric]\n{bad}\n"))


def _evaluate_logged(config, caplog, level):
    """Evaluate ``config`` with the ``workbench`` logger at ``level``: its result and lines."""
    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.prepare import load_config

    caplog.clear()
    with caplog.at_level(level, logger="workbench"):
        result = evaluate(load_config(config))
    return result.to_json(), [r.getMessage() for r in caplog.records]


def _without_timings(result):
    out = {k: v for k, v in result.items() if k != "wall_s"}
    out["parametric"] = {k: v for k, v in result["parametric"].items() if k != "selection"}
    out["parametric"]["path"] = result["parametric"]["selection"]["path"]
    return out


def test_evaluate_reports_the_fits_progress_and_no_number_depends_on_it(decay_csv, tmp_path,
                                                                         caplog):
    """Each phase, CV fold and selection step of the family's fit is a line on the
    ``workbench`` logger (which a command prints), in the order they run; with that logger
    quiet there are none, and every number is the same."""
    import logging

    config = _decay_config(tmp_path, 'drift = "both"\nridge_alphas = [1.0, 0.01]\n'
                                     "[model.parametric.boost]\nrounds = 4\n")
    config.write_text(config.read_text().replace("boost_stage = false", "boost_stage = true"))
    shown, lines = _evaluate_logged(config, caplog, logging.INFO)
    expected = ["[c] fitting 1 targets",
                "parametric: 3 parameters, 49 rows, 3 CV folds; the prior's training MAE",
                *[f"parametric: calibrated model: CV fold {k}/3" for k in (1, 2, 3)],
                "parametric: calibrated model: cv_mae=",
                "parametric: drift: forward selection over 12 candidate terms, at most 1 step(s)",
                "parametric: selection start: cv_mae=",
                "parametric: selection step 1: tau <- temp  cv_mae=",
                "parametric: drift: 1 step(s), cv_mae=",
                "parametric: ridge drift: alpha 1 (1/2) cv_mae=",
                "parametric: ridge drift: alpha 0.01 (2/2) cv_mae=",
                *[f"parametric: boost: 4 rounds at most: CV fold {k}/3" for k in (1, 2, 3)],
                "parametric: boost: ",
                "parametric: chose ",
                "stage: out-of-fold priors: 2 refits of the physics model",
                "stage: base boosting 1 target(s) from the out-of-fold priors",
                "stage: kept on "]
    at = 0
    for want in expected:  # each in turn, after the one before
        found = [i for i, line in enumerate(lines) if i >= at and line.startswith(want)]
        assert found, f"no line {want!r} after line {at}: {lines}"
        at = found[0] + 1
    progress = [line for line in lines if line.startswith(("parametric:", "stage:"))]
    assert len(progress) == len(expected) - 1  # a line per phase, fold and step, no more
    quiet, lines = _evaluate_logged(config, caplog, logging.WARNING)
    assert not [line for line in lines if line.startswith(("parametric:", "stage:"))]
    assert _without_timings(quiet) == _without_timings(shown)
    assert shown["parametric"]["choices"] == quiet["parametric"]["choices"]


def test_progress_prints_where_no_logging_is_set_up(capsys, monkeypatch):
    """``verbose=True`` is never silent: without a handler the lines go to standard error
    (as scikit-learn's verbose prints); ``verbose=False`` reports nothing."""
    import logging

    from workbench._progress import Progress

    logger = logging.getLogger("workbench.test_progress")
    monkeypatch.setattr(logger, "hasHandlers", lambda: False)
    Progress(logger.name, enabled=True, prefix="parametric: ")("calibrated model: CV fold 1/5")
    Progress(logger.name, enabled=False)("nothing")
    captured = capsys.readouterr()
    assert (captured.out, captured.err) == ("", "parametric: calibrated model: CV fold 1/5\n")


def test_the_fits_choices_kept_and_a_sweeps_trials_report_no_progress(decay_csv, tmp_path,
                                                                      caplog):
    """Refits with the choices kept (repeated CV, learning curves) and a sweep's trials fit
    quietly (the sweep's progress is its line per trial); the fit evaluate builds reports,
    and cloning keeps its ``verbose``."""
    import logging

    from optuna.trial import FixedTrial
    from sklearn.base import clone
    from sklearn.model_selection import KFold

    from workbench.experiment.runs.prepare import load_config, prepare

    search = "[search.parametric]\nalpha = { low = 0.1, high = 10.0, log = true }\n"
    run = prepare(load_config(_decay_config(tmp_path, search)))
    ds, family = run.dataset, run.family
    X, Y = family.inputs(run.config, ds).loc[ds.train_index], ds.targets.loc[ds.train_index]
    folds = []
    with caplog.at_level(logging.INFO, logger="workbench"):
        model = family.build(run.config, ds)
        family.objective(run.config, ds, ["y"], X, Y, FixedTrial({"parametric.alpha": 3.0}),
                         KFold(2), lambda i, mae, prior: folds.append(mae))
    assert len(folds) == 2 and not caplog.records  # the trial's two fits said nothing
    assert model.verbose and model.physics.verbose
    assert clone(model).get_params()["physics__verbose"] is True
    fitted = model.fit(X, Y)
    assert family.fixed_choices(fitted).verbose is False


def test_a_fitted_model_needs_no_model_file(decay_csv, tmp_path):
    """The model file travels inside the fitted model (its source code): unpickled after the
    file is gone (a model server, another machine), it predicts the same."""
    import pickle

    from workbench.experiment.runs.prepare import load_config, prepare

    run = prepare(load_config(_decay_config(tmp_path)))
    ds = run.dataset
    X = run.family.inputs(run.config, ds)
    model = run.family.build(run.config, ds).fit(X.loc[ds.train_index],
                                                 ds.targets.loc[ds.train_index])
    blob = pickle.dumps(model)
    (tmp_path / "models" / "decay.py").unlink()
    again = pickle.loads(blob)
    np.testing.assert_array_equal(again.predict(X), model.predict(X))


def test_a_tracked_run_logs_registers_and_serves(decay_csv, tmp_path):
    """MLflow: the calibrated parameters and the choice's CV MAE as metrics, the family's
    tables, a learning curve and SHAP of the correction as artifacts, the registered model
    predicting a CSV of features alone after the model file moved."""
    import mlflow

    uri = f"sqlite:///{tmp_path}/mlflow.db"
    out = tmp_path / "result.json"
    assert main(["evaluate", str(_decay_config(tmp_path)), "--tracking-uri", uri,
                 "--register", "decay", "--json", str(out), "--jobs", "1",
                 "--no-intervals"]) == 0
    result = json.loads(out.read_text())
    client = mlflow.MlflowClient(uri)
    run = client.get_run(result["mlflow"]["run_id"])
    metrics = run.data.metrics
    calibration = {r["parameter"]: r for r in result["parametric"]["calibration"]}
    assert metrics["parametric/calibrated/tau"] == pytest.approx(
        calibration["tau"]["start"] + calibration["tau"]["offset"])
    assert {"parametric/cv_mae/prior", "parametric/cv_mae/calibrated",
            "parametric/cv_mae/drift"} <= set(metrics)
    logged = {a.path for a in client.list_artifacts(run.info.run_id, "parametric")}
    assert {"parametric/calibration.csv", "parametric/selection_path.csv"} <= logged
    plots = {a.path for a in client.list_artifacts(run.info.run_id, "plots")}
    assert {"plots/learning_curve.png", "plots/shap_y.png", "plots/shap_correction_y.png",
            "plots/parameter_drift.png", "plots/mae_bars.png"} <= plots
    curves = client.download_artifacts(run.info.run_id, "learning_curves.json", str(tmp_path))
    curve = json.loads(open(curves).read())["y"]
    # the drift learned from the training rows beats the start values at every size
    assert np.all(np.nanmean(curve["cv_error"], axis=1)
                  < np.nanmean(curve["incumbent_error"], axis=1))
    (tmp_path / "models").rename(tmp_path / "elsewhere")
    pd.DataFrame({"t": [1.0, 2.0], "temp": [0.5, -0.3]}).to_csv(tmp_path / "new.csv",
                                                                  index=False)
    assert main(["predict", "models:/decay@champion", str(tmp_path / "new.csv"),
                 "--out", str(tmp_path / "p.csv"), "--tracking-uri", uri]) == 0
    pred = pd.read_csv(tmp_path / "p.csv")["y"].to_numpy()
    np.testing.assert_allclose(pred, [2.5 * np.exp(-1 / 1.65) + 0.1,
                                      2.5 * np.exp(-2 / 1.41) + 0.1], atol=0.05)


def test_a_missing_term_is_not_forced_into_a_drift(tmp_path):
    """Simulated (no offline public set shows it): the decay law misses a term, a second
    channel that switches on at t = 1.5 (a step no drift of amplitude, lifetime or offset in
    the conditions temp and humidity makes). The family's table says the error is not a
    drift, it falls back to the calibrated model and boosts from its prediction: the same
    model and numbers as the family without drift candidates (boosting from the calibrated
    prediction), and far better than the prior."""
    rng = np.random.default_rng(3)
    n = 160
    t, temp, humidity = rng.uniform(0, 3, n), rng.normal(size=n), rng.normal(size=n)
    y = 2.5 * np.exp(-t / 1.5) + 0.1 + 0.3 * (t > 1.5) + rng.normal(0, 0.01, n)
    pd.DataFrame({"t": t, "temp": temp, "humidity": humidity, "y": y}).to_csv(
        tmp_path / "decay.csv", index=False)
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "decay.py").write_text(DECAY)
    conditions = '["temp", "humidity", "temp^2", "humidity^2"]'
    config = tmp_path / "c.toml"
    config.write_text(
        'random_state = 0\n[data]\ncsv = "decay.csv"\ntargets = ["y"]\n'
        'features = ["t", "temp", "humidity"]\ntest_fraction = 0.3\n'
        '[model]\nfamily = "parametric"\nbasis = "lightgbm"\nbasis_inputs = "prior+features"\n'
        'line_search_penalty = 0.0\n'
        '[model.basis_params]\nn_estimators = 60\nnum_leaves = 4\n'
        'min_child_samples = 5\nverbose = -1\n'
        '[model.parametric]\nmodel = "models/decay.py"\nloss = "squared_error"\n'
        'max_steps = 2\nprior_cv = 3\nselection_cv = 3\n'
        f'[model.parametric.candidates]\namplitude = {conditions}\ntau = {conditions}\n'
        f'offset = {conditions}\n[selection]\ncv = 3\nshuffle = true\n')
    runs = {}
    no_drift = ["--set", 'model.parametric.candidates="none"']
    for name, extra in (("family", []), ("no drift", no_drift)):
        out = tmp_path / f"{name}.json"
        assert main(["evaluate", str(config), "--no-track", "--json", str(out), "--jobs", "1",
                     *extra]) == 0
        runs[name] = json.loads(out.read_text())
    result, info = runs["family"], runs["family"]["parametric"]
    assert info["choice"] == "calibrated" and "not a drift" in info["note"]
    cv = {row["candidate"]: row["cv_mae"] for row in info["choices"]}
    assert set(cv) == {"prior", "calibrated", "drift"}  # the drift was tried, and lost
    assert cv["calibrated"] - cv["drift"] <= 1e-3
    selected = result["model"]["selected"][0]
    assert selected.startswith("parametric:calibrated (error not a drift)+")  # stage kept
    # the fall-back is boosting from the calibrated prediction, number for number
    assert runs["no drift"]["model"]["test_mae"] == result["model"]["test_mae"]
    assert runs["no drift"]["model"]["selected"] == result["model"]["selected"]
    assert result["model"]["test_mae"][0] < 0.5 * result["prior"]["test_mae"][0]


def test_the_learning_curve_fits_keep_the_targets_names():
    """A multi-target model with per-target stage settings (keyed by the targets' names)
    needs them in every learning-curve fit; an array lost them (every fit of
    parametric_device.toml's curve failed: "unknown targets ['eeig1', ...]")."""
    from sklearn.base import BaseEstimator, RegressorMixin

    from workbench.experiment.families.parametric_artifacts import AllTargets

    class Names(RegressorMixin, BaseEstimator):
        def fit(self, X, y):
            self.names_, self.rows_ = list(y.columns), len(y)
            return self

    Y = pd.DataFrame({"eeig1": [1.0, 2.0, 3.0], "eeig2": [4.0, 5.0, 6.0]})
    fitted = AllTargets(Names(), Y).fit(pd.DataFrame({"x": [0.0, 1.0]}), [0.0, 2.0])
    assert fitted.estimator_.names_ == ["eeig1", "eeig2"] and fitted.estimator_.rows_ == 2


def test_the_config_reaches_the_extrapolation_guard(decay_csv, tmp_path):
    """[model.parametric] out_of_bounds = "calibrated" reaches the regressor; a bad value is
    one error naming the key and the valid values."""
    from workbench.experiment.runs.prepare import ConfigError, load_config, prepare

    run = prepare(load_config(_decay_config(tmp_path, 'out_of_bounds = "calibrated"\n')))
    model = run.family.build(run.config, run.dataset)
    found = [v for k, v in model.get_params().items() if k.endswith("out_of_bounds")
             and isinstance(v, str) and v == "calibrated"]
    assert found, model.get_params()
    with pytest.raises(ConfigError, match="out_of_bounds.*calibrated"):
        load_config(_decay_config(tmp_path, 'out_of_bounds = "hold"\n'))


def test_test_rows_outside_the_models_domain_are_said_not_a_crash(tmp_path, capsys):
    """A drift that takes a test row's parameter outside the model's domain (sqrt of a
    negative k) used to end evaluate with a traceback; the row gets the calibrated model's
    prediction and the table says how many rows did."""
    rng = np.random.default_rng(0)
    temp = np.concatenate([rng.uniform(0, 1, 60), [-3.0, -2.5, 0.5, 0.7]])
    x = rng.uniform(1, 2, temp.size)
    y = np.sqrt(np.clip(0.8 + 6.0 * temp, 0.1, None)) * x + 0.1
    split = ["train"] * 60 + ["test"] * 4
    pd.DataFrame({"x": x, "temp": temp, "y": y, "split": split}).to_csv(
        tmp_path / "root.csv", index=False)
    (tmp_path / "root.py").write_text(
        "import numpy as np\nPARAMETERS = {'k': 1.0, 'B': 0.0}\n\n\n"
        "def predict(params, data):\n"
        "    return np.sqrt(params['k']) * data['x'].to_numpy() + params['B']\n")
    config = tmp_path / "root.toml"
    config.write_text('random_state = 0\n[data]\ncsv = "root.csv"\ntargets = ["y"]\n'
                      'features = ["x", "temp"]\nsplit_column = "split"\n[model]\n'
                      'family = "parametric"\n[model.parametric]\nmodel = "root.py"\n'
                      'loss = "squared_error"\nalpha = 0.0\nmax_steps = 1\nsquares = false\n'
                      'products = false\nboost_stage = false\nselection_cv = 3\n'
                      'start = { k = ["temp"] }\ncandidates = "none"\n')
    out = tmp_path / "result.json"
    assert main(["evaluate", str(config), "--no-track", "--json", str(out), "--jobs", "1",
                 "--no-intervals"]) == 0
    result = json.loads(out.read_text())
    assert result["parametric"]["outside_domain_test_rows"] == 2
    assert result["parametric"]["outside_box_test_rows"] == 2  # temp -3 and -2.5
    assert np.isfinite(result["model"]["test_mae"][0])
    printed = capsys.readouterr().out
    assert "2 of 4 test rows: the corrected parameters leave the model's domain" in printed
    assert ("2 of 4 test rows lie outside the box the training rows' covariates span: the "
            "drift extrapolates there") in printed


def test_the_stage_compares_the_drift_with_the_calibrated_model(decay_csv, tmp_path):
    """``stage_priors = "calibrated"``: the stage on top is also fitted on the calibrated
    model's out-of-fold prior (the generic path), and the target keeps the prior the stage
    scored better in CV; the table records both CV MAEs, the label says which prior, and a
    learning curve's fits keep that choice."""
    from workbench.experiment.runs.prepare import ConfigError, load_config, prepare

    config = tmp_path / "c.toml"
    config.write_text(_decay_config(tmp_path).read_text()
                      .replace('[model]\nfamily = "parametric"\n', STAGE)
                      .replace("boost_stage = false\n", 'stage_priors = "calibrated"\n'))
    out = tmp_path / "r.json"
    assert main(["evaluate", str(config), "--no-track", "--json", str(out), "--jobs", "1"]) == 0
    result = json.loads(out.read_text())
    rows = result["parametric"]["stage_cv_mae"]
    assert [r["target"] for r in rows] == ["y"]
    (row,) = rows
    calibrated = row["calibrated"] <= row["physics"]
    assert row["stage_prior"] == ("calibrated" if calibrated else "physics")
    label = result["model"]["selected"][0]
    assert label.startswith("parametric:calibrated (the stage did better on it)"
                            if calibrated else "parametric:drift")
    run = prepare(load_config(config))
    metrics = run.family.run_metrics(result)
    assert metrics["parametric/stage_cv_mae/physics/y"] == row["physics"]
    assert metrics["parametric/stage_cv_mae/calibrated/y"] == row["calibrated"]
    model = run.family.build(run.config, run.dataset)
    assert list(model.alternative) == ["calibrated"]
    X, Y = run.family.inputs(run.config, run.dataset), run.dataset.targets
    model.fit(X.loc[run.dataset.train_index], Y.loc[run.dataset.train_index])
    fixed = run.family.fixed_choices(model)
    assert fixed.alternative is None  # one target: its choice is fixed
    if model.alternative_selected_[0]:  # the calibrated model, no covariates
        def settings(m):
            return {k: v for k, v in m.get_params().items() if k != "model"}

        assert settings(fixed.physics) == settings(model.alternative["calibrated"])
    else:  # the drift, its covariates fixed
        assert fixed.physics.covariates == model.physics_.estimator_.covariates
    with pytest.raises(ConfigError, match="'calibrated_stage' is now 'stage_priors = "):
        load_config(_decay_config(tmp_path, "calibrated_stage = true\n"))


def test_the_stage_chooses_among_every_candidate(decay_csv, tmp_path):
    """``stage_priors = "candidates"``: the stage is fitted on the out-of-fold prior of
    every candidate the choice scored (the calibrated model, the drift, the
    parameter-space boost), the target keeps the one with the lowest stage CV MAE, and
    the fixed choices keep that candidate with its own choices (covariates, rounds)."""
    from workbench.experiment.runs.prepare import load_config, prepare

    config = _decay_config(tmp_path, 'stage_priors = "candidates"\n'
                           '[model.parametric.boost]\nregressor = "tree"\nrounds = 8\n')
    config.write_text(config.read_text().replace('[model]\nfamily = "parametric"\n', STAGE)
                      .replace("boost_stage = false\n", ""))
    run = prepare(load_config(config))
    X, Y = run.family.inputs(run.config, run.dataset), run.dataset.targets
    model = run.family.build(run.config, run.dataset)
    model.fit(X.loc[run.dataset.train_index], Y.loc[run.dataset.train_index])
    physics = model.physics_
    scored = [c for c in physics.choices_["candidate"] if c != "prior"]
    assert set(scored) == {"calibrated", "drift", "boost"}
    assert list(model.stage_cv_mae_.columns) == ["physics", *physics.other_candidates_]
    assert set(physics.other_candidates_) == set(scored) - {physics.choice_}
    cv = model.stage_cv_mae_.loc["y"]
    (chosen,) = model.prior_choice_
    assert cv[chosen] == cv.min()
    label = run.family.selected(model, ["y"])[0]
    fixed = run.family.fixed_choices(model)
    assert fixed.alternative is None
    if chosen == "physics":
        assert label.startswith(f"parametric:{physics.choice_}")
        kept = physics.estimator_
    else:
        assert label.startswith(f"parametric:{chosen} (the stage did better on it)")
        kept = model.alternatives_[chosen]
    assert type(fixed.physics) is type(kept)
    assert fixed.physics.get_params().keys() == kept.get_params().keys()
    pred = model.predict(X.loc[run.dataset.test_index])
    assert np.isfinite(pred.to_numpy()).all()


def test_the_stage_mean_is_scored_beside_each_prior(decay_csv, tmp_path):
    """``stage_mean = true``: the mean of the stages over the candidates' priors is scored
    by its CV (the ``mean`` column) and kept where lowest; the table's CV MAE, the label
    and the fixed choices follow what was kept."""
    from workbench.experiment.runs.prepare import load_config, prepare

    config = _decay_config(tmp_path, 'stage_priors = "candidates"\nstage_mean = true\n')
    config.write_text(config.read_text().replace('[model]\nfamily = "parametric"\n', STAGE)
                      .replace("boost_stage = false\n", ""))
    out = tmp_path / "r.json"
    assert main(["evaluate", str(config), "--no-track", "--json", str(out), "--jobs", "1"]) == 0
    result = json.loads(out.read_text())
    (row,) = result["parametric"]["stage_cv_mae"]
    scored = {k: v for k, v in row.items() if k not in ("target", "stage_prior")}
    assert set(scored) == {"physics", "calibrated", "mean"}
    assert scored[row["stage_prior"]] == min(scored.values())
    label = result["model"]["selected"][0]
    run = prepare(load_config(config))
    model = run.family.build(run.config, run.dataset)
    assert model.stage_mean
    X, Y = run.family.inputs(run.config, run.dataset), run.dataset.targets
    model.fit(X.loc[run.dataset.train_index], Y.loc[run.dataset.train_index])
    assert model.prior_choice_.tolist() == [row["stage_prior"]]
    fixed = run.family.fixed_choices(model)
    if row["stage_prior"] == "mean":
        assert label.startswith("parametric:mean of the stages on drift, calibrated")
        assert result["model"]["cv_mae"][0] == pytest.approx(row["mean"])
        assert list(fixed.alternative) == ["calibrated"] and fixed.stage_mean
    else:
        assert "mean of the stages" not in label and fixed.alternative is None
    # without alternatives the option has nothing to mix: no mean scored
    plain = _decay_config(tmp_path, "stage_mean = true\n")
    plain.write_text(plain.read_text().replace('[model]\nfamily = "parametric"\n', STAGE)
                     .replace("boost_stage = false\n", ""))
    run = prepare(load_config(plain))
    assert not run.family.build(run.config, run.dataset).stage_mean


def test_the_test_row_notes_follow_the_prior_the_stage_kept():
    """The notes on test rows outside the box come from the regressor the kept priors use:
    the chosen model's where a target keeps it alone or in the stages' mean (it raised a
    KeyError on the mean), the one alternative every target has, else none."""
    from types import SimpleNamespace

    from workbench.experiment.families.parametric import _used_regressor

    chosen, other = object(), object()
    physics = SimpleNamespace(estimator_=chosen)
    for choice, expected in ((["physics"], chosen), (["mean"], chosen),
                             (["mean", "calibrated"], chosen), (["calibrated"], other),
                             (["calibrated", "boost"], None)):
        model = SimpleNamespace(physics_=physics, prior_choice_=choice,
                                alternatives_={"calibrated": other, "boost": object()})
        assert _used_regressor(model) is expected


def test_a_note_where_test_rows_lie_beyond_and_a_target_keeps_the_mean():
    """Test rows outside the training rows' box and a target on the mean of the stages: a
    note says the mean was chosen on the training rows' folds and how to keep a single
    stage; without the mean, or with every row inside the box, no such note."""
    from types import SimpleNamespace

    from workbench.experiment.families.parametric import _test_row_notes

    X = pd.DataFrame({"t": [0.5, 4.0, 5.0]})
    regressor = SimpleNamespace(outside=lambda X: (X["t"] > 3).to_numpy(),
                                outside_domain=lambda X: np.zeros(len(X), dtype=bool),
                                out_of_bounds="extrapolate")
    info: dict = {}
    notes = _test_row_notes(regressor, X, info, mean_targets=1)
    assert info["outside_box_test_rows"] == 2 and len(notes) == 2
    assert notes[1].startswith("1 target(s) keep the mean of the stages")
    assert "stage_mean = false" in notes[1]
    assert len(_test_row_notes(regressor, X, {}, mean_targets=0)) == 1
    assert _test_row_notes(regressor, X.iloc[:1], {}, mean_targets=1) == []


def test_design_asks_where_the_drifts_coefficients_are_least_known(decay_csv, tmp_path, capsys):
    """``workbench design`` with the parametric family: the Fisher information of the drift's
    coefficients (every covariate the selection could use), as the Hamiltonian family's."""
    config = _decay_config(tmp_path)
    rng = np.random.default_rng(7)
    pool = tmp_path / "pool.csv"
    pd.DataFrame({"t": rng.uniform(0, 3, 60), "temp": rng.normal(0, 2, 60)}).to_csv(
        pool, index=False)
    out = tmp_path / "next.csv"
    assert main(["design", str(config), "--candidates", str(pool), "--n", "4",
                 "--out", str(out)]) == 0
    assert "4 of 60 candidates" in capsys.readouterr().out
    chosen = pd.read_csv(out)
    assert list(chosen["design_rank"]) == [1, 2, 3, 4]
    assert chosen["design_reason"].str.contains("correction coefficients of the model's "
                                                "parameters").all()
    assert (chosen["y_sd"] > 0).all()
    # the coefficients' information is largest far out in temp, where the drift is least known
    assert chosen["temp"].abs().mean() > pd.read_csv(pool)["temp"].abs().mean()


def test_fallback_in_a_parametric_config(decay_csv, tmp_path, capsys):
    """``[model.parametric] fallback = true``: the model at its start values per target where
    the corrections do not help (here they do); not with a stage choosing among priors."""
    config = _decay_config(tmp_path, "fallback = true\n")
    out = tmp_path / "result.json"
    assert main(["evaluate", str(config), "--no-track", "--no-intervals", "--jobs", "1",
                 "--json", str(out)]) == 0
    assert json.loads(out.read_text())["model"]["selected"] == ["parametric:drift"]
    capsys.readouterr()
    assert main(["evaluate", str(config), "--no-track", "--set",
                 "model.parametric.boost_stage=true", "--set",
                 'model.parametric.stage_priors="candidates"']) != 0
    assert 'fallback = true needs stage_priors = "chosen"' in capsys.readouterr().err
