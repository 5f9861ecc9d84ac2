"""A sweep's PostgreSQL server killed (SIGKILL) and restarted mid-sweep: the sweep waits for
it and finishes every study to exactly its budget; a server that stays away ends the command
in one line naming the store; four sweeps, one killed and restarted again and again (slow),
lose and repeat no trial (issue 35)."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import optuna
import psutil
import pytest
from optuna.trial import TrialState

from workbench.experiment.process.errors import StorageError
from workbench.experiment.storage import _rdb, open_storage
from workbench.experiment.sweep.scheduler import is_counted, run_study

from services import Postgres, command_env, tiny_sweep, workbench_cmd

SECRET = "s3cret-pw"


@pytest.fixture
def pg(tmp_path):
    server = Postgres(tmp_path / "pg")
    yield server
    server.stop()


def _kill(pg: Postgres) -> None:
    """SIGKILL the server (as an out-of-memory killer or a crashed host does) and wait for
    its backends to notice and end, as a restart needs."""
    info = pg.server.get_postmaster_info()
    backends = info.process.children()
    os.kill(info.pid, signal.SIGKILL)
    psutil.wait_procs(backends, timeout=30)


def test_a_sweep_waits_for_a_restarted_postgres_and_finishes_exactly(pg, tmp_path):
    url = pg.database("optuna", password=SECRET)
    config = tiny_sweep(tmp_path / "cfg", trials=10)
    err = tmp_path / "err.log"
    cmd = workbench_cmd("sweep", config, "--storage", url, "--no-track", "--json",
                        tmp_path / "out.json")
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=command_env(), stdout=subprocess.DEVNULL,
                            stderr=open(err, "w"))
    try:
        deadline = time.monotonic() + 120
        while "] trial " not in err.read_text():
            assert proc.poll() is None and time.monotonic() < deadline, err.read_text()[-3000:]
            time.sleep(0.02)
        _kill(pg)
        time.sleep(3)  # away for a while
        pg.server.ensure_postgres_running()
        assert proc.wait(timeout=240) == 0, err.read_text()[-3000:]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "Traceback" not in err.read_text()
    storage = optuna.storages.RDBStorage(url)
    names = optuna.get_all_study_names(storage)
    assert len(names) == 3
    for name in names:
        trials = optuna.load_study(study_name=name, storage=storage).get_trials()
        assert sum(is_counted(t) for t in trials) == 10
        assert not [t for t in trials if t.state in (TrialState.RUNNING, TrialState.WAITING)]


def test_a_postgres_that_stays_away_ends_in_one_line_naming_it(pg, tmp_path, monkeypatch):
    storage = open_storage(pg.database("optuna", password=SECRET), tmp_path)
    optuna.create_study(study_name="s", storage=storage)
    monkeypatch.setattr(_rdb, "RETRY_DELAYS_S", (0.05, 0.1))
    _kill(pg)
    start = time.monotonic()
    with pytest.raises(StorageError) as caught:
        storage.get_all_studies()
    message = str(caught.value)
    assert "\n" not in message and SECRET not in message
    assert message.startswith("Optuna storage postgresql+psycopg2://postgres:***@/optuna")
    assert "did not answer" in message and "run the same command" in message
    assert time.monotonic() - start < 10
    pg.server.ensure_postgres_running()  # for the fixture's stop


def test_a_store_away_during_a_trial_is_not_the_configuration_s_fault(tmp_path):
    """A storage error inside the objective (a report the store did not take) ends the
    search; the trial is not recorded as a failed configuration that counts."""
    storage = open_storage(str(tmp_path / "s.journal"), tmp_path)
    study = optuna.create_study(study_name="s", storage=storage)

    def objective(trial):
        raise StorageError("Optuna storage db did not answer")

    with pytest.raises(StorageError):
        run_study(study, objective, 3)
    trials = study.get_trials()
    assert [t.state for t in trials] == [TrialState.RUNNING]  # for the reaper
    assert not [t for t in trials if is_counted(t) and t.state == TrialState.FAIL]


def _running_in(storage, pid: int) -> bool:
    """Whether process ``pid`` runs a trial of any study in ``storage``."""
    return any(t.state == TrialState.RUNNING and t.user_attrs.get("worker", "").endswith(
        f":{pid}") for s in optuna.get_all_study_summaries(storage)
        for t in optuna.load_study(study_name=s.study_name, storage=storage).get_trials(
            deepcopy=False, states=(TrialState.RUNNING,)))


@pytest.mark.slow  # four sweeps on 2 cores, six of them killed: a few minutes
def test_soak_four_sweeps_one_killed_and_restarted_again_and_again(pg, tmp_path):
    """Four ``workbench sweep`` processes share one PostgreSQL; every few seconds one of them
    is SIGKILLed mid-trial and started again. Every study ends with exactly its budget of
    complete trials, none lost, and no killed trial run again more than once."""
    url = pg.database("optuna")
    storage = optuna.storages.RDBStorage(url)
    # SOAK_TRIALS per study (3 studies shared by the 4 processes): 16 by default; the issue's
    # soak of 4 processes x 100 trials is SOAK_TRIALS=134 (about 400 trials in all)
    budget = int(os.environ.get("SOAK_TRIALS", "16"))
    config = tiny_sweep(tmp_path / "cfg", trials=budget)
    cmd = workbench_cmd("sweep", config, "--storage", url, "--no-track")

    def start(n: int) -> subprocess.Popen:
        proc = subprocess.Popen(cmd, cwd=tmp_path, env=command_env(),
                                stdout=subprocess.DEVNULL, stderr=open(tmp_path / f"p{n}.log", "w"))
        proc.log = tmp_path / f"p{n}.log"  # type: ignore[attr-defined]
        return proc

    procs, kills, n = [start(i) for i in range(4)], [], 4
    try:
        deadline = time.monotonic() + 600 + 10 * budget
        while len(kills) < max(6, budget // 8) and any(p.poll() is None for p in procs):
            assert time.monotonic() < deadline
            victim = procs[len(kills) % 4]
            if victim.poll() is None and _running_in(storage, victim.pid):
                victim.kill()
                victim.wait()
                kills.append(victim.pid)
                procs[procs.index(victim)] = start(n)
                n += 1
                time.sleep(2)  # a few seconds between kills
            elif victim.poll() is not None:
                kills.append(None)  # it finished: on to the next one
            time.sleep(0.05)
        for p in procs:
            assert p.wait(timeout=600 + 10 * budget) == 0, p.log.read_text()[-3000:]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    assert len([k for k in kills if k]) >= 3, kills  # it did kill mid-trial
    for log in tmp_path.glob("p*.log"):
        assert "Traceback" not in log.read_text(), log.read_text()[-3000:]
    names = optuna.get_all_study_names(storage)
    assert len(names) == 3
    for name in names:
        trials = optuna.load_study(study_name=name, storage=storage).get_trials()
        counted = [t for t in trials if is_counted(t)]
        assert len(counted) == budget and all(t.state == TrialState.COMPLETE for t in counted), [
            (t.number, t.state.name, t.user_attrs) for t in trials]
        assert not [t for t in trials if t.state in (TrialState.RUNNING, TrialState.WAITING)]
        reruns = [t.system_attrs["failed_trial"] for t in trials
                  if t.system_attrs.get("failed_trial") is not None]
        assert len(reruns) == len(set(reruns)), name  # a killed trial is re-run once at most
