"""A full disk (ENOSPC) under the MLflow store, an Optuna journal, ``--out`` or a tracking
server's own store: a real tmpfs of a few kilobytes, mounted by the test (root only), that
fills while the command writes. The command ends in one line naming the problem (exit code
2), no traceback; the store stays readable and the next command carries on (issue 35)."""

from __future__ import annotations

import os
import re
import subprocess
import time
from pathlib import Path

import optuna
import pytest
from optuna.trial import TrialState

from workbench.experiment.cli import main
from workbench.experiment.sweep.scheduler import is_counted

from services import MlflowServer, command_env, tiny_sweep, workbench_cmd

SECRET = "s3cret-pw"


@pytest.fixture
def tiny_disk(tmp_path):
    """``tiny_disk(name, size)`` mounts a tmpfs of ``size`` (``"16k"``) at ``tmp_path/name``;
    unmounted at the end."""
    mounted: list[Path] = []

    def mount(name: str, size: str) -> Path:
        if os.geteuid() != 0:
            pytest.skip("mounting a tmpfs needs root")
        path = tmp_path / name
        path.mkdir(parents=True, exist_ok=True)
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                               str(path)], capture_output=True, text=True)
        if done.returncode:
            pytest.skip(f"cannot mount a tmpfs: {done.stderr.strip()}")
        mounted.append(path)
        return path

    yield mount
    for path in reversed(mounted):
        if subprocess.run(["umount", str(path)], capture_output=True).returncode:
            subprocess.run(["umount", "-l", str(path)], capture_output=True)  # still in use


def _grow(path: Path, size: str) -> None:
    """Free space: the tmpfs at ``path`` gets ``size``."""
    subprocess.run(["mount", "-o", f"remount,size={size}", str(path)], check=True)


def _run(tmp_path: Path, *args: object, timeout: float = 240) -> tuple[int, str]:
    done = subprocess.run(workbench_cmd(*map(str, args)), cwd=tmp_path, env=command_env(),
                          capture_output=True, text=True, timeout=timeout)
    return done.returncode, done.stderr


def _one_error_line(code: int, err: str) -> str:
    assert code == 2 and "Traceback" not in err, err
    errors = [line for line in err.splitlines() if "error" in line.lower()]
    assert len(errors) == 1 and errors[0] == err.splitlines()[-1], err
    return errors[0]


def test_a_full_disk_under_the_mlflow_store_is_one_line(tiny_disk, tmp_path):
    """The SQLite store and its artifacts on 1.2 MB: the database (about 0.9 MB) is created,
    the run starts, the figures and the model do not fit."""
    from mlflow import MlflowClient

    from workbench.experiment.tracking.lifecycle import reap_stale_runs
    from workbench.experiment.tracking.runs import Tracker

    disk = tiny_disk("store", "1200k")
    uri = f"sqlite:///{disk / 'mlflow.db'}"
    config = tiny_sweep(tmp_path / "cfg")
    code, err = _run(tmp_path, "evaluate", config, "--no-intervals", "--tracking-uri", uri)
    line = _one_error_line(code, err)
    assert line.startswith(f"workbench: error: SQLite database {disk / 'mlflow.db'}: the disk "
                           "is full"), err
    client = MlflowClient(uri)  # readable as it is, the disk still full
    (run,) = client.search_runs([client.get_experiment_by_name("tiny").experiment_id])
    assert run.info.status in ("RUNNING", "FAILED")
    _grow(disk, "16m")
    reap_stale_runs(Tracker(uri, "tiny"))  # what the next command does first
    assert client.get_run(run.info.run_id).info.status == "FAILED"


def test_a_full_disk_under_a_sweep_s_journal_leaves_it_whole(tiny_disk, tmp_path,
                                                           monkeypatch, capsys):
    """The journal (about 36 kB when done) on 16 kB: the append that does not fit is undone,
    so the journal opens without ``--repair`` and the same command, once there is space,
    finishes every study to its budget."""
    disk = tiny_disk("journal", "16k")
    journal = disk / "optuna.journal"
    config = tiny_sweep(tmp_path / "cfg", trials=4)
    cmd = ("sweep", config, "--no-track", "--storage", journal)
    code, err = _run(tmp_path, *cmd)
    line = _one_error_line(code, err)
    assert line.startswith(f"workbench: error: cannot write Optuna journal {journal}: No space "
                           "left on device; nothing was appended"), err
    assert journal.read_bytes().endswith(b"\n")  # no torn record
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(journal)))
    assert optuna.get_all_study_names(storage)  # readable as it is
    _grow(disk, "1m")
    # the same command, in this process: what it does with the journal is the check (the
    # failing one above is a process of its own: its exit code and output are checked)
    monkeypatch.chdir(tmp_path)
    assert main([str(a) for a in cmd]) == 0, capsys.readouterr().err[-3000:]
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(journal)))
    for name in optuna.get_all_study_names(storage):
        trials = optuna.load_study(study_name=name, storage=storage).get_trials()
        assert sum(is_counted(t) for t in trials) == 4, name
        assert not [t for t in trials if t.state in (TrialState.RUNNING, TrialState.WAITING)]


@pytest.mark.slow  # one more evaluation; write_artifacts stages --out (see test_io)
def test_a_full_disk_under_out_leaves_nothing_partial(tiny_disk, tmp_path):
    disk = tiny_disk("out", "32k")  # the tables and figures take about 64 kB
    config = tiny_sweep(tmp_path / "cfg")
    code, err = _run(tmp_path, "evaluate", config, "--no-track", "--out", disk / "out")
    line = _one_error_line(code, err)
    assert line.startswith(f"workbench: error: --out {disk / 'out'}: cannot write: No space "
                           "left on device"), err
    assert list(disk.iterdir()) == []  # nor the directory it created


def _fill(disk: Path) -> None:
    """Write a file on ``disk`` until no byte more fits."""
    with open(disk / "filler", "wb", buffering=0) as fh:
        try:
            while True:
                fh.write(b"\0" * 4096)
        except OSError as exc:
            assert exc.errno == 28, exc  # ENOSPC


def _server_failed(line: str, uri: str) -> re.Match | None:
    """The one line of a tracking server that failed a request (its password shown ***)."""
    shown = re.escape(uri.replace("http://", "http://u:***@"))
    return re.match(rf"workbench: error: the MLflow tracking store {shown} (answered HTTP 5\d\d "
                    rf"to|answers, but dropped the connection of) .* the server failed \(its "
                    rf"log says why: a full disk\?\)", line)


@pytest.mark.slow  # a server start and an evaluation: 21-23 s on 2 idle cores
def test_evaluate_on_a_tracking_server_whose_database_disk_fills(tiny_disk, tmp_path):
    """``evaluate`` against a server whose SQLite database's tmpfs is filled once the run
    exists (while the model is fitted): the server answers 503 to the first write that needs
    space (MLflow's retries, one here), said in one line naming the server (password
    hidden), exit 2, no traceback; with space again, the next command's reaping leaves the
    run FAILED."""
    from mlflow import MlflowClient

    from workbench.experiment.tracking.lifecycle import reap_stale_runs
    from workbench.experiment.tracking.runs import Tracker

    disk = tiny_disk("server", "2m")  # the new database takes about 0.9 MB
    server = MlflowServer(f"sqlite:///{disk / 'mlflow.db'}", tmp_path / "artifacts",
                          tmp_path / "server.log")
    try:
        config = tiny_sweep(tmp_path / "cfg")
        uri = server.uri.replace("http://", f"http://u:{SECRET}@")
        err = tmp_path / "err.log"
        proc = subprocess.Popen(
            workbench_cmd("evaluate", str(config), "--no-intervals", "--tracking-uri", uri),
            cwd=tmp_path, env=command_env(MLFLOW_HTTP_REQUEST_MAX_RETRIES="1"),
            stdout=subprocess.DEVNULL, stderr=open(err, "w"))
        client = MlflowClient(server.uri)
        deadline = time.monotonic() + 120
        while not (client.get_experiment_by_name("tiny") and client.search_runs(
                [client.get_experiment_by_name("tiny").experiment_id])):
            assert proc.poll() is None and time.monotonic() < deadline, err.read_text()
            time.sleep(0.1)
        assert "] tracking in " not in err.read_text()  # still fitting: its logging is next
        _fill(disk)
        line = _one_error_line(proc.wait(timeout=300), err.read_text())
        assert _server_failed(line, server.uri) and "answered HTTP 503 to" in line, line
        assert SECRET not in err.read_text()
        (disk / "filler").unlink()
        reap_stale_runs(Tracker(server.uri, "tiny"))  # what the next command does first
        (run,) = client.search_runs([client.get_experiment_by_name("tiny").experiment_id])
        assert run.info.status == "FAILED"
    finally:
        server.stop()


@pytest.mark.slow  # a server start, two evaluations: 26-42 s on 2 idle cores, 113 s busy
def test_evaluate_on_a_tracking_server_whose_artifact_disk_fills(tiny_disk, tmp_path):
    """``evaluate`` against a server whose artifact root (a 64 kB tmpfs) fills with the run's
    figures: one line naming the server (password hidden), exit 2, no traceback; once there is
    space the next command runs, and no run is left RUNNING."""
    from mlflow import MlflowClient

    disk = tiny_disk("artifacts", "64k")
    server = MlflowServer(f"sqlite:///{tmp_path / 'mlflow.db'}", disk, tmp_path / "server.log")
    try:
        config = tiny_sweep(tmp_path / "cfg")
        uri = server.uri.replace("http://", f"http://u:{SECRET}@")
        cmd = ("evaluate", config, "--no-intervals", "--tracking-uri", uri)
        done = subprocess.run(workbench_cmd(*map(str, cmd)), cwd=tmp_path, capture_output=True,
                              text=True, timeout=300,
                              env=command_env(MLFLOW_HTTP_REQUEST_MAX_RETRIES="1"))
        line = _one_error_line(done.returncode, done.stderr)
        assert _server_failed(line, server.uri), done.stderr
        assert SECRET not in done.stderr
        _grow(disk, "64m")
        code, err = _run(tmp_path, *cmd)
        assert code == 0, err[-3000:]
        client = MlflowClient(server.uri)
        runs = client.search_runs([client.get_experiment_by_name("tiny").experiment_id])
        assert sorted(r.info.status for r in runs) == ["FAILED", "FINISHED"]
    finally:
        server.stop()
