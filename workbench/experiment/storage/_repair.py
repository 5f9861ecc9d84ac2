"""Repairing a damaged Optuna journal file (``workbench sweep --repair``).

Every complete record is recovered into a new file that must replay before it replaces the
original, which is kept beside it.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import optuna
from optuna.storages.journal import JournalFileSymlinkLock

from ..process.errors import StorageError, redact
from ._journal import holding, id_gap, journal_path, read_lines, replay_records

__all__ = ["Repair", "repair_journal"]


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
    """Recover every complete record of a damaged journal file into a new file.

    ``None`` when it is not damaged, or does not exist. The original is kept as ``<file>.damaged``
    (``.damaged-N`` when that exists); the good records are written to a temporary file
    beside it, which must replay (a :class:`JournalStorage` on it loads every study's
    trials) before it is moved into place atomically. When the complete records do not
    replay as written without the damaged lines (a lost record created a study or trial, so
    later ids would shift), only the records before the first damaged line are kept. Run it
    while no sweep works on the file.
    """
    if "://" in storage:
        raise StorageError(f"--repair repairs an Optuna journal file; {redact(storage)} is a "
                           "database")
    path = journal_path(storage, root)
    if not path.exists():
        return None
    if not path.is_file():
        raise StorageError(f"--repair: Optuna journal {storage} is not a file")
    with holding(JournalFileSymlinkLock(str(path)), storage):
        lines = list(read_lines(path))
        bad = {n: why for n, _, record, why in lines if record is None}
        for _ in range(3):  # well-formed records that Optuna cannot replay are damaged too
            kept = [(n, record) for n, _, record, _ in lines if n not in bad]
            index, why = replay_records([record for _, record in kept])
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
            if id_gap(records) is not None or replay_records(records)[0] is not None:
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
    """Count ``(studies, trials)`` of a journal file replayed by Optuna itself.

    Raises unless every one of its ``n_records`` lines was read.
    """
    storage = optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(path)))
    if storage._replay_result.log_number_read != n_records:
        raise StorageError(f"replayed {storage._replay_result.log_number_read} of "
                           f"{n_records} records")
    studies = storage.get_all_studies()
    trials = sum(len(storage.get_all_trials(s._study_id, deepcopy=False)) for s in studies)
    return len(studies), trials


def _keep_original(path: Path) -> Path:
    """Give the damaged file a second name, ``<file>.damaged`` or ``<file>.damaged-N``.

    It keeps the bytes once the repaired file replaces the original (a hard link, else a
    copy).
    """
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

