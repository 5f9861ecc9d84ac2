"""workbench sweep: nested-CV results, resuming an interrupted study, workers sharing storage."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import optuna
import pytest
from optuna.trial import TrialState

from workbench.experiment.cli import main
from workbench.experiment.storage import open_storage
from workbench.experiment.sweep.scheduler import is_counted, run_study

SMOKE = "experiments/smoke.toml"
#: The smoke sweep as the tests run it: 5 targets, 2 outer folds (the config's 3 less one:
#: each fold is 5 more studies to search and draw), 3 trials per study.
TARGETS, OUTER, TRIALS = 5, 2, 3


@pytest.fixture
def project(tmp_path, monkeypatch, google_5q_dir):
    """Run from a temporary project directory (storage and stores land there)."""
    from pathlib import Path

    smoke = Path(__file__).resolve().parents[1] / SMOKE
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    monkeypatch.chdir(tmp_path)
    return smoke


@pytest.fixture
def smoke_run(project, tmp_path, capsys, monkeypatch, new_store):
    """The smoke sweep (:data:`OUTER` outer folds, :data:`TRIALS` trials per study) with
    tracking in a temporary store, without the family's learning curves and SHAP figures
    (about half the command's CPU time; a sweep's are checked by test_services.py on the same
    ``record``, an evaluate's by test_cli.py).

    First stopped by ``--timeout`` after its first trial (exit 124), then resumed by the same
    command without it, with ``--out``. Returns the result, the store, standard error."""
    from workbench.experiment.families import Artifacts
    from workbench.experiment.families.eigenvalue import EigenvalueFamily

    monkeypatch.setattr(EigenvalueFamily, "begin_artifacts",
                        lambda *args, **kwargs: lambda emit=None: Artifacts())
    out = tmp_path / "out.json"
    uri = new_store(tmp_path / "store" / "mlflow.db")
    args = ["sweep", str(project), "--trials", str(TRIALS), "--set", f"cv.outer_folds={OUTER}",
            "--tracking-uri", uri]
    assert main([*args, "--timeout", "0.01"]) == 124  # no trial starts after the first
    assert main([*args, "--json", str(out), "--out", str(tmp_path / "out")]) == 0
    return json.loads(out.read_text()), uri, capsys.readouterr().err


def test_smoke_sweep_json_and_tracking(smoke_run, tmp_path, project):
    import matplotlib.image
    import mlflow
    import pandas as pd
    from mlflow import MlflowClient

    from workbench.datasets import load_google_5q

    res, uri, err = smoke_run
    for key in ("targets", "prior", "model", "wall_s", "nested_cv_mae", "nested_cv_mae_avg",
                "best_params", "mlflow"):
        assert key in res
    assert len(res["nested_cv_mae"]) == len(res["best_params"]) == TARGETS
    # resumed after the timeout to every study's budget (the outer folds' and a final one)
    studies = TARGETS * (OUTER + 1)
    assert res["trials"] == {"per_study": TRIALS, "counted": studies * TRIALS,
                             "studies": studies}
    assert all(p is None or "basis" in p for p in res["best_params"])
    # the nested-CV estimate of the model beats the prior's on the training rows
    assert res["nested_cv_mae_avg"] < res["nested_cv_prior_mae_avg"]
    assert (tmp_path / "mlruns" / "optuna.journal").is_file()
    assert "trial   0" in err and "best" in err  # a progress line per trial
    stopped = [line for line in err.splitlines() if "timeout" in line]
    assert len(stopped) == 1 and "run the same command again to resume" in stopped[0]

    client = MlflowClient(uri)
    run = client.get_run(res["mlflow"]["run_id"])
    every = client.search_runs([run.info.experiment_id], max_results=1000)
    assert not [r for r in every if r.info.status == "RUNNING"]
    # the run stopped by the timeout ended KILLED, with its one trial; the resumed one has
    # the other trials
    parents = {r.info.status: r.info.run_id for r in every
               if r.data.tags["workbench.kind"] == "sweep"}
    assert sorted(parents) == ["FINISHED", "KILLED"] and parents["FINISHED"] == run.info.run_id
    kinds = pd.crosstab(pd.Series([r.data.tags.get("mlflow.parentRunId") for r in every]),
                        pd.Series([r.data.tags["workbench.kind"] for r in every]))
    assert kinds.loc[parents["KILLED"]].sum() == kinds.loc[parents["KILLED"], "trial"] == 1
    assert kinds.loc[run.info.run_id, "trial"] == studies * TRIALS - 1
    assert kinds.loc[run.info.run_id, "outer_fold"] == TARGETS * OUTER
    for name in ("test_mae_avg", "prior_test_mae_avg", "nested_cv_mae_avg", "cv_mae_avg",
                 "test_mae/eeig1", "test_mse/eeig5", "nested_cv_mae/eeig3"):
        assert name in run.data.metrics
    assert run.data.metrics["test_mae_avg"] == pytest.approx(res["model"]["test_mae_avg"])
    assert run.data.metrics["wall_s"] == pytest.approx(res["wall_s"])  # the whole command's
    # the studies' objective is named (the dashboard's label), with its unit
    from workbench.experiment.sweep.scheduler import OBJECTIVE

    journal = open_storage(str(tmp_path / "mlruns" / "optuna.journal"), tmp_path)
    names = optuna.get_all_study_names(journal)  # the sweep's studies, no bookkeeping
    assert sorted(names) == sorted(f"smoke.eeig{j}.{k}" for j in range(1, TARGETS + 1)
                                   for k in [*(f"outer{i}" for i in range(OUTER)), "final"])
    assert all(optuna.load_study(study_name=n, storage=journal).metric_names
               == [OBJECTIVE] for n in names)
    # recognisable as one sweep's in the dashboard: the name's prefix and user attributes
    attrs = optuna.load_study(study_name="smoke.eeig2.outer1", storage=journal).user_attrs
    assert attrs == {"sweep": "smoke", "config": str(project),
                     "block": "eeig2", "targets": ["eeig2"], "fold": 1}
    assert optuna.load_study(study_name="smoke.eeig2.final",
                             storage=journal).user_attrs["fold"] == "final"
    assert run.data.tags["dataset_hash"] and run.data.tags["git_commit"]
    plots = [a.path for a in client.list_artifacts(run.info.run_id, "plots")]
    assert len(plots) >= 3 and all(p.endswith(".png") for p in plots)
    local = client.download_artifacts(run.info.run_id, plots[0], str(tmp_path))
    assert matplotlib.image.imread(local).size > 0

    # Optuna's figures of every study, in its outer fold's run (the final studies, which
    # have none, in the sweep's) and under --out, and the importances
    def is_png(path):
        return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and matplotlib.image.imread(path).size

    optuna_dir = Path(client.download_artifacts(run.info.run_id, "optuna", str(tmp_path / "dl")))
    folds = {r.data.tags["study"]: r.info.run_id for r in every
             if r.data.tags["workbench.kind"] == "outer_fold"
             and r.data.tags.get("mlflow.parentRunId") == run.info.run_id}
    assert len(folds) == TARGETS * OUTER and all(".outer" in name for name in folds)
    in_runs = {name: Path(client.download_artifacts(folds[name], "optuna",
                                                    str(tmp_path / "dl" / name)))
               if name in folds else optuna_dir / "studies" / name for name in names}
    assert sorted(p.name for p in (optuna_dir / "studies").iterdir()) == sorted(
        name for name in names if name.endswith(".final"))
    for folder in (optuna_dir, tmp_path / "out"):
        for name in names:
            study = folder / "studies" / name if folder != optuna_dir else in_runs[name]
            for figure in ("history", "importances", "parallel_coordinate", "slice"):
                assert is_png(study / f"{figure}.png"), (name, figure)
            table = pd.read_csv(study / "importances.csv")
            assert list(table.columns) == ["param", "importance"] and len(table) >= 2
            assert table["importance"].sum() == pytest.approx(1.0)
        assert is_png(folder / "outer_folds.png")
        assert set(pd.read_csv(folder / "importances.csv")["study"]) == set(names)

    ds = load_google_5q()
    _, X_test, _, _ = ds.split()
    served = mlflow.pyfunc.load_model(
        client.get_logged_model(res["mlflow"]["model_uri"].split("/")[-1]).artifact_location
    ).predict(X_test)
    # the targets, then their conformal intervals ([intervals] is on by default)
    assert list(served.columns[:5]) == ds.target_names
    assert sorted(served.columns[5:]) == sorted(f"{t}_{s}" for t in ds.target_names
                                                for s in ("lower", "upper"))
    test_mae = (served[ds.target_names].to_numpy() - ds.targets.loc[ds.test_index].to_numpy())
    assert abs(test_mae).mean(axis=0) == pytest.approx(res["model"]["test_mae"], rel=1e-9)


INTERRUPTED = textwrap.dedent("""
    import os, sys, optuna
    from pathlib import Path
    from workbench.experiment.sweep.scheduler import run_study
    from workbench.experiment.storage import open_storage
    study = optuna.create_study(study_name="s", storage=open_storage(sys.argv[1], Path(".")),
                                load_if_exists=True)
    calls = []
    def objective(trial):
        calls.append(1)
        if len(calls) == 4:
            os._exit(3)  # the machine goes away in the middle of a trial
        return trial.suggest_float("x", 0, 1) ** 2
    run_study(study, objective, 8)
""")


def test_interrupted_study_resumes_without_losing_or_repeating_trials(tmp_path):
    journal = str(tmp_path / "s.journal")
    proc = subprocess.run([sys.executable, "-c", INTERRUPTED, journal], capture_output=True)
    assert proc.returncode == 3
    study = optuna.load_study(study_name="s", storage=open_storage(journal, tmp_path))
    before = {t.number: t.params for t in study.get_trials() if t.state == TrialState.COMPLETE}
    assert len(before) == 3
    assert [t.state for t in study.get_trials()].count(TrialState.RUNNING) == 1

    run_study(study, lambda trial: trial.suggest_float("x", 0, 1) ** 2, 8)
    trials = study.get_trials()
    assert sum(is_counted(t) for t in trials) == 8
    assert sum(t.state == TrialState.COMPLETE for t in trials) == 8
    assert {t.number: t.params for t in trials if t.number in before} == before  # kept
    stale = [t for t in trials if t.state == TrialState.FAIL]
    assert len(stale) == 1 and not is_counted(stale[0])  # the interrupted one, not counted
    assert len(trials) == 9


WORKER = textwrap.dedent("""
    import sys, time, optuna
    from pathlib import Path
    from workbench.experiment.sweep.scheduler import run_study
    from workbench.experiment.storage import open_storage
    study = optuna.load_study(study_name="w", storage=open_storage(sys.argv[1], Path(".")))
    # both workers start their trials together: under load one process's imports can
    # outlast the other's twelve trials
    ready = Path(sys.argv[2])
    (ready / sys.argv[3]).touch()
    deadline = time.monotonic() + 100
    while len(list(ready.iterdir())) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    def objective(trial):
        time.sleep(0.05)
        return trial.suggest_float("x", -1, 1) ** 2
    run_study(study, objective, 12)
""")


def test_two_workers_finish_exactly_n_trials(tmp_path):
    journal = str(tmp_path / "w.journal")
    optuna.create_study(study_name="w", storage=open_storage(journal, tmp_path))
    ready = tmp_path / "ready"
    ready.mkdir()
    procs = [subprocess.Popen([sys.executable, "-c", WORKER, journal, str(ready), str(i)])
             for i in range(2)]
    assert [p.wait(timeout=120) for p in procs] == [0, 0]
    trials = optuna.load_study(study_name="w", storage=open_storage(journal, tmp_path)).get_trials()
    counted = [t for t in trials if is_counted(t)]
    assert len(counted) == 12
    assert sum(t.state == TrialState.COMPLETE for t in counted) == 12
    assert len({t.number for t in trials}) == len(trials)  # no duplicated trial numbers
    assert len({t.user_attrs["worker"] for t in counted}) == 2  # both workers took part


def test_failed_and_pruned_trials_are_recorded_not_chosen(tmp_path):
    study = optuna.create_study(study_name="f", storage=open_storage(str(tmp_path / "f.j"),
                                                                      tmp_path))

    def objective(trial):
        x = trial.suggest_int("x", 0, 5)
        if trial.number == 1:
            raise RuntimeError("basis exploded")
        if trial.number == 2:
            raise optuna.TrialPruned("pruned after inner fold 0")
        return float(x)

    run_study(study, objective, 5)
    states = [t.state for t in study.get_trials()]
    assert states.count(TrialState.FAIL) == 1 and states.count(TrialState.PRUNED) == 1
    assert study.get_trials()[1].user_attrs["error"] == "RuntimeError: basis exploded"
    assert study.best_trial.state == TrialState.COMPLETE


def test_trial_of_a_vanished_machine_is_failed_and_rerun(tmp_path):
    import time

    study = optuna.create_study(study_name="m", storage=open_storage(str(tmp_path / "m.j"),
                                                                      tmp_path))
    ghost = study.ask()  # started on another machine that then went away
    ghost.set_user_attr("worker", "other-host:4242")
    ghost.set_user_attr("heartbeat", time.time() - 3600)
    live = study.ask()  # another machine's trial that is still running (fresh heartbeat)
    live.set_user_attr("worker", "other-host:4243")
    live.set_user_attr("heartbeat", time.time())

    def finish_live_later(trial):
        if trial.number == 4:  # the live trial finishes while this worker is busy
            study.tell(live, 0.5)
        return trial.suggest_float("x", 0, 1)

    run_study(study, finish_live_later, 5, stale_after_s=60)
    trials = study.get_trials()
    assert trials[0].state == TrialState.FAIL and not is_counted(trials[0])
    assert trials[1].state == TrialState.COMPLETE and trials[1].value == 0.5
    assert sum(is_counted(t) for t in trials) == 5
    assert all(t.state != TrialState.RUNNING for t in trials)


def _cfg(sampler="tpe", trials=14, seed=3):
    from types import SimpleNamespace

    return SimpleNamespace(cv=SimpleNamespace(sweep_seed=seed), study=SimpleNamespace(
        sampler=sampler, trials=trials, timeout=None, stale_after_s=60))


def _search(storage, cfg, names=("a", "b")) -> dict[str, list[dict]]:
    """``run_studies`` on studies ``names`` with a toy objective; their trials' params."""
    from workbench.experiment.sweep.scheduler import open_study, run_studies, sampler

    def objective(trial):
        x, n = trial.suggest_float("x", -2, 2), trial.suggest_int("n", 1, 9)
        c = trial.suggest_categorical("c", ["u", "v"])
        return (x - 0.5) ** 2 + abs(n - 4) / 9 + (c == "v")

    studies = [(open_study(n, storage, sampler=sampler(cfg)), objective) for n in names]
    run_studies(cfg, studies)
    return {s.study_name: [t.params for t in s.get_trials()] for s, _ in studies}


def test_one_seed_gives_the_same_trials(tmp_path):
    """A lone process proposes the same trials run after run (random and TPE, past TPE's 10
    random startup trials), on any storage; another seed, or another study, other ones."""
    for kind in ("tpe", "random"):
        first = _search(open_storage(str(tmp_path / f"{kind}1.journal"), tmp_path), _cfg(kind))
        again = _search(optuna.storages.InMemoryStorage(), _cfg(kind))
        assert first == again and len(first["a"]) == 14
        assert first["a"] != first["b"]  # seeded by the study's name too
        other = _search(optuna.storages.InMemoryStorage(), _cfg(kind, seed=4))
        assert other["a"][0] != first["a"][0]


def test_a_trial_number_draws_the_same_numbers_in_any_process():
    """Two processes (samplers) on one study, taking turns: distinct proposals, and each
    trial's the ones a lone process draws for that trial number (random phase)."""
    from workbench.experiment.sweep.scheduler import sampler, trial_seed

    storage = optuna.storages.InMemoryStorage()
    optuna.create_study(study_name="s", storage=storage)
    procs = [optuna.load_study(study_name="s", storage=storage, sampler=sampler(_cfg()))
             for _ in range(2)]
    shared = [procs[i % 2].ask().suggest_float("x", 0, 1) for i in range(6)]
    alone = optuna.create_study(study_name="s", sampler=sampler(_cfg()))
    assert [alone.ask().suggest_float("x", 0, 1) for _ in range(6)] == shared
    assert len(set(shared)) == 6
    assert len({trial_seed(3, "s", n) for n in range(1000)}) == 1000
    assert trial_seed(3, "s", 0) != trial_seed(3, "t", 0) != trial_seed(4, "s", 0)


def test_a_storage_with_older_stream_studies_still_sweeps(tmp_path):
    """Studies ``<name>.streams`` that earlier versions kept in the storage (a dummy trial
    per process) are left alone: the sweep adds nothing beside its own studies."""
    journal = open_storage(str(tmp_path / "old.journal"), tmp_path)
    legacy = optuna.create_study(study_name="a.streams", storage=journal)
    legacy.tell(legacy.ask(), 0.0)
    _search(journal, _cfg(trials=3))
    assert sorted(optuna.get_all_study_names(journal)) == ["a", "a.streams", "b"]
    assert [t.value for t in optuna.load_study(study_name="a.streams",
                                               storage=journal).get_trials()] == [0.0]


def _fake_search(cfg, storage_url, progress=False, worker=0, on_trial=None, dataset=None):
    """Records where it runs, then waits (up to 30 s) until the other search runs too: two
    searches at once, as a sweep's workers are."""
    import time

    from workbench.parallel import effective_n_jobs, in_worker

    folder = Path(storage_url).parent
    (folder / f"worker-{worker}.txt").write_text(
        f"{os.getpid()} {in_worker()} {effective_n_jobs(-1)}")
    deadline = time.monotonic() + 30
    while len(list(folder.glob("worker-*.txt"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)


def test_sweep_workers_are_the_command_s_worker_processes(tmp_path):
    """``--workers 2``: the searches run as tasks on the command's forked worker processes
    (one mechanism for every parallel part; no process forked after the command's threads
    start), each a worker whose own fits are serial."""
    from types import SimpleNamespace

    from workbench.experiment.sweep.workers import search_in_workers
    from workbench.parallel import worker_pool

    cfg = SimpleNamespace(study=SimpleNamespace(stale_after_s=60))
    journal = tmp_path / "w.journal"
    with worker_pool(2, eager=True):
        search_in_workers(_fake_search, cfg, str(journal), 2, False, ["a"], tmp_path,
                          attrs={"a": {"sweep": "s", "fold": 0}})
    seen = [(tmp_path / f"worker-{i}.txt").read_text().split() for i in range(2)]
    pids = {pid for pid, _, _ in seen}
    assert len(pids) == 2 and str(os.getpid()) not in pids
    assert all(worker == "True" and jobs == "1" for _, worker, jobs in seen)
    study = optuna.load_study(study_name="a", storage=open_storage(str(journal), tmp_path))
    assert study.user_attrs == {"sweep": "s", "fold": 0}  # created once, before the workers


