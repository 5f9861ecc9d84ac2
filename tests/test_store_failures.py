"""Stores that fail safe (issue 20): every unusable store or bad argument ends in one line
(``workbench: error: ...``, under 300 characters, exit code 2, no password) before any work,
with nothing written; a damaged Optuna journal is reported before anything is appended to
it, and ``--repair`` recovers every complete record so the sweep resumes with its trials."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import optuna
import pytest
from optuna.trial import TrialState

from workbench.experiment.cli import main
from workbench.experiment.storage import JournalDamaged, open_storage, repair_journal
from workbench.experiment.sweep.scheduler import is_counted

from services import free_port, tiny_sweep

SECRET = "s3cret"


@pytest.fixture(scope="module")
def tiny_dir(tmp_path_factory):
    """The tiny sweep's config and data (3 studies of one target)."""
    directory = tmp_path_factory.mktemp("tiny")
    tiny_sweep(directory, trials=2)
    return directory


@pytest.fixture
def project(tiny_dir, tmp_path, monkeypatch):
    """A fresh project directory with the tiny config and data, as the working directory."""
    for name in ("tiny.toml", "sim.csv"):
        shutil.copy(tiny_dir / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _files(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` with its bytes (what a failed command must leave as is)."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def _run(argv: list[str], capsys) -> tuple[int, str]:
    """``workbench argv`` in this process: (exit code, standard error)."""
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    return code, capsys.readouterr().err


def _one_line(code: int, err: str, *words: str) -> str:
    lines = err.splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("workbench: error: "), err
    assert len(lines[0]) < 300, (len(lines[0]), lines[0])
    assert SECRET not in err and "Traceback" not in err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.fixture
def read_only():
    """``read_only(path)``: the directory ``path`` made one this process cannot write in:
    read-only permissions, or, as root (whom permissions do not stop), immutable
    (``chattr +i``; skipped where that is not allowed). Undone at the end of the test."""
    import subprocess
    import tempfile

    made = []

    def make(path: Path) -> Path:
        path.mkdir(parents=True, exist_ok=True)
        if os.geteuid() == 0:
            done = subprocess.run(["chattr", "+i", str(path)], capture_output=True)
            if done.returncode != 0:
                pytest.skip(f"as root, and chattr +i is not allowed here: {done.stderr!r}")
        else:
            path.chmod(0o555)
        made.append(path)
        try:  # the check sees what SQLite would see
            os.close(tempfile.mkstemp(dir=path)[0])
            pytest.skip(f"{path} is still writable")
        except OSError:
            pass
        return path

    yield make
    for path in made:
        if os.geteuid() == 0:
            subprocess.run(["chattr", "-i", str(path)], check=True)
        else:
            path.chmod(0o755)


# --------------------------------------------------------------------------- one line, no work

STORE = "sqlite:///{root}/store/mlflow.db"

CASES = {
    # argparse: one line instead of the whole usage
    "trials 0": (["sweep", "tiny.toml", "--trials", "0"],
                 ["argument --trials: expected an integer >= 1, got 0"]),
    "trials abc": (["sweep", "tiny.toml", "--trials", "abc"],
                   ["argument --trials: expected an integer >= 1, got 'abc'"]),
    "workers 0": (["sweep", "tiny.toml", "--workers", "0"], ["argument --workers:", ">= 1"]),
    "jobs 0": (["evaluate", "tiny.toml", "--jobs", "0"], ["argument --jobs:", ">= 1"]),
    "no command": ([], ["required: command", "sweep"]),
    # the Optuna storage, before the tracking store is created or a progress line printed
    "storage is a directory": (["sweep", "tiny.toml", "--storage", "{root}/studies",
                                "--tracking-uri", STORE], ["is a directory"]),
    "storage unreachable": (["sweep", "tiny.toml", "--storage",
                             "postgresql+psycopg2://u:" + SECRET + "@127.0.0.1:{port}/db",
                             "--tracking-uri", STORE], ["cannot connect", "u:***@"]),
    "storage without driver": (["sweep", "tiny.toml", "--storage",
                                "mysql+mysqldb://u:" + SECRET + "@127.0.0.1/db",
                                "--tracking-uri", STORE], ["driver is not installed"]),
    "storage in a read-only directory": (["sweep", "tiny.toml", "--storage",
                                          "{ro}/optuna.journal", "--no-track"],
                                         ["cannot write in"]),
    "reproduce storage is a directory": (["reproduce", "--storage", "{root}/studies", "--out",
                                          "{root}/report", "--tracking-uri", STORE],
                                         ["is a directory"]),
    "reproduce storage unreachable": (["reproduce", "--quick", "--out", "{root}/report",
                                       "--storage", "postgresql+psycopg2://u:" + SECRET +
                                       "@127.0.0.1:{port}/db", "--no-track"],
                                      ["cannot connect"]),
    # the tracking store, before the journal is created
    "tracking without driver": (["sweep", "tiny.toml", "--tracking-uri",
                                 "postgresql+pg8000://u:" + SECRET + "@dbhost/db"],
                                ["driver is not installed", "pg8000", "u:***@dbhost"]),
    "tracking mysql without driver": (["evaluate", "tiny.toml", "--tracking-uri",
                                       "mysql://u:" + SECRET + "@dbhost/db"],
                                      ["driver is not installed"]),
    "tracking ftp": (["sweep", "tiny.toml", "--tracking-uri",
                      "ftp://u:" + SECRET + "@host/mlruns"],
                     ["no tracking store for 'ftp://'"]),
    "tracking store under a file": (["evaluate", "tiny.toml", "--tracking-uri",
                                     "sqlite:///{root}/tiny.toml/mlflow.db"],
                                    ["is a file, not a directory"]),
    "tracking store in a read-only directory": (["sweep", "tiny.toml", "--tracking-uri",
                                                 "sqlite:///{ro}/mlflow.db"],
                                                ["cannot write in"]),
    "reproduce tracking without driver": (["reproduce", "--out", "{root}/report",
                                           "--tracking-uri",
                                           "postgresql+pg8000://u:" + SECRET + "@h/db"],
                                          ["driver is not installed"]),
    # workbench ui, before a server starts
    "ui store not SQLite": (["ui", "--tracking-uri", "sqlite:///{root}/sim.csv"],
                            ["sim.csv is not a valid SQLite database"]),
    "ui tracking without driver": (["ui", "--tracking-uri",
                                    "postgresql+pg8000://u:" + SECRET + "@dbhost/db"],
                                   ["driver is not installed", "u:***@dbhost"]),
    "ui storage is a directory": (["ui", "--tracking-uri", STORE, "--storage", "{root}/studies"],
                                  ["is a directory"]),
    "ui storage not a journal": (["ui", "--tracking-uri", STORE, "--storage", "tiny.toml"],
                                 ["tiny.toml"]),
    "ui storage unreachable": (["ui", "--tracking-uri", STORE, "--storage",
                                "postgresql+psycopg2://u:" + SECRET + "@127.0.0.1:{port}/db"],
                               ["cannot connect", "u:***@"]),
    # output locations
    "reproduce out is a file": (["reproduce", "--out", "tiny.toml", "--no-track"],
                                ["--out tiny.toml: is a file"]),
}


@pytest.mark.parametrize("argv, words", CASES.values(), ids=CASES.keys())
def test_one_line_before_any_work_and_nothing_written(project, capsys, read_only, argv,
                                                       words):
    (project / "studies").mkdir()
    fields = {"root": project, "port": free_port()}
    if any("{ro}" in a for a in argv):
        fields["ro"] = read_only(project / "ro")
    argv = [a.format(**fields) for a in argv]
    before = _files(project)
    code, err = _run(argv, capsys)
    _one_line(code, err, *words)
    assert _files(project) == before  # no journal, no mlflow.db, no report folder
    assert sorted(p.name for p in project.iterdir()) == sorted(
        ["tiny.toml", "sim.csv", "studies", *(["ro"] if (project / "ro").exists() else [])])


def test_existing_store_in_a_read_only_directory(project, capsys, read_only):
    """An existing SQLite store whose directory became read-only: one line, not
    PermissionError on mlflow.db.lock."""
    from workbench.experiment.tracking.runs import Tracker

    store = project / "store"
    assert Tracker(f"sqlite:///{store}/mlflow.db", "tiny").experiment_id  # the store exists
    read_only(store)
    before = _files(project)
    code, err = _run(["sweep", "tiny.toml", "--tracking-uri", f"sqlite:///{store}/mlflow.db"],
                     capsys)
    _one_line(code, err, "cannot write in", "store")
    assert _files(project) == before


# --------------------------------------------------------------------------- damaged journals


def _trials(journal: Path) -> dict[str, list[tuple]]:
    """Per study: (number, state, params, value) of every trial, read by Optuna itself."""
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(journal)))
    return {s.study_name: [(t.number, t.state, t.params, t.value)
                           for t in storage.get_all_trials(s._study_id)]
            for s in storage.get_all_studies()}


@pytest.fixture(scope="module")
def swept(tiny_dir, tmp_path_factory):
    """A journal after a real 2-trial sweep of the tiny config (3 studies)."""
    cwd = os.getcwd()
    os.chdir(tiny_dir)
    try:
        assert main(["sweep", "tiny.toml", "--no-track"]) == 0
    finally:
        os.chdir(cwd)
    journal = tiny_dir / "optuna.journal"
    trials = _trials(journal)
    assert len(trials) == 3 and all(len(t) == 2 for t in trials.values())
    return journal.read_bytes(), trials


DAMAGE = {
    "garbage line": b"this is not a journal record\n",
    # a torn write: the append of a record cut short, no line end (Optuna's reader takes it
    # for a write in progress, and the next append would glue a record to it)
    "truncated mid-line": b'{"op_code":8,"worker_id":"3f2c-140","trial_id":5,"user_at',
    "random bytes": bytes(range(256))[::-7] + b"\n\xff\xfe\x00\x81",
}


@pytest.mark.parametrize("damage", DAMAGE.values(), ids=DAMAGE.keys())
def test_damaged_journal_is_one_line_then_repair_resumes_with_every_trial(
        project, swept, capsys, damage):
    data, before = swept
    journal = project / "optuna.journal"
    journal.write_bytes(data + damage)
    good = data.count(b"\n")
    damaged = journal.read_bytes()
    store = "sqlite:///store/mlflow.db"  # relative to the project

    code, err = _run(["sweep", "tiny.toml", "--trials", "3", "--tracking-uri", store], capsys)
    line = _one_line(code, err, "optuna.journal", f"damaged from line {good + 1}",
                     f"last good record: line {good}", "nothing was appended",
                     f": workbench sweep tiny.toml --trials 3 --tracking-uri {store} "
                     "--repair")
    assert journal.read_bytes() == damaged  # nothing appended after the damage
    assert not (project / "store").exists()  # checked before the tracking store is created
    assert line.count("optuna.journal") == 1

    code, err = _run(["sweep", "tiny.toml", "--trials", "3", "--no-track", "--repair"], capsys)
    assert code == 0, err
    assert f"kept {good} records (6 trials in 3 studies)" in err, err
    assert (project / "optuna.journal.damaged").read_bytes() == damaged  # nothing lost
    after = _trials(journal)
    assert journal.read_bytes().startswith(data)  # every complete record, as written
    for name, trials in before.items():
        assert after[name][:2] == trials  # number, state, params and value kept
        assert [t[1] for t in after[name]] == [TrialState.COMPLETE] * 3  # budget reached

    # a second repair of the repaired file: nothing to do; the damaged copies are kept
    code, err = _run(["sweep", "tiny.toml", "--trials", "3", "--no-track", "--repair"], capsys)
    assert code == 0 and "not damaged: nothing to repair" in err, err
    assert not (project / "optuna.journal.damaged-1").exists()


def _small_journal(path: Path, trials: int = 4) -> list[bytes]:
    study = optuna.create_study(study_name="s", storage=open_storage(str(path), path.parent))
    study.optimize(lambda t: t.suggest_float("x", 0, 1), n_trials=trials)
    return path.read_bytes().splitlines(keepends=True)


def test_repair_keeps_the_records_after_a_damaged_middle_line(tmp_path):
    """A damaged parameter record: every other record is kept, and so every trial."""
    journal = tmp_path / "j.journal"
    lines = _small_journal(journal)
    index = [i for i, ln in enumerate(lines) if ln.startswith(b'{"op_code":5')][1]
    lines[index] = b"\x00\x01 not json\n"
    journal.write_bytes(b"".join(lines))
    with pytest.raises(JournalDamaged, match=f"damaged from line {index + 1} of {len(lines)}"):
        open_storage(str(journal), tmp_path)
    repair = repair_journal(str(journal), tmp_path)
    assert repair.kept == len(lines) - 1 and repair.after == 0
    assert repair.damaged == [(index + 1, "not a JSON record")]
    assert repair.trials == 4 and repair.damaged_copy == tmp_path / "j.journal.damaged"
    assert len(optuna.load_study(study_name="s", storage=open_storage(
        str(journal), tmp_path)).get_trials()) == 4


def test_repair_falls_back_when_a_lost_record_would_shift_trial_ids(tmp_path):
    """A damaged trial-creation record: the later records would name the wrong trials, so
    only the records before the damage are kept, and the report says so."""
    journal = tmp_path / "j.journal"
    lines = _small_journal(journal)
    index = [i for i, ln in enumerate(lines) if ln.startswith(b'{"op_code":4')][2]
    lines[index] = lines[index][:30] + b"\n"  # cut short, then a later record went on
    journal.write_bytes(b"".join(lines))
    (tmp_path / "j.journal.damaged").write_bytes(b"an older copy")
    repair = repair_journal(str(journal), tmp_path)
    assert repair.kept == index and repair.after == len(lines) - index - 1
    assert repair.trials == 2  # trials 0 and 1, whole
    assert "would not replay as written" in str(repair)
    assert repair.damaged_copy == tmp_path / "j.journal.damaged-1"  # the older copy stays
    assert (tmp_path / "j.journal.damaged").read_bytes() == b"an older copy"
    study = optuna.load_study(study_name="s", storage=open_storage(str(journal), tmp_path))
    assert [t.state for t in study.get_trials()] == [TrialState.COMPLETE] * 2
    assert sum(is_counted(t) for t in study.get_trials()) == 2


def test_an_append_in_progress_is_not_taken_for_damage(tmp_path):
    """Another process appending (it holds the journal's lock) leaves a line without its end
    for a moment: the check waits for the lock and finds the line whole."""
    import threading
    import time

    from optuna.storages.journal import JournalFileSymlinkLock

    journal = tmp_path / "j.journal"
    record = _small_journal(journal, trials=1)[-1]
    lock = JournalFileSymlinkLock(str(journal))
    lock.acquire()
    with open(journal, "ab") as fh:
        fh.write(record[:20])
    opened: list = []
    thread = threading.Thread(target=lambda: opened.append(open_storage(str(journal),
                                                                        tmp_path)))
    thread.start()
    time.sleep(0.5)
    assert thread.is_alive() and not opened  # waiting for the lock, not failing
    with open(journal, "ab") as fh:
        fh.write(record[20:])
    lock.release()
    thread.join(timeout=30)
    assert len(opened) == 1
