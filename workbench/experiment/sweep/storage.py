"""The Optuna storage adapter of ``workbench sweep``: the only module that touches Optuna's
private names (a test checks).

* :func:`open_storage` / :func:`check_storage`: an RDB URL (with Optuna's heartbeat, a grace
  period and one retry of a stale trial) or a journal file, checked before any work; problems
  are one :class:`~workbench.experiment.errors.StorageError` line without the password.
* The journal file fails safe: a damaged line is found before anything is appended
  (:class:`JournalDamaged`, naming the command that repairs it) and :func:`repair_journal`
  recovers every complete record into a new file (``workbench sweep --repair``).
* What the scheduler needs of Optuna's internals: :func:`beat`, :func:`heartbeat_enabled`,
  :func:`set_trial_attr`, :func:`retry`; and the
  ``optuna-dashboard`` command line (:func:`dashboard_command`).
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import os
import shutil
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import optuna
from optuna.exceptions import ExperimentalWarning
from optuna.storages.journal import JournalFileSymlinkLock
from optuna.storages.journal._file import get_lock_file
from optuna.storages.journal._storage import JournalOperation, JournalStorageReplayResult
from optuna.trial import FrozenTrial

from ..errors import StorageError, driver_hint, redact
from ..outputs import OutputError, check_file
from ..signals import interrupts_deferred

log = logging.getLogger("workbench")

__all__ = ["JournalDamaged", "Repair", "StorageError", "beat", "check_storage",
           "dashboard_command", "heartbeat_enabled", "heartbeat_interval", "open_storage",
           "repair_journal", "retry", "set_trial_attr"]

#: User attributes that belong to one attempt at a trial, not to its configuration.
_ATTEMPT_ATTRS = ("worker", "heartbeat", "finished_by", "error", "surplus", "stale")


def heartbeat_interval(stale_after_s: float) -> int:
    """Seconds between heartbeats: a quarter of the grace period, 1 to 10 s."""
    return int(max(1, min(10, stale_after_s // 4)))


class _Retry(optuna.storages.RetryFailedTrialCallback):
    """Optuna's retry of a failed trial (same parameters, ``retry_history`` in its system
    attributes), without the dead attempt's own user attributes: its ``worker`` (host:pid of
    a dead process) would get the retry failed again the moment another process looks."""

    def __call__(self, study: optuna.Study, trial: FrozenTrial) -> None:
        trial = copy.deepcopy(trial)
        trial.user_attrs = {k: v for k, v in trial.user_attrs.items()
                            if k not in _ATTEMPT_ATTRS}
        super().__call__(study, trial)


def _retry() -> _Retry:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # experimental / renamed in 4.9: same behaviour
        return _Retry(max_retry=1)


# --------------------------------------------------------------------------- journal file
#
# Optuna's journal file is one JSON record per line, replayed from the start by every process
# that opens it. Optuna's reader tolerates a damaged *last* line (a write in progress), but
# once anything is appended after a damaged line every later read fails, so one torn write
# (a full disk, a killed machine) would end the study for good. Here the file is checked
# under its lock when it is opened, before anything is appended; an append never lands after
# a torn line; and :func:`repair_journal` recovers every complete record into a new file.

#: What a record does, by op code (``optuna.storages.journal._storage.JournalOperation``).
_OPS = {0: "a study created", 1: "a study deleted", 2: "a study attribute",
        3: "a study attribute", 4: "a trial created", 5: "a trial parameter",
        6: "a trial's state", 7: "a trial's report", 8: "a trial attribute",
        9: "a trial attribute", 10: "trials discarded"}
_STATES = {0: "a trial started", 1: "a trial completed", 2: "a trial pruned",
           3: "a trial failed", 4: "a trial queued"}


class JournalDamaged(StorageError):
    """An Optuna journal file with a damaged line: a torn (incomplete) record, bytes that are
    not a JSON record, or a record Optuna cannot replay. Nothing was appended to it."""

    def __init__(self, shown: str, line: int, total: int, why: str, last_good: str,
                 hint: str | None = None):
        self.shown, self.line, self.total, self.why = shown, line, total, why
        self.last_good = last_good
        text = (f"Optuna journal {shown} is damaged from line {line} of {total} ({why}; "
                f"last good record: {last_good}); nothing was appended. To keep every "
                "complete record")
        command = f": {hint}" if hint else ""
        # the whole line (after "workbench: error: ") under 300 characters
        super().__init__(text + (command if len(text + command) < 280 else
                                 ", rerun the command with --repair"))


def _what(record: dict) -> str:
    op = record["op_code"]
    if op == 0 and isinstance(record.get("study_name"), str):
        name = record["study_name"]
        return f"study {name if len(name) <= 40 else name[:37] + '...'} created"
    if op == 6:
        state = record.get("state")
        return _STATES.get(state, _OPS[op]) if isinstance(state, int) else _OPS[op]
    return _OPS[op]


def _parse(line: bytes) -> tuple[dict | None, str]:
    """``(record, "")`` for a complete journal line, else ``(None, why it is damaged)``."""
    if not line.endswith(b"\n"):
        return None, "torn: no line end"
    try:
        record = json.loads(line.decode("utf-8"))
    except UnicodeDecodeError:
        return None, "not UTF-8 text"
    except ValueError:
        return None, "not a JSON record"
    if not (isinstance(record, dict) and type(record.get("op_code")) is int
            and record["op_code"] in _OPS and isinstance(record.get("worker_id"), str)):
        return None, "not an Optuna journal record"
    return record, ""


def _lines(path: Path):
    """``(number, bytes, record or None, why)`` for each line of the file (from 1)."""
    with open(path, "rb") as fh:
        for number, line in enumerate(fh, start=1):
            yield (number, line, *_parse(line))


def _replay(records: list[dict]) -> tuple[int | None, str]:
    """``(index, why)`` of the first record Optuna's replay raises on, else ``(None, "")``
    (replayed as a process that wrote none of them, as Optuna replays others' records)."""
    replay = JournalStorageReplayResult("workbench-check-")
    for i, record in enumerate(records):
        try:
            replay.apply_logs([record])
        except Exception as exc:
            return i, f"a record Optuna cannot replay: {type(exc).__name__}"
    return None, ""


def _id_gap(records: list[dict]) -> int | None:
    """Index of the first record naming a study or trial that no earlier record created,
    else ``None``. Optuna numbers studies and trials by their creation records, so in a
    sound journal this never happens; after a lost creation record the ids shift and the
    records of the last trials point past the end (or at the wrong trial)."""
    studies: dict[int, str] = {}
    next_study = n_trials = 0
    for i, r in enumerate(records):
        op, sid, tid = r["op_code"], r.get("study_id"), r.get("trial_id")
        if op == 0:
            name = r.get("study_name")
            if isinstance(name, str) and name not in studies.values():
                studies[next_study] = name
                next_study += 1
            continue
        if sid is not None and not (isinstance(sid, int) and 0 <= sid < next_study):
            return i
        if tid is not None and not (isinstance(tid, int) and 0 <= tid < n_trials):
            return i
        if op == 1 and isinstance(sid, int):
            studies.pop(sid, None)
        elif op == 4 and sid in studies:
            n_trials += 1
    return None


def _find_damage(path: Path, shown: str, hint: str | None = None,
                 replay: bool = False) -> JournalDamaged | None:
    """The file's first damaged line as a :class:`JournalDamaged`, else ``None`` (with
    ``replay``, records that Optuna cannot replay count as damaged too). Without the file's
    lock, another process's append in progress can look like a torn last line."""
    first = None
    last_good, total, records, numbers = "none", 0, [], []
    for number, _, record, why in _lines(path):
        total = number
        if first is None:
            if record is None:
                first = (number, why)
            else:
                last_good = f"line {number}, {_what(record)}"
                if replay:
                    records.append(record)
                    numbers.append(number)
    if first is None and replay and records:
        index, why = _replay(records)
        if index is not None:
            first = (numbers[index], why)
            last_good = (f"line {numbers[index - 1]}, {_what(records[index - 1])}" if index
                         else "none")
    if first is None:
        return None
    return JournalDamaged(shown, first[0], total, first[1], last_good, hint)


@contextlib.contextmanager
def _holding(lock, shown: str):
    """The journal file's lock (Optuna's: every append takes it), or a one-line error."""
    try:
        lock.acquire()
    except OSError as exc:
        raise StorageError(f"cannot lock Optuna journal {shown}: "
                           f"{exc.strerror or type(exc).__name__} (its directory must be "
                           "writable)") from None
    try:
        yield
    finally:
        lock.release()


class _JournalFile(optuna.storages.journal.JournalFileBackend):
    """Optuna's journal file, flushed to disk (fsync) only when the appended operations
    create or delete a study, create a trial or set a trial's state, instead of after every
    append (a trial's parameters, reports, heartbeats and attributes: ~20 fsyncs of ~3.5 ms
    per trial here, an eighth of a small sweep). Every append is still written under the
    file lock before it returns, so other processes (and machines sharing the file, whose
    NFS flushes at close) see it at once; only an operating-system crash or power loss can
    lose the unsynced operations of the running trials, which a resumed sweep runs again.

    Fails safe: :meth:`check` finds a damaged line before anything is appended; an append
    after a torn last line is refused (it would glue a good record to the torn one); a read
    that meets a damaged line ends in a :class:`JournalDamaged` of one line."""

    def __init__(self, file_path: str, shown: str | None = None):
        super().__init__(file_path)
        self._shown = shown or file_path

    def check(self, hint: str | None = None) -> None:
        """Raise :class:`JournalDamaged` at the first damaged line. Damage found is checked
        again under the file lock (another process's append in progress looks like a torn
        last line), so an intact file is read without taking the lock."""
        path = Path(self._file_path)
        if _find_damage(path, self._shown, hint) is None:
            return
        with _holding(self._lock, self._shown):
            damage = _find_damage(path, self._shown, hint)
        if damage is not None:
            raise damage

    def read_logs(self, log_number_from: int):
        try:
            yield from super().read_logs(log_number_from)
        except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, "Invalid log format."
            damage = _find_damage(Path(self._file_path), self._shown)
            if damage is not None:
                raise damage from None
            raise StorageError(f"cannot read Optuna journal {self._shown}: "
                               f"{type(exc).__name__}") from None

    def append_logs(self, logs: list[dict]) -> None:
        op = JournalOperation
        synced = (op.CREATE_STUDY, op.DELETE_STUDY, op.CREATE_TRIAL, op.SET_TRIAL_STATE_VALUES,
                  op.DISCARD_TRIALS)
        sync = any(log.get("op_code") in synced for log in logs)
        # a Ctrl-C waits for the append: interrupted under the lock, it would leave the
        # lock file behind (and a torn record)
        with interrupts_deferred(), get_lock_file(self._lock):
            text = "\n".join(json.dumps(log, separators=(",", ":")) for log in logs) + "\n"
            with open(self._file_path, "a+b") as f:  # appends go to the end, wherever read
                end = f.seek(0, os.SEEK_END)
                if end:
                    f.seek(end - 1)
                torn = end > 0 and f.read(1) != b"\n"
                if torn:  # a write cut short: glued to it, this record would be lost too
                    damage = _find_damage(Path(self._file_path), self._shown)
                    raise damage or StorageError(f"Optuna journal {self._shown} ends in a "
                                                 "torn record; nothing was appended")
                f.write(text.encode("utf-8"))
                f.flush()
                if sync:
                    os.fsync(f.fileno())


def _journal_path(storage: str, root: Path) -> Path:
    path = Path(storage)
    return path if path.is_absolute() else root / path


def _journal_file(storage: str, root: Path) -> Path:
    """:func:`_journal_path`, refused when it is a directory."""
    path = _journal_path(storage, root)
    if path.is_dir():
        raise StorageError(f"Optuna storage {path} is a directory; give a journal file path "
                           "(e.g. mlruns/optuna.journal) or a database URL")
    return path


def open_storage(storage: str, root: Path, *, stale_after_s: float = 600,
                 hint: str | None = None):
    """An Optuna storage: an RDB URL (with Optuna's heartbeat, grace period ``stale_after_s``
    and one retry of a stale trial), else a journal file (relative to ``root``), checked for
    damage before anything is appended (:class:`JournalDamaged`; ``hint``: the command that
    repairs it). Problems end in a :class:`StorageError` of one line (without the URL's
    password)."""
    if "://" in storage:
        return _rdb_storage(storage, stale_after_s)
    path = _journal_file(storage, root)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        backend = _JournalFile(str(path), storage)
    except OSError as exc:
        raise StorageError(f"cannot use Optuna journal file {path}: "
                           f"{exc.strerror or type(exc).__name__}") from None
    backend.check(hint)
    try:
        return optuna.storages.JournalStorage(backend)
    except StorageError:
        raise
    except Exception as exc:  # a well-formed record that Optuna cannot replay
        damage = _find_damage(path, storage, hint, replay=True)
        raise damage or StorageError(f"Optuna journal {storage} cannot be replayed "
                                     f"({type(exc).__name__})") from None


def check_storage(storage: str, root: Path, *, hint: str | None = None) -> None:
    """Before any work, writing nothing: the Optuna storage can be used. A journal file that
    exists is checked as :func:`open_storage` checks it; a missing one must be creatable (it
    is not created here); a database must accept a connection (its tables are not created
    here). Raises :class:`StorageError` (one line, no password)."""
    if "://" in storage:
        _check_rdb(storage)
        return
    path = _journal_file(storage, root)
    try:  # its directory takes new files (the journal's lock is created there)
        check_file(path, "Optuna journal")
    except OutputError as exc:
        raise StorageError(str(exc)) from None
    if path.exists():
        if not os.access(path, os.R_OK | os.W_OK):
            raise StorageError(f"Optuna journal {storage} cannot be read and written "
                               "(its permissions)")
        open_storage(storage, root, hint=hint)


@dataclass
class Repair:
    """What :func:`repair_journal` did."""

    shown: str
    damaged_copy: Path
    kept: int  # records kept
    damaged: list[tuple[int, str]]  # (line, why) of the damaged lines left out
    after: int  # complete records left out after the first damaged line (fallback)
    studies: int
    trials: int

    def __str__(self) -> str:
        lines = ", ".join(f"{n} ({why})" for n, why in self.damaged[:3])
        more = f" and {len(self.damaged) - 3} more" if len(self.damaged) > 3 else ""
        text = (f"repaired Optuna journal {self.shown}: kept {_n(self.kept, 'record')} "
                f"({_n(self.trials, 'trial')} in {_n(self.studies, 'study')}), left out "
                f"{_n(len(self.damaged), 'damaged line')}: {lines}{more}")
        if self.after:
            text += (f"; also left out the {_n(self.after, 'complete record')} after line "
                     f"{self.damaged[0][0]}: without the damaged line(s) they would not "
                     "replay as written (a lost record created a study or trial)")
        return text + f"; the damaged original is {self.damaged_copy}"


def _n(count: int, noun: str) -> str:
    plural = noun[:-1] + "ies" if noun.endswith("y") else noun + "s"
    return f"{count} {noun if count == 1 else plural}"


def repair_journal(storage: str, root: Path) -> Repair | None:
    """Recover every complete record of a damaged journal file into a new file (``None`` when it is
    not damaged, or does not exist). The original is kept as ``<file>.damaged``
    (``.damaged-N`` when that exists); the good records are written to a temporary file
    beside it, which must replay (a :class:`JournalStorage` on it loads every study's
    trials) before it is moved into place atomically. When the complete records do not
    replay as written without the damaged lines (a lost record created a study or trial, so
    later ids would shift), only the records before the first damaged line are kept. Run it
    while no sweep works on the file."""
    if "://" in storage:
        raise StorageError(f"--repair repairs an Optuna journal file; {redact(storage)} is a "
                           "database")
    path = _journal_path(storage, root)
    if not path.exists():
        return None
    if not path.is_file():
        raise StorageError(f"--repair: Optuna journal {storage} is not a file")
    with _holding(JournalFileSymlinkLock(str(path)), storage):
        lines = list(_lines(path))
        bad = {n: why for n, _, record, why in lines if record is None}
        for _ in range(3):  # well-formed records that Optuna cannot replay are damaged too
            kept = [(n, record) for n, _, record, _ in lines if n not in bad]
            index, why = _replay([record for _, record in kept])
            if index is None:
                break
            bad[kept[index][0]] = why
        if not bad:
            return None
        first = min(bad)
        candidates = ([ln for ln in lines if ln[0] not in bad],
                      [ln for ln in lines if ln[0] < first])
        for keep in candidates:
            records = [ln[2] for ln in keep]
            if _id_gap(records) is not None or _replay(records)[0] is not None:
                continue
            tmp = _write_temp(path, b"".join(ln[1] for ln in keep))
            try:
                studies, trials = _verify(tmp, len(keep))
            except Exception:
                tmp.unlink(missing_ok=True)
                continue
            break
        else:
            raise StorageError(f"cannot repair Optuna journal {storage}: even the records "
                               f"before line {first} do not replay; it was left untouched")
        copy = _keep_original(path)
        os.replace(tmp, path)
        _sync_dir(path.parent)
    after = sum(1 for ln in lines if ln[0] > first and ln[0] not in bad) if keep is \
        candidates[1] else 0
    return Repair(storage, copy, len(keep), sorted(bad.items()), after, studies, trials)


def _write_temp(path: Path, data: bytes) -> Path:
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".repair")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    except BaseException:
        Path(name).unlink(missing_ok=True)
        raise
    return Path(name)


def _verify(path: Path, n_records: int) -> tuple[int, int]:
    """``(studies, trials)`` of a journal file replayed by Optuna itself; raises unless every
    one of its ``n_records`` lines was read."""
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(path)))
    if storage._replay_result.log_number_read != n_records:
        raise StorageError(f"replayed {storage._replay_result.log_number_read} of "
                           f"{n_records} records")
    studies = storage.get_all_studies()
    trials = sum(len(storage.get_all_trials(s._study_id, deepcopy=False)) for s in studies)
    return len(studies), trials


def _keep_original(path: Path) -> Path:
    """A second name for the damaged file, ``<file>.damaged`` or ``<file>.damaged-N``, that
    keeps its bytes once the repaired file replaces it (a hard link, else a copy)."""
    for n in range(10_000):
        copy = path.with_name(f"{path.name}.damaged" + (f"-{n}" if n else ""))
        if os.path.lexists(copy):
            continue
        try:
            os.link(path, copy)
        except FileExistsError:
            continue
        except OSError:  # no hard links here
            shutil.copy2(path, copy)
        return copy
    raise StorageError(f"cannot name a copy of Optuna journal {path}")


def _sync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


# --------------------------------------------------------------------------- databases


@contextlib.contextmanager
def _rdb_errors(shown: str):
    """Database problems as one :class:`StorageError` line (without the password)."""
    import sqlalchemy.exc  # (b) SQLAlchemy: database storages only, not a journal

    try:
        yield
    except ImportError as exc:  # missing driver (psycopg2, pymysql, ...)
        raise StorageError(f"Optuna storage {shown}: its database driver is not installed "
                           f"({exc}); {driver_hint(exc)}") from None
    except sqlalchemy.exc.NoSuchModuleError as exc:
        raise StorageError(f"Optuna storage {shown}: unknown database kind ({exc})") from None
    except sqlalchemy.exc.ArgumentError as exc:
        raise StorageError(f"Optuna storage {shown} is not a valid database URL "
                           f"({exc})") from None
    except (sqlalchemy.exc.OperationalError, sqlalchemy.exc.InterfaceError) as exc:
        reason = str(getattr(exc, "orig", exc)).strip().splitlines()
        raise StorageError(f"cannot connect to Optuna storage {shown}: "
                           f"{reason[0][:150] if reason else type(exc).__name__}") from None


def _engine_kwargs(url: str) -> dict:
    if url.startswith("postgresql"):  # an unreachable host fails in seconds, not minutes
        return {"connect_args": {"connect_timeout": 10}}
    return {}


def _sqlite_file(url: str, shown: str) -> Path | None:
    if not url.startswith("sqlite:///"):
        return None
    db = Path(url[len("sqlite:///"):].partition("?")[0])
    if db.is_dir():
        raise StorageError(f"Optuna storage {shown} is a directory, not a database file")
    return db


def _check_rdb(url: str) -> None:
    """The database accepts a connection (nothing is created; a new SQLite file's directory
    must be writable)."""
    import sqlalchemy  # (b) SQLAlchemy: database storages only, not a journal

    shown = redact(url)
    db = _sqlite_file(url, shown)
    if db is not None:
        try:
            check_file(db, "Optuna storage")
        except OutputError as exc:
            raise StorageError(str(exc)) from None
        if not db.exists():
            return  # connecting would create it
    with _rdb_errors(shown):
        engine = sqlalchemy.create_engine(url, **_engine_kwargs(url))
        try:
            with engine.connect():
                pass
        finally:
            engine.dispose()


def _rdb_storage(url: str, stale_after_s: float):
    shown = redact(url)
    db = _sqlite_file(url, shown)
    if db is not None:
        db.parent.mkdir(parents=True, exist_ok=True)
    with _rdb_errors(shown):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExperimentalWarning)  # heartbeat_interval
            return optuna.storages.RDBStorage(
                url, engine_kwargs=_engine_kwargs(url) or None,
                heartbeat_interval=heartbeat_interval(stale_after_s),
                grace_period=max(1, int(stale_after_s)),
                heartbeat_stale_trial_callback=_retry())


# --------------------------------------------------------------------------- Optuna internals
# The scheduler's access to what Optuna keeps private (a study's storage, its id, a trial's
# id): here, and nowhere else (tests/test_layering.py checks).


def heartbeat_enabled(study: optuna.Study) -> bool:
    """Whether ``study``'s storage has Optuna's own heartbeat (an RDB storage opened by
    :func:`open_storage`); the journal file has none."""
    storage = study._storage
    return isinstance(storage, optuna.storages.RDBStorage) \
        and storage.get_heartbeat_interval() is not None


def beat(study: optuna.Study, trial: optuna.Trial) -> None:
    """One heartbeat of a running trial: Optuna's own on an RDB storage, a user attribute on
    the journal file."""
    storage = study._storage
    if isinstance(storage, optuna.storages.RDBStorage) and heartbeat_enabled(study):
        storage.record_heartbeat(trial._trial_id)
    else:
        trial.set_user_attr("heartbeat", time.time())


def set_trial_attr(study: optuna.Study, number: int, key: str, value) -> None:
    """Set a user attribute of trial ``number``, which another process may be running."""
    storage = study._storage
    trial_id = storage.get_trial_id_from_study_id_trial_number(study._study_id, number)
    storage.set_trial_user_attr(trial_id, key, value)


def retry(study: optuna.Study, number: int) -> None:
    """Queue failed trial ``number`` once more with its parameters (Optuna's
    ``RetryFailedTrialCallback``, without the dead attempt's own attributes)."""
    _retry()(study, study.get_trials(deepcopy=False)[number])


def dashboard_command(storage: str, port: int, root: Path) -> list[str]:
    """The ``optuna-dashboard`` command line serving the studies of ``storage`` (a journal
    file, relative to ``root``, or an RDB URL) on 127.0.0.1."""
    cmd = [sys.executable, "-c", "from optuna_dashboard._cli import main; main()",
           "--host", "127.0.0.1", "--port", str(port)]  # the package has no __main__
    if "://" in storage:
        return cmd + [storage]
    path = Path(storage)
    path = path if path.is_absolute() else root / path
    return cmd + ["--storage-class", "JournalFileStorage", str(path)]
