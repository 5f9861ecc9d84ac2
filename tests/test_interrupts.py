"""Interrupts end a command from any phase: one line, exit 130 (SIGINT) / 143 (SIGTERM)
within seconds, nothing written, the run KILLED, the worker processes gone, and the same
command resumes exactly."""

from __future__ import annotations

import os
import queue
import random
import signal
import sqlite3
import subprocess
import threading
import time
from pathlib import Path

import optuna
import pytest
from mlflow import MlflowClient
from optuna.trial import TrialState

from workbench.experiment.cli import main
from workbench.experiment.process import signals
from workbench.experiment.process.signals import MESSAGE
from workbench.experiment.storage import open_storage
from workbench.experiment.sweep.scheduler import is_counted
from workbench.experiment.tracking.runs import Tracker

from services import command_env, tiny_sweep, workbench_cmd

#: What "within seconds" means here: the issue's bound, with room for a loaded machine.
ENDS_WITHIN_S = 10


def _within_s() -> float:
    """:data:`ENDS_WITHIN_S`, times how oversubscribed the cores are: at load 16 on 2 cores a
    process gets an eighth of a core, and 10 s failed (twice in three runs of this file at
    load 15-17) where a quiet machine ends the command in a second or two."""
    return ENDS_WITHIN_S * max(1.0, os.getloadavg()[0] / (os.cpu_count() or 1))


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    return tiny_sweep(tmp_path_factory.mktemp("tiny"), trials=8)


def _start(cmd: list, cwd: Path, err: Path, phase: str) -> subprocess.Popen:
    """Start ``cmd`` in its own process group; return it once its standard error shows
    ``phase``."""
    proc = subprocess.Popen(cmd, cwd=cwd, env=command_env(), stdout=subprocess.DEVNULL,
                            stderr=open(err, "w"), start_new_session=True)
    deadline = time.monotonic() + 120
    while phase not in err.read_text():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise AssertionError(f"{phase!r} never came:\n{err.read_text()[-3000:]}")
        time.sleep(0.02)
    return proc


def _children(pid: int) -> set[int]:
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        out.update(int(c) for c in (task / "children").read_text().split())
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:  # a zombie (exited, unreaped) counts as gone
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def _ends(proc: subprocess.Popen, signum: int, *, group: bool = False) -> float:
    """Send ``signum`` (to the process group with ``group``, as Ctrl-C in a terminal does);
    return the seconds until ``proc`` exits (killed, and the test failed, after
    :func:`_within_s`)."""
    start, within = time.monotonic(), _within_s()
    if group:
        os.killpg(proc.pid, signum)
    else:
        proc.send_signal(signum)
    try:
        proc.wait(timeout=within)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        pytest.fail(f"still running {within:.0f} s after {signal.Signals(signum).name}")
    return time.monotonic() - start


def _one_line(err: Path) -> None:
    text = err.read_text()
    assert "Traceback" not in text, text[-3000:]
    assert text.count(f"workbench: {MESSAGE}") == 1, text[-3000:]
    assert text.splitlines()[-1] == f"workbench: {MESSAGE}"


def _statuses(uri: str) -> list[str]:
    """The statuses of the commands' runs (not of a sweep's trials, their children)."""
    client = MlflowClient(uri)
    return [r.info.status for r in client.search_runs(
        [e.experiment_id for e in client.search_experiments()])
        if "mlflow.parentRunId" not in r.data.tags]


@pytest.mark.parametrize("signum, group", [(signal.SIGTERM, False), (signal.SIGINT, True)],
                         ids=["SIGTERM", "Ctrl-C"])
def test_an_interrupted_sweep_with_two_workers_ends_and_resumes_exactly(tiny, tmp_path,
                                                                        new_store, signum,
                                                                        group, monkeypatch,
                                                                        capsys):
    """SIGTERM to ``sweep --workers 2`` (or Ctrl-C, which reaches its workers too) ends it
    with 143 / 130 within seconds, its workers gone, no ``--json``, the run KILLED; the
    same command then completes every study to exactly its budget, every trial completed
    before kept, none left running or queued."""
    uri = new_store(tmp_path / "mlflow.db")  # a store's first use: tests/test_lifecycle.py
    journal, out, err = tmp_path / "s.journal", tmp_path / "out.json", tmp_path / "err.log"
    cmd = workbench_cmd("sweep", tiny, "--storage", journal, "--tracking-uri", uri,
                        "--workers", "2", "--json", out)
    proc = _start(cmd, tmp_path, err, "] trial ")
    workers = _children(proc.pid)
    assert len(workers) >= 2
    _ends(proc, signum, group=group)
    assert proc.returncode == 128 + signum
    _one_line(err)
    assert not out.exists()
    assert _statuses(uri) == ["KILLED"]
    deadline = time.monotonic() + 5  # init reaps them
    while any(_alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(p) for p in workers), "workers outlived the command"
    if signum != signal.SIGTERM:
        return  # the resume, once is enough

    storage = open_storage(str(journal), tmp_path)
    names = optuna.get_all_study_names(storage)
    before = {n: optuna.load_study(study_name=n, storage=storage).get_trials() for n in names}
    assert not [t for ts in before.values() for t in ts if t.state == TrialState.RUNNING]
    # the studies' resume is the check: untracked, the rerun skips the final model's figures
    # and SHAP and the studies' figures (a tracked sweep of this config resumed with nothing
    # left to search: 18.7 CPU-s; untracked from the start: 5.7, at load ~13); a tracked
    # sweep resumed to its end: tests/test_services.py (after a SIGKILL, its plots checked).
    # In this process (``main``, its two workers forked from here): what the same command
    # does, without a second process's start (about 4 CPU-s of imports); the interrupted
    # command above is the process whose exit code, output and workers are checked
    monkeypatch.chdir(tmp_path)
    assert main([*cmd[3:], "--no-track"]) == 0, capsys.readouterr().err[-3000:]
    assert out.exists()
    for name in names:
        trials = optuna.load_study(study_name=name, storage=storage).get_trials()
        assert sum(is_counted(t) for t in trials) == 8
        assert not [t for t in trials if t.state in (TrialState.RUNNING, TrialState.WAITING)]
        kept = [(t.number, t.params, t.value) for t in before[name]
                if t.state == TrialState.COMPLETE]  # every trial completed before is kept
        assert kept == [(t.number, t.params, t.value) for t in trials
                        if t.number in {k[0] for k in kept}]


class _SignalsInFinalizer:
    """An object whose finalizer receives ``signum`` (and runs on, so that Python runs the
    handler inside it), as when a signal lands while matplotlib or SHAP finalize objects."""

    def __init__(self, signum: int) -> None:
        self.signum = signum

    def __del__(self) -> None:
        os.kill(os.getpid(), self.signum)
        for _ in range(100_000):
            pass


def _busy(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        pass


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupt_inside_a_finalizer_still_stops_the_command(signum):
    """Python drops an exception raised in a finalizer (``sys.unraisablehook``): the
    interrupt is delivered to the main thread again instead of the command going on."""
    with pytest.raises(signals.Interrupted) as caught:
        with signals.handle_signals():
            _SignalsInFinalizer(signum)  # finalized at once
            _busy(5)
    assert caught.value.code == 128 + signum


def test_an_interrupt_ending_another_thread_stops_the_command():
    """An :class:`Interrupted` that ends another thread reaches the main thread, also while
    it waits (as ``evaluate`` waits for its figures' results)."""
    def work() -> None:
        time.sleep(0.2)
        raise signals.Interrupted(signal.SIGTERM)

    start = time.monotonic()
    with pytest.raises(signals.Interrupted) as caught:
        with signals.handle_signals():
            threading.Thread(target=work).start()
            queue.Queue().get(timeout=10)
    assert caught.value.code == 143
    assert time.monotonic() - start < 5


@pytest.mark.parametrize("signum, group, phase", [
    (signal.SIGINT, True, "] figures: "), (signal.SIGTERM, False, "] figures: "),
    (signal.SIGTERM, False, "] fitting the model"),
    (signal.SIGINT, True, "] tracking in ")],
    ids=["Ctrl-C-figures", "SIGTERM-figures", "SIGTERM-fitting", "Ctrl-C-logging"])
def test_an_interrupted_evaluate_ends(tiny, tmp_path, new_store, signum, group, phase):
    """Ctrl-C or SIGTERM while ``evaluate`` fits, logs, or computes and draws its learning
    curves and SHAP summaries: 130 / 143 within seconds, one line, no ``--json``, the run
    KILLED, its worker processes gone."""
    uri = new_store(tmp_path / "mlflow.db")  # a store's first use: tests/test_lifecycle.py
    out, err = tmp_path / "out.json", tmp_path / "err.log"
    cmd = workbench_cmd("evaluate", tiny, "--tracking-uri", uri, "--jobs", "2",
                        "--json", out)
    proc = _start(cmd, tmp_path, err, phase)
    workers = _children(proc.pid)
    _ends(proc, signum, group=group)
    assert proc.returncode == 128 + signum
    _one_line(err)
    assert not out.exists()
    assert _statuses(uri) == ["KILLED"]
    deadline = time.monotonic() + 5
    while any(_alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(p) for p in workers), "workers outlived the command"


def test_an_interrupt_in_a_sqlite_store_call_leaves_the_database_unlocked(tmp_path,
                                                                          new_store):
    """Ctrl-C at random moments of a run's logging to SQLite: while the interrupt is being
    handled (its traceback alive, as when the run's end is written), no connection of the
    process holds the database's lock, and the run ends at once. Raised inside SQLAlchemy,
    about one interrupt in ten left the lock held and the end waited MLflow's 20 s busy
    timeout (the command still running 10 s after Ctrl-C)."""
    db = tmp_path / "mlflow.db"
    tracker = Tracker(new_store(db), "interrupts")
    run = tracker.start_run("interrupted")
    main, rng = threading.main_thread().ident, random.Random(0)
    for i in range(40):
        with pytest.raises(signals.Interrupted) as caught:
            with signals.handle_signals():
                threading.Timer(rng.uniform(0, 0.06), signal.pthread_kill,
                                (main, signal.SIGINT)).start()
                for step in range(100_000):  # minutes of writes: the signal lands in them
                    tracker.log_metrics(run, {"mae": 1 / (step + 1)}, step=step)
                    tracker.set_tags(run, {"step": step})
        other = sqlite3.connect(db, timeout=0)  # no waiting: a lock held fails at once
        try:
            other.execute("BEGIN EXCLUSIVE")  # needs every other connection's lock gone
            other.rollback()
        except sqlite3.OperationalError as exc:
            pytest.fail(f"interrupt {i} left the database locked ({exc}) while handled")
        finally:
            other.close()
    assert caught.value.code == 130
    start = time.monotonic()
    tracker.end_run(run, "KILLED")
    assert time.monotonic() - start < ENDS_WITHIN_S  # unscaled: below the 20 s busy wait


_CLOSE_AFTER_INTERRUPT = """
import sqlite3, sys
from sqlalchemy import create_engine
from workbench.experiment.process.startup import setup_logging
if sys.argv[2] == "command":
    setup_logging()
engine = create_engine(f"sqlite:///{sys.argv[1]}")
with engine.connect() as conn:
    raw = conn.connection.dbapi_connection
    cursor = raw.cursor()
    raw.close()  # as a Ctrl-C inside a read leaves it: the cursor's database is closed
    conn._safe_close_cursor(cursor)  # what SQLAlchemy's error handling does next
"""


@pytest.mark.parametrize("setup", ["command", "library"])
def test_a_cursor_left_by_an_interrupted_sqlite_read_logs_no_traceback(tmp_path, setup):
    """SQLAlchemy logs "Error closing cursor" with a traceback when a Ctrl-C lands in an
    MLflow SQLite read (about one interrupt in thirty on a busy store); the command's
    logging keeps it out of its output (its interrupt is one line). Without the command's
    set-up it is printed: the check can fail."""
    import sys

    done = subprocess.run([sys.executable, "-c", _CLOSE_AFTER_INTERRUPT,
                           str(tmp_path / "x.db"), setup], capture_output=True, text=True,
                          env=command_env(), timeout=60)
    assert done.returncode == 0, done.stderr
    if setup == "command":
        assert done.stderr == ""
    else:
        assert "Error closing cursor" in done.stderr
