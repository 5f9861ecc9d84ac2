"""workbench sweep for family = "hamiltonian": one study per outer fold (and a final one) for
all targets together, searching [search.hamiltonian] (and the shared boosting stage)."""

from __future__ import annotations

import json
import math

import numpy as np
import optuna
import pytest
from optuna.trial import FixedTrial, TrialState

from workbench.experiment.cli import main
from workbench.experiment.config import ConfigError, load_dataset
from workbench.experiment.families import FAMILIES
from workbench.experiment.runs.evaluate import evaluate
from workbench.experiment.runs.intervals import family_model
from workbench.experiment.runs.prepare import load_config
from workbench.experiment.storage import open_storage
from workbench.experiment.sweep.scheduler import is_counted, run_study
from workbench.experiment.sweep.search import StudySpec, run_sweep, study_names, study_objective
from workbench.simulate import Mismatch, simulate

N = 5
TARGETS = [f"measured_E{i}" for i in range(1, N + 1)]

DATA = f"""
[data]
csv = "sim.csv"
prior = {json.dumps([f"model_E{i}" for i in range(1, N + 1)])}
targets = {json.dumps(TARGETS)}
features = {json.dumps([f"v_q{i}" for i in range(1, N + 1)] + [f"v_c{i}" for i in range(1, N)])}
test_fraction = 0.3

[data.hamiltonian]
onsite = {json.dumps([f"model_f{i}" for i in range(1, N + 1)])}
couplings = {json.dumps([f"model_g{i}" for i in range(1, N)])}
sign = -1
qubit_features = {json.dumps([f"v_q{i}" for i in range(1, N + 1)])}
coupler_features = {json.dumps([f"v_c{i}" for i in range(1, N)])}
"""

MODEL = """
[model]
family = "hamiltonian"
basis = "ridge"
basis_inputs = "prior+features"
input_transform = "standard"

[model.hamiltonian]
selection = "none"
boost_stage = false
prior_cv = 2
"""

SEARCH = """
[search.hamiltonian]
alpha = { low = 0.1, high = 10.0, log = true }
loss = ["huber", "squared_error"]
huber_delta = { low = 0.2, high = 2.0 }
candidates = ["physical", "local", "none"]
selection = ["none"]
"""

SWEEP = """
[cv]
outer_folds = 2
inner_folds = 3
sweep_seed = 0

[study]
trials = 3
storage = "optuna.journal"
"""


@pytest.fixture(scope="module")
def sim_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("sim") / "sim.csv"
    simulate(N, 120, device_seed=0, mismatch=Mismatch.only("coupler_frequency_shift")).data.to_csv(
        path, index=False)
    return path


@pytest.fixture
def project(tmp_path, monkeypatch, sim_csv):
    """A temporary project directory holding the simulated CSV (storage lands there)."""
    (tmp_path / "sim.csv").write_bytes(sim_csv.read_bytes())
    monkeypatch.chdir(tmp_path)
    return tmp_path


def write(directory, *, model=MODEL, search_=SEARCH, sweep=SWEEP, name="h.toml"):
    path = directory / name
    path.write_text(f'name = "hsweep"\nrandom_state = 0\n{DATA}\n{model}\n{search_}\n{sweep}\n')
    return path


def _counts(storage, names):
    return {n: sum(is_counted(t) for t in optuna.load_study(study_name=n, storage=storage)
                   .get_trials()) for n in names}


# --- the search space ---------------------------------------------------------------------

def test_study_names_have_one_block_for_all_targets(project):
    cfg = load_config(write(project))
    assert [(s.name, s.block, s.fold) for s in study_names(cfg, TARGETS)] == [
        ("hsweep.all.outer0", "all", 0), ("hsweep.all.outer1", "all", 1),
        ("hsweep.all.final", "all", None)]
    assert all(s.targets == TARGETS for s in study_names(cfg, TARGETS))
    eig = load_config(write(project, model='[model]\nbasis = "ridge"', search_="",
                            name="e.toml"))
    assert len(study_names(eig, TARGETS)) == 3 * N  # eigenvalue: per target, as before
    first = study_names(eig, TARGETS)[0]
    assert (first.name, first.block, first.targets, first.fold) == (
        "hsweep.measured_E1.outer0", "measured_E1", ["measured_E1"], 0)


def test_sampled_names_and_settings(project):
    cfg = load_config(write(project, search_=SEARCH + '\n[search]\nline_search_penalty = '
                            '{ low = 0.0, high = 0.5 }\n'))
    trial = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=1)).ask()
    ham = cfg.search.sample_family(trial, cfg.family_settings)
    assert set(trial.params) == {"hamiltonian.alpha", "hamiltonian.loss",
                                 "hamiltonian.huber_delta", "hamiltonian.candidates",
                                 "hamiltonian.selection"}
    assert ham.alpha == trial.params["hamiltonian.alpha"] and ham.selection == "none"
    assert ham.prior_cv == 2 and ham.boost_stage is False  # unsearched: the config's
    params = {**trial.params, "line_search_penalty": 0.25}
    chosen = cfg.family.with_trial(cfg, FixedTrial(params), TARGETS)
    s = chosen.model_for("measured_E2")
    assert s["line_search_penalty"] == 0.25 and s["basis"] == "ridge"
    assert chosen.family_settings == ham


@pytest.mark.parametrize("entry, match", [
    ("bogus = [1, 2]", r"\[search\]: hamiltonian\.bogus: unknown key; valid keys "
                       r"are .*'alpha'.*'boost_stage'"),
    ('loss = ["huber", "cauchy"]', r"hamiltonian\.loss = 'cauchy': The 'loss' parameter of "
                                   r"HamiltonianParameterRegressor must be a str among .*"
                                   r"'squared_error'"),
    ('candidates = ["physical", "everything"]', r"hamiltonian\.candidates = 'everything'"),
    ('selection = "backward"', r"hamiltonian\.selection = 'backward'"),
    ('boost_stage = ["yes"]', r"hamiltonian\.boost_stage = 'yes'"),
    ("boost_stage = { low = 0, high = 1 }", r"hamiltonian\.boost_stage"),
    ("alpha = { low = -1.0, high = 1.0 }", r"\[search\]: hamiltonian\.alpha = -1\.0: The "
                                           r"'alpha' parameter of HamiltonianParameterRegressor "
                                           r"must be a float in the range \[0\.0, inf\)"),
    ("huber_delta = [0.0, 1.0]", r"hamiltonian\.huber_delta = 0\.0: The 'huber_delta' "
                                 r"parameter .* must be a float in the range \(0\.0, inf\)"),
    ("selection_cv = { low = 1, high = 3 }", r"hamiltonian\.selection_cv = 1: The 'cv' "
                                             r"parameter of HamiltonianSelectionCV must be an "
                                             r"int in the range \[2, inf\)"),
    ('max_steps = { low = "a", high = "b" }', r"hamiltonian\.max_steps: a range needs numbers"),
    ("alpha = { low = 10.0, high = 1.0 }", r"hamiltonian\.alpha: low 10\.0 is above high"),
])
def test_bad_hamiltonian_search_is_a_config_error(project, entry, match):
    with pytest.raises(ConfigError, match=match):
        load_config(write(project, search_=f"[search.hamiltonian]\n{entry}\n"))


def test_hamiltonian_search_needs_family_hamiltonian(project):
    path = write(project, model='[model]\nbasis = "ridge"', search_=SEARCH)
    with pytest.raises(ConfigError, match=r"\[search\]: unknown key\(s\) \['hamiltonian'\]"):
        load_config(path)


def test_eigenvalue_keys_in_search_are_allowed_for_family_hamiltonian(project):
    stage = '[search]\nbasis = ["ridge", "kernel_ridge"]\nn_stages = { low = 1, high = 2 }\n'
    cfg = load_config(write(project, search_=f"{SEARCH}\n{stage}"))
    assert cfg.search.table["basis"] == ["ridge", "kernel_ridge"]
    assert "hamiltonian" not in cfg.search.table and "alpha" in cfg.search.family_table


# --- the sweep ----------------------------------------------------------------------------

def test_sweep_nested_cv_results_and_resume(project, capsys):
    cfg_path = write(project)
    out = project / "out.json"
    assert main(["sweep", str(cfg_path), "--json", str(out), "--no-track"]) == 0
    res = json.loads(out.read_text())
    assert "nested-CV MAE" in capsys.readouterr().out
    assert res["family"] == "hamiltonian" and res["targets"] == TARGETS
    assert res["trials"] == {"per_study": 3, "counted": 3 * 3, "studies": 3}
    for key in ("nested_cv_mae", "nested_cv_prior_mae"):
        assert len(res[key]) == N and all(math.isfinite(v) for v in res[key])
    # the coupler frequency shift is learnable: far better than the control program
    assert res["nested_cv_mae_avg"] < 0.5 * res["nested_cv_prior_mae_avg"]
    assert res["model"]["test_mae_avg"] < 0.5 * res["prior"]["test_mae_avg"]
    best = res["best_params"]
    assert len(best) == N and all(p == best[0] for p in best)
    assert best[0] and all(k.startswith("hamiltonian.") for k in best[0])

    storage = open_storage("optuna.journal", project)
    names = [s.name for s in study_names(load_config(cfg_path), TARGETS)]
    assert sorted(optuna.get_all_study_names(storage)) == sorted(names)  # nothing else
    assert _counts(storage, names) == {n: 3 for n in names}
    for name in names:
        for t in optuna.load_study(study_name=name, storage=storage).get_trials():
            assert t.state == TrialState.COMPLETE
            folds = t.user_attrs["fold_mae"]
            assert len(folds) == 3 and "heartbeat" in t.user_attrs
            assert t.value == pytest.approx(np.mean(folds))
            assert t.user_attrs["prior_cv_mae"] > t.value
            # median pruner: the running mean of the inner folds' MAE, fold by fold
            running = [np.mean(folds[:i + 1]) for i in range(3)]
            assert [t.intermediate_values[i] for i in range(3)] == pytest.approx(running)

    # a second run resumes: no new trials, the same choice and the same numbers
    sweep = run_sweep(load_config(cfg_path), progress=False)
    res2 = sweep.result.to_json()
    assert _counts(storage, names) == {n: 3 for n in names}
    assert res2["best_params"] == best
    assert res2["nested_cv_mae"] == pytest.approx(res["nested_cv_mae"])
    assert res2["model"]["test_mae"] == pytest.approx(res["model"]["test_mae"])
    folds = sweep.outer_folds
    assert [(f.block, f.fold, f.study) for f in folds] == [
        ("all", 0, "hsweep.all.outer0"), ("all", 1, "hsweep.all.outer1")]
    for f in folds:
        assert f.selected == ",".join(["hamiltonian"] * N)
        assert f.n_train + f.n_val == res["n_train"]
        assert f.mae < f.prior_mae and f.params["hamiltonian.selection"] == "none"
    assert np.mean([f.mae for f in folds]) == pytest.approx(res["nested_cv_mae_avg"])
    # the final model is the final study's choice
    chosen = sweep.config.family_settings
    assert chosen.alpha == best[0]["hamiltonian.alpha"]
    assert chosen.candidates == best[0]["hamiltonian.candidates"]


def test_sweep_with_the_boosting_stage_searched_too(project):
    stage = ('\n[search]\nline_search_penalty = { low = 0.0, high = 0.5 }\n'
             '[selection]\ncv = 2\n')
    search_ = (SEARCH.replace('selection = ["none"]', 'selection = "none"\nboost_stage = [true]')
               .replace('"physical", "local", "none"', '"local", "none"'))  # fewer covariates
    sweep = SWEEP.replace("trials = 3", "trials = 2").replace("inner_folds = 3",
                                                              "inner_folds = 2")
    cfg = load_config(write(project, search_=search_ + stage, sweep=sweep))
    sweep = run_sweep(cfg, progress=False)
    res = sweep.result.to_json()
    best = res["best_params"][0]
    assert set(best) == {"hamiltonian.alpha", "hamiltonian.loss", "hamiltonian.huber_delta",
                         "hamiltonian.candidates", "hamiltonian.boost_stage",
                         "line_search_penalty"}
    model = family_model(sweep.model)
    assert model.boost_stage is True
    penalties = {e.estimator.line_search_penalty for e in model.boost_.estimators_}
    assert penalties == {best["line_search_penalty"]}  # one setting shared by all targets
    assert res["trials"]["counted"] == 3 * 2
    assert res["nested_cv_mae_avg"] < res["nested_cv_prior_mae_avg"]


def test_no_completed_trial_keeps_the_prior_then_the_config_settings(project, monkeypatch):
    def broken(self, cfg, ds, targets, X, Y, trial, cv, report):
        raise RuntimeError("every configuration fails")

    monkeypatch.setattr(type(FAMILIES["hamiltonian"]), "objective", broken)
    cfg = load_config(write(project, sweep=SWEEP.replace("trials = 3", "trials = 1")))
    sweep = run_sweep(cfg, progress=False)
    res = sweep.result.to_json()
    assert res["best_params"] == [None] * N
    assert res["nested_cv_mae"] == res["nested_cv_prior_mae"]  # outer folds: the prior stands
    assert all(f.selected == "prior" for f in sweep.outer_folds)
    own = evaluate(cfg)  # final: the config's own settings
    assert res["model"]["test_mae"] == pytest.approx(own.model.test_mae)


def test_wilcoxon_pruner_reads_each_inner_fold(project):
    cfg = load_config(write(project, sweep=SWEEP + 'pruner = "wilcoxon"\n'))
    ds = load_dataset(cfg)
    study = optuna.create_study(pruner=optuna.pruners.NopPruner())
    run_study(study, study_objective(cfg, ds, StudySpec("w", "all", TARGETS, None)), 2)
    for t in study.get_trials():
        assert [t.intermediate_values[i] for i in range(3)] == t.user_attrs["fold_mae"]


def test_two_worker_processes_run_the_sweep(project):
    """``--workers 2``: spawned processes share the journal; every study still ends with
    exactly ``trials`` counted trials and no trial number twice."""
    cfg = load_config(write(project))
    sweep = run_sweep(cfg.with_study(workers=2), progress=False)
    storage = open_storage(cfg.study.storage, project)
    names = [s.name for s in study_names(cfg, TARGETS)]
    assert _counts(storage, names) == {n: 3 for n in names}
    for n in names:
        numbers = [t.number for t in optuna.load_study(study_name=n, storage=storage)
                   .get_trials()]
        assert len(numbers) == len(set(numbers))
    workers = {t.user_attrs.get("worker") for s in sweep.studies.values()
               for t in s.get_trials() if is_counted(t)}
    assert len(workers) == 2  # both processes took trials
    assert sweep.result.sweep.trials_counted == 3 * len(names)
