"""Optuna's journal file, failing safe.

Optuna's journal file is one JSON record per line, replayed from the start by every process
that opens it. Optuna's reader tolerates a damaged *last* line (a write in progress), but
once anything is appended after a damaged line every later read fails, so one torn write
(a full disk, a killed machine) would end the study for good. Here the file is checked
under its lock when it is opened, before anything is appended; an append never lands after
a torn line; and :func:`~._repair.repair_journal` recovers every complete record into a new
file.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Generator, Iterator
from pathlib import Path
from typing import Any

from optuna.storages.journal import JournalFileBackend

from ..process.errors import StorageError
from ..process.signals import interrupts_deferred
from ._optuna import JournalOperation, JournalStorageReplayResult, get_lock_file

__all__ = ["JournalDamaged", "JournalFile", "describe_record", "find_damage", "holding",
           "id_gap", "journal_file", "journal_path", "parse_line", "read_lines", "replay_records"]

#: What a record does, by op code (Optuna's ``JournalOperation``).
_OPS = {0: "a study created", 1: "a study deleted", 2: "a study attribute",
        3: "a study attribute", 4: "a trial created", 5: "a trial parameter",
        6: "a trial's state", 7: "a trial's report", 8: "a trial attribute",
        9: "a trial attribute", 10: "trials discarded"}
_STATES = {0: "a trial started", 1: "a trial completed", 2: "a trial pruned",
           3: "a trial failed", 4: "a trial queued"}


class JournalDamaged(StorageError):
    """An Optuna journal file with a damaged line.

    The line is a torn (incomplete) record, bytes that are not a JSON record, or a record
    Optuna cannot replay. Nothing was appended to the file.
    """

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


def describe_record(record: dict) -> str:
    op = record["op_code"]
    if op == 0 and isinstance(record.get("study_name"), str):
        name = record["study_name"]
        return f"study {name if len(name) <= 40 else name[:37] + '...'} created"
    if op == 6:
        state = record.get("state")
        return _STATES.get(state, _OPS[op]) if isinstance(state, int) else _OPS[op]
    return _OPS[op]


def parse_line(line: bytes) -> tuple[dict | None, str]:
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


def read_lines(path: Path) -> Iterator[tuple[int, bytes, Any, str]]:
    """Yield ``(number, bytes, record or None, why)`` for each line of the file (from 1)."""
    with open(path, "rb") as fh:
        for number, line in enumerate(fh, start=1):
            yield (number, line, *parse_line(line))


def replay_records(records: list[dict]) -> tuple[int | None, str]:
    """Find the first record Optuna's replay raises on: ``(index, why)``, else ``(None, "")``.

    The records are replayed as a process that wrote none of them, as Optuna replays
    others' records.
    """
    replay = JournalStorageReplayResult("workbench-check-")
    for i, record in enumerate(records):
        try:
            replay.apply_logs([record])
        except Exception as exc:
            return i, f"a record Optuna cannot replay: {type(exc).__name__}"
    return None, ""


def id_gap(records: list[dict]) -> int | None:
    """Index of the first record naming a study or trial that no earlier record created.

    ``None`` when there is none. Optuna numbers studies and trials by their creation
    records, so in a sound journal this never happens; after a lost creation record the ids
    shift and the records of the last trials point past the end (or at the wrong trial).
    """
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


def find_damage(path: Path, shown: str, hint: str | None = None,
                 replay: bool = False) -> JournalDamaged | None:
    """Find the file's first damaged line, as a :class:`JournalDamaged`, else ``None``.

    With ``replay``, records that Optuna cannot replay count as damaged too. Without the
    file's lock, another process's append in progress can look like a torn last line.
    """
    first = None
    last_good, total, records, numbers = "none", 0, [], []
    for number, _, record, why in read_lines(path):
        total = number
        if first is None:
            if record is None:
                first = (number, why)
            else:
                last_good = f"line {number}, {describe_record(record)}"
                if replay:
                    records.append(record)
                    numbers.append(number)
    if first is None and replay and records:
        index, why = replay_records(records)
        if index is not None:
            first = (numbers[index], why)
            last_good = (f"line {numbers[index - 1]}, {describe_record(records[index - 1])}"
                         if index else "none")
    if first is None:
        return None
    return JournalDamaged(shown, first[0], total, first[1], last_good, hint)


@contextlib.contextmanager
def holding(lock: Any, shown: str) -> Iterator[None]:
    """Hold the journal file's lock (Optuna's: every append takes it), or fail in one line."""
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


class JournalFile(JournalFileBackend):
    """Optuna's journal file, flushed to disk (fsync) only when a trial's state changes.

    The file is synced when the appended operations create or delete a study, create a trial
    or set a trial's state, instead of after every append (a trial's parameters, reports,
    heartbeats and attributes: ~20 fsyncs of ~3.5 ms per trial here, an eighth of a small
    sweep). Every append is still written under the file lock before it returns, so other
    processes (and machines sharing the file, whose NFS flushes at close) see it at once;
    only an operating-system crash or power loss can lose the unsynced operations of the
    running trials, which a resumed sweep runs again.

    Fails safe: :meth:`check` finds a damaged line before anything is appended; an append
    after a torn last line is refused (it would glue a good record to the torn one); a read
    that meets a damaged line ends in a :class:`JournalDamaged` of one line.
    """

    def __init__(self, file_path: str, shown: str | None = None):
        super().__init__(file_path)
        self._shown = shown or file_path

    def check(self, hint: str | None = None) -> None:
        """Raise :class:`JournalDamaged` at the first damaged line.

        Damage found is checked again under the file lock (another process's append in
        progress looks like a torn last line), so an intact file is read without taking the
        lock.
        """
        path = Path(self._file_path)
        if find_damage(path, self._shown, hint) is None:
            return
        with holding(self._lock, self._shown):
            damage = find_damage(path, self._shown, hint)
        if damage is not None:
            raise damage

    def read_logs(self, log_number_from: int) -> Generator[dict[str, Any], None, None]:
        try:
            yield from super().read_logs(log_number_from)
        except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, "Invalid log format."
            damage = find_damage(Path(self._file_path), self._shown)
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
                    damage = find_damage(Path(self._file_path), self._shown)
                    raise damage or StorageError(f"Optuna journal {self._shown} ends in a "
                                                 "torn record; nothing was appended")
                _append(f.fileno(), text.encode("utf-8"), end, sync, self._shown)


def _append(fd: int, data: bytes, end: int, sync: bool, shown: str) -> None:
    """Append ``data`` to the journal open as ``fd`` (``end``: its size), under its lock.

    A write that fails (a full disk) is undone: the file is cut back to ``end``, so it never
    ends in a torn record that a later command would have to repair.
    """
    try:
        view = memoryview(data)
        while view:  # the file is open for appending: every write goes to its end
            view = view[os.write(fd, view):]
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.ftruncate(fd, end)
        raise StorageError(f"cannot write Optuna journal {shown}: "
                           f"{exc.strerror or type(exc).__name__}; nothing was appended. Free "
                           "space (or fix the file system), then run the command again") from None
    if sync:
        try:
            os.fsync(fd)
        except OSError as exc:  # written, perhaps already read by other processes: kept
            raise StorageError(f"cannot sync Optuna journal {shown} to disk: "
                               f"{exc.strerror or type(exc).__name__}") from None


def journal_path(storage: str, root: Path) -> Path:
    path = Path(storage)
    return path if path.is_absolute() else root / path


def journal_file(storage: str, root: Path) -> Path:
    """:func:`journal_path`, refused when it is a directory."""
    path = journal_path(storage, root)
    if path.is_dir():
        raise StorageError(f"Optuna storage {path} is a directory; give a journal file path "
                           "(e.g. mlruns/optuna.journal) or a database URL")
    return path
