"""Runs never left RUNNING (signals, silent deaths), safe first use of a SQLite store, storage
errors of one line, heartbeats while a trial runs, distinct sampler streams per trial."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import threading
import time

import optuna
import pytest
from mlflow import MlflowClient
from optuna.trial import TrialState

from workbench.experiment.cli import main
from workbench.experiment.process import signals
from workbench.experiment.process.errors import redact
from workbench.experiment.storage import open_storage
from workbench.experiment.sweep.scheduler import fail_stale, is_counted, run_study, sampler
from workbench.experiment.tracking import lifecycle
from workbench.experiment.tracking.runs import Tracker
from workbench.experiment.tracking.store_template import store_template

from services import command_env, free_port, tiny_sweep, workbench_cmd


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    return tiny_sweep(tmp_path_factory.mktemp("tiny"), trials=4)


def _sweep_studies(storage) -> list[str]:
    names = optuna.get_all_study_names(storage)
    assert len(names) == 3
    return names


def _runs(uri):
    client = MlflowClient(uri)
    exp = client.get_experiment_by_name("tiny")
    return client.search_runs([exp.experiment_id]) if exp else []


def _sweep_until_a_trial(cmd, cwd, err):
    """Start ``cmd``; return it once its search runs (its parent run exists then)."""
    fh = open(err, "w")
    proc = subprocess.Popen(cmd, cwd=cwd, env=command_env(), stdout=subprocess.DEVNULL,
                            stderr=fh)
    deadline = time.monotonic() + 120
    while "] trial " not in err.read_text() and time.monotonic() < deadline:
        assert proc.poll() is None, err.read_text()[-3000:]
        time.sleep(0.05)
    return proc


def _kill_with_trials_claimed(proc, journal, tmp_path) -> None:
    """SIGKILL ``proc`` at a moment when trials run and each carries its ``worker`` (a trial
    killed between Optuna's ``ask`` and that attribute has no owner to probe: it waits for
    ``stale_after_s``, as on another host). The process is stopped while the test looks."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        proc.send_signal(signal.SIGSTOP)
        storage = open_storage(str(journal), tmp_path)
        running = [t for name in _sweep_studies(storage)
                   for t in optuna.load_study(study_name=name, storage=storage).get_trials(
                       deepcopy=False, states=(TrialState.RUNNING,))]
        if running and all("worker" in t.user_attrs for t in running):
            proc.send_signal(signal.SIGKILL)
            return
        proc.send_signal(signal.SIGCONT)
        time.sleep(0.05)
    raise AssertionError("no moment with every running trial claimed")


def test_runs_never_left_running(tiny, tmp_path, new_store):
    """SIGKILL leaves a RUNNING run that the next command marks FAILED at its start (its
    process is gone); SIGINT and SIGTERM end the run KILLED, print one line and exit 130 /
    143; every interrupted trial is failed and queued again."""
    uri = new_store(tmp_path / "mlflow.db")  # first use: the concurrent evaluates below
    journal = tmp_path / "s.journal"
    # 30 trials a study: the search lasts seconds, so the kill lands while trials run
    cmd = workbench_cmd("sweep", tiny, "--storage", journal, "--tracking-uri", uri,
                        "--trials", "30")

    def status(proc):
        return {r.data.tags.get("workbench.pid"): r.info.status for r in _runs(uri)}[
            str(proc.pid)]

    silent = _sweep_until_a_trial(cmd, tmp_path, tmp_path / "kill.log")
    _kill_with_trials_claimed(silent, journal, tmp_path)
    silent.wait(timeout=30)
    assert status(silent) == "RUNNING"
    for signum, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        err = tmp_path / f"{signum}.log"
        proc = _sweep_until_a_trial(cmd, tmp_path, err)
        assert status(silent) == "FAILED"  # found dead when this command started
        assert status(proc) == "RUNNING"  # the sweep's run exists during the search
        proc.send_signal(signum)
        assert proc.wait(timeout=60) == code
        text = err.read_text()
        assert "Traceback" not in text and text.count("interrupted") == 1
        assert text.splitlines()[-1] == "workbench: interrupted; run the same command to resume"
        assert status(proc) == "KILLED"
    runs = _runs(uri)
    assert not [r for r in runs if r.info.status == "RUNNING"]
    dead = [r for r in runs if r.data.tags.get("workbench.pid") == str(silent.pid)]
    assert dead[0].data.tags["workbench.failed"] == "its process is gone"
    storage = open_storage(str(journal), tmp_path)
    for name in _sweep_studies(storage):
        trials = optuna.load_study(study_name=name, storage=storage).get_trials()
        interrupted = [t for t in trials if t.state == TrialState.FAIL and not is_counted(t)]
        retried = [t for t in trials if "failed_trial" in t.system_attrs]
        assert len(retried) == len(interrupted)  # each queued once more
        assert not [t for t in trials if t.state == TrialState.RUNNING]


def test_reaper_uses_heartbeats_for_other_hosts(tmp_path, new_store):
    tracker = Tracker(new_store(tmp_path / "mlflow.db"), "reap")
    now = time.time()
    tags = {lifecycle.HOST_TAG: "another-host", lifecycle.PID_TAG: "4242"}
    silent = tracker.start_run("silent", tags={**tags, lifecycle.HEARTBEAT_TAG: now - 600})
    beating = tracker.start_run("beating", tags={**tags, lifecycle.HEARTBEAT_TAG: now})
    child = tracker.start_run("child", parent_run_id=silent)
    with lifecycle.live_run(tracker, "mine") as mine:  # this process: alive
        assert sorted(lifecycle.reap_stale_runs(tracker, grace_s=60)) == sorted([silent, child])
        status = {r: tracker.client.get_run(r).info.status for r in (silent, beating, mine)}
    assert status == {silent: "FAILED", beating: "RUNNING", mine: "RUNNING"}
    assert tracker.client.get_run(mine).info.status == "FINISHED"


def test_two_concurrent_evaluates_on_a_new_sqlite_store(tiny, tmp_path):
    """A machine's first store (no template in the cache: MLflow migrates it) made by two
    commands at once: both finish, and one of them keeps the template."""
    uri = f"sqlite:///{tmp_path / 'new' / 'mlflow.db'}"
    cmd = workbench_cmd("evaluate", tiny, "--tracking-uri", uri)
    env = command_env(XDG_CACHE_HOME=str(tmp_path / "cache"))
    procs = [subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=240) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1][-2000:] for o in outs]
    assert [r.info.status for r in _runs(uri)] == ["FINISHED", "FINISHED"]
    assert len(list((tmp_path / "cache" / "workbench" / "mlflow-stores").glob("*.db"))) == 1


def test_a_new_store_starts_as_a_copy_of_the_kept_template(tmp_path, monkeypatch):
    """The first new store is migrated by MLflow and kept empty in the cache; the next new
    store is its copy (no migration), gets its own Default experiment, and works."""
    import sqlite3

    import mlflow.store.db.utils as db_utils

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    template = store_template()
    assert not template.exists()
    monkeypatch.chdir(tmp_path)
    lifecycle.prepare_store(Tracker(f"sqlite:///{tmp_path / 'a' / 'mlflow.db'}", "first"))
    with contextlib.closing(sqlite3.connect(template)) as db:
        assert db.execute("SELECT count(*) FROM experiments").fetchone() == (0,)
        assert db.execute("SELECT count(*) FROM alembic_version").fetchone() == (1,)

    def no_migration(engine):
        raise AssertionError("MLflow migrated a store copied from the template")

    migrate = db_utils._initialize_tables
    monkeypatch.setattr(db_utils, "_initialize_tables", no_migration)
    (tmp_path / "b").mkdir()
    monkeypatch.chdir(tmp_path / "b")
    tracker = Tracker(f"sqlite:///{tmp_path / 'b' / 'mlflow.db'}", "second")
    lifecycle.prepare_store(tracker)
    run = tracker.start_run("r")
    tracker.log_metrics(run, {"mae": 1.0})
    tracker.end_run(run, "FINISHED")
    experiments = {e.name: e.artifact_location for e in tracker.client.search_experiments()}
    assert sorted(experiments) == ["Default", "second"]
    assert str(tmp_path / "b") in experiments["Default"]  # its own, not the template's
    with contextlib.closing(sqlite3.connect(template)) as db:  # the template stays empty
        assert db.execute("SELECT count(*) FROM runs").fetchone() == (0,)
    # an existing store is never replaced by the template
    before = (tmp_path / "b" / "mlflow.db").read_bytes()
    lifecycle.prepare_store(Tracker(f"sqlite:///{tmp_path / 'b' / 'mlflow.db'}", "second"))
    assert (tmp_path / "b" / "mlflow.db").read_bytes() == before
    # a damaged template is dropped: MLflow creates the store, which is kept instead
    monkeypatch.setattr(db_utils, "_initialize_tables", migrate)
    template.write_bytes(template.read_bytes()[:8192])
    tracker = Tracker(f"sqlite:///{tmp_path / 'c' / 'mlflow.db'}", "third")
    lifecycle.prepare_store(tracker)
    tracker.end_run(tracker.start_run("r"), "FINISHED")
    with contextlib.closing(sqlite3.connect(template)) as db:
        assert db.execute("PRAGMA quick_check").fetchall() == [("ok",)]


@pytest.mark.parametrize("storage, problem", [
    ("{dir}", "is a directory"),
    ("mysql+mysqldb://user:s3cret@127.0.0.1/db", "driver is not installed"),
    ("postgresql+psycopg2://user:s3cret@127.0.0.1:{port}/db", "cannot connect"),
])
def test_storage_problems_end_in_one_line(tiny, tmp_path, capsys, storage, problem):
    storage = storage.format(dir=tmp_path, port=free_port())
    assert main(["sweep", str(tiny), "--storage", storage, "--no-track"]) == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("workbench: error:")]
    assert len(errors) == 1 and problem in errors[0], err
    assert "Traceback" not in err and "s3cret" not in err


def test_redact_hides_passwords():
    assert redact("postgresql://u:pw@h:5432/db") == "postgresql://u:***@h:5432/db"
    assert redact("http://u:pw@h:5000") == "http://u:***@h:5000"
    assert redact("mlruns/optuna.journal") == "mlruns/optuna.journal"


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupt_inside_bookkeeping_is_raised_after_it(signum):
    """A signal inside ``interrupts_deferred`` (a trial being asked or told) is raised only
    once the block is left: no trial is left RUNNING by an interrupt between ``ask`` and its
    objective (seen on a fresh clone: a SIGINT right after a trial line)."""
    done = []
    with pytest.raises(signals.Interrupted):
        with signals.handle_signals():
            with signals.interrupts_deferred():
                os.kill(os.getpid(), signum)
                time.sleep(0.2)  # the handler ran meanwhile
                done.append("block finished")
            done.append("not reached")  # raised as the block is left
    assert done == ["block finished"]


def test_an_interrupt_during_the_ask_fails_and_queues_the_asked_trial(tmp_path, monkeypatch):
    """A signal that arrives while a trial is being asked is raised as the deferred block is
    left: run_study fails that trial and queues it again, as when the objective is
    interrupted (it was left RUNNING; seen under load in test_runs_never_left_running)."""
    from workbench.experiment.sweep import scheduler

    ask = scheduler._start_trial

    def ask_then_signal(study, worker):
        trial = ask(study, worker)
        os.kill(os.getpid(), signal.SIGINT)  # pending: the ask's block is deferring it
        time.sleep(0.2)
        return trial

    monkeypatch.setattr(scheduler, "_start_trial", ask_then_signal)
    study = optuna.create_study(study_name="ask",
                                storage=open_storage(str(tmp_path / "a.journal"), tmp_path))
    with pytest.raises(signals.Interrupted):
        with signals.handle_signals():
            run_study(study, lambda trial: 1.0, 3)
    trials = study.get_trials()
    assert [t.state for t in trials] == [TrialState.FAIL, TrialState.WAITING]
    assert not is_counted(trials[0]) and "failed_trial" in trials[1].system_attrs


def test_an_interrupt_does_not_wait_for_mlflow_s_retries(monkeypatch):
    """Outside the deferred bookkeeping, Ctrl-C interrupts at once, even while MLflow retries
    a request to a server that does not answer (its retries with back-off take minutes)."""
    from mlflow import MlflowClient

    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "8")  # MLflow allows at most 10
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    start = time.monotonic()
    with pytest.raises(signals.Interrupted):
        with signals.handle_signals():
            timer.start()
            MlflowClient("http://127.0.0.1:9").search_experiments()  # discard port: refused
    assert time.monotonic() - start < 10


@pytest.mark.parametrize("kind", ["journal", "sqlite"])
def test_heartbeat_beats_while_a_long_trial_runs(tmp_path, kind):
    """A trial longer than the grace period is not failed by another worker's check: its
    heartbeat beats from a background thread (Optuna's table for RDB, a user attribute for
    the journal). The grace period is 4 s with a beat every second: on a loaded machine a
    SQLite write can wait a second or more for its lock, so a 2 s grace could pass between two
    beats that were both on time."""
    url = str(tmp_path / "h.journal") if kind == "journal" else f"sqlite:///{tmp_path}/h.db"
    storage = open_storage(url, tmp_path, stale_after_s=4)
    study = optuna.create_study(study_name="h", storage=storage)
    checks, stop = [], threading.Event()

    def other_worker():  # another machine's view: same study, checking for stale trials
        other = optuna.load_study(study_name="h", storage=open_storage(url, tmp_path,
                                                                       stale_after_s=4))
        while not stop.wait(0.5):
            fail_stale(other, 4)
            checks.append(1)

    def objective(trial):
        time.sleep(6)  # one long fold, longer than the grace period
        return trial.suggest_float("x", 0, 1)

    watcher = threading.Thread(target=other_worker)
    watcher.start()
    try:
        run_study(study, objective, 1, stale_after_s=4)
    finally:
        stop.set()
        watcher.join()
    assert len(checks) >= 5
    assert [t.state for t in study.get_trials()] == [TrialState.COMPLETE]


@pytest.mark.parametrize("finished", [False, True], ids=["mid-trial", "before-its-tell"])
def test_dead_worker_on_this_host_is_failed_at_once_and_rerun_once(tmp_path, finished):
    """A trial whose process died is failed, not counted, and re-run once: also when the
    process died between setting ``finished_by`` and its own ``tell`` (seen under load)."""
    study = optuna.create_study(study_name="d", storage=open_storage(str(tmp_path / "d.j"),
                                                                      tmp_path))
    gone = subprocess.Popen(["true"])
    gone.wait()
    ghost = study.ask({"x": optuna.distributions.FloatDistribution(0, 1)})
    ghost.set_user_attr("worker", f"{socket.gethostname()}:{gone.pid}")
    ghost.set_user_attr("heartbeat", time.time())  # fresh: only the dead pid tells
    if finished:
        ghost.set_user_attr("finished_by", f"{socket.gethostname()}:{gone.pid}")
    seen = []
    run_study(study, lambda t: seen.append(t.params["x"]) or t.suggest_float("x", 0, 1), 3,
              stale_after_s=600)
    trials = study.get_trials()
    assert trials[0].state == TrialState.FAIL and not is_counted(trials[0])
    assert seen[0] == trials[0].params["x"]  # re-run with the same parameters
    assert trials[1].system_attrs["failed_trial"] == 0
    assert sum(is_counted(t) for t in trials) == 3


def test_processes_draw_distinct_streams(tmp_path):
    """Four processes (threads, each with its own study object and sampler) start trials on
    one study at once: distinct trial numbers, so distinct random streams and proposals;
    the storage holds the study alone (no bookkeeping beside it)."""
    from types import SimpleNamespace

    cfg = SimpleNamespace(cv=SimpleNamespace(sweep_seed=0), study=SimpleNamespace(sampler="tpe"))
    storage = open_storage(str(tmp_path / "c.journal"), tmp_path)
    optuna.create_study(study_name="c", storage=storage)
    drawn: dict[int, float] = {}

    def process():
        study = optuna.load_study(study_name="c", storage=storage, sampler=sampler(cfg))
        trial = study.ask()
        drawn[trial.number] = trial.suggest_float("x", 0, 1)

    threads = [threading.Thread(target=process) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(drawn) == [0, 1, 2, 3] and len(set(drawn.values())) == 4
    assert optuna.get_all_study_names(storage) == ["c"]


def test_rerun_after_killing_a_sweep_and_its_workers(tiny, tmp_path, new_store,
                                                    monkeypatch, capsys):
    """SIGKILL on the parent of ``--workers 2``: the workers end with it (their trials are
    queued again); the rerun does not wait for ``stale_after_s`` (600 s here)."""
    uri = new_store(tmp_path / "mlflow.db")  # first use: the concurrent evaluates below
    storage = str(tmp_path / "w.journal")
    cmd = workbench_cmd("sweep", tiny, "--storage", storage, "--tracking-uri", uri,
                        "--workers", "2")
    log = tmp_path / "parent.log"
    parent = subprocess.Popen(cmd, cwd=tmp_path, env=command_env(), stdout=subprocess.DEVNULL,
                              stderr=open(log, "w"))
    try:
        rdb = open_storage(storage, tmp_path)
        deadline = time.monotonic() + 120
        workers: set[int] = set()
        while len(workers) < 2 and time.monotonic() < deadline:
            workers = {int(t.user_attrs["worker"].rpartition(":")[2])
                       for s in optuna.get_all_study_summaries(rdb)
                       for t in optuna.load_study(study_name=s.study_name, storage=rdb)
                       .get_trials(deepcopy=False) if "worker" in t.user_attrs}
            time.sleep(0.1)
        assert len(workers) == 2, log.read_text()[-3000:]
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=30)
    finally:
        if parent.poll() is None:
            parent.kill()
    deadline = time.monotonic() + 90  # a worker in a fold notices at the fold's end
    while time.monotonic() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.2)
    assert not any(_alive(p) for p in workers), "workers outlived their parent"

    # the same command, in this process (what it does is the check, not its process: no
    # second start, about 4 CPU-s of imports); it must not wait for stale_after_s (600 s)
    monkeypatch.chdir(tmp_path)
    start = time.monotonic()
    assert main([*cmd[3:-2], "--no-track"]) == 0, capsys.readouterr().err[-3000:]
    assert time.monotonic() - start < 240  # << stale_after_s: no wait for the dead workers
    for name in _sweep_studies(rdb):
        trials = optuna.load_study(study_name=name, storage=rdb).get_trials()
        assert sum(is_counted(t) for t in trials) == 4
        assert not [t for t in trials if t.state in (TrialState.RUNNING, TrialState.WAITING)]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (exited, not yet reaped by init) counts as gone
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False
