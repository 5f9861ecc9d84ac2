"""IBM single-qubit calibration targets with their physical limits as priors.

The same snapshots as the two-qubit gate benchmark (:mod:`workbench.datasets.ibm_gates`: the
calibration files of ``qiskit-ibm-runtime==0.51.0``'s fake backends, Apache-2.0, fetched and
verified by the same :data:`~workbench.datasets.ibm_gates.WHEEL`), one row per qubit of each
snapshot, two targets:

* ``"sx"``: the ``sx`` gate's measured error (``u2`` on the oldest devices; randomized
  benchmarking), in percent; **prior** ``sx_limit``: the average gate infidelity T1 and T2
  alone cause during the gate's length, ``2/3 (1 - F)`` with the process fidelity of
  amplitude and phase damping ``F = (1 + e^(-t/T1) + 2 e^(-t/T2)) / 4`` (dimension 2; ``T2``
  capped at ``2 T1``);
* ``"readout"``: the qubit's readout assignment error (the mean of P(0|1) and P(1|0)), in
  percent; **prior** ``readout_limit``: the T1-limited error, ``(1 - e^(-t_ro/T1)) / 2``
  (the prepared 1 decays during the readout window ``t_ro``; the prepared 0 does not).
  Snapshots without a readout length (9 of the 67) have no readout rows.

**Features**: the qubit's T1 and T2 (us), the sx gate's length (ns), the readout length (ns;
sx rows: 0 where the file gives none), the other target's measured error (sx rows: the
readout error; readout rows: the sx error) and the device's number of qubits.

Left out: qubits without T1/T2, and errors IBM marks as out of service (1). Splits as the
gate benchmark's: ``"time"`` (snapshots before 2025-01-01 train, the newer ones test) and
``"devices"`` (30% of the devices held out, ``split_seed``).
"""

from __future__ import annotations

import json
import os
from datetime import datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .base import Dataset
from .ibm_gates import DEVICES_TEST_FRACTION, ONE_QUBIT, TIME_SPLIT, WHEEL, _values

__all__ = ["QUBIT_TARGETS", "load_ibm_qubits", "qubit_table", "readout_limit", "sx_limit"]

#: target -> (target column, prior column, features)
QUBIT_TARGETS = {
    "sx": ("sx_error", "sx_limit",
           ["t1_us", "t2_us", "sx_length_ns", "readout_length_ns", "readout_error",
            "n_qubits"]),
    "readout": ("readout_error", "readout_limit",
                ["t1_us", "t2_us", "sx_length_ns", "readout_length_ns", "sx_error",
                 "n_qubits"]),
}
_UNITS = {"readout_length": ("ns",)}


def sx_limit(length_ns: ArrayLike, t1_us: ArrayLike, t2_us: ArrayLike) -> np.ndarray:
    """The average infidelity (a fraction) T1 and T2 (us) alone cause in a one-qubit gate of
    ``length_ns``: ``2/3 (1 - F)``, ``F = (1 + e^(-t/T1) + 2 e^(-t/T2)) / 4``, ``T2 <= 2 T1``.

    Parameters
    ----------
    length_ns : array-like
        The gate's length (ns).
    t1_us, t2_us : array-like
        The qubit's T1 and T2 (us).

    Returns
    -------
    ndarray
        The infidelity.
    """
    t = np.asarray(length_ns, dtype=float) * 1e-3
    t1 = np.asarray(t1_us, dtype=float)
    t2 = np.minimum(np.asarray(t2_us, dtype=float), 2 * t1)
    return 2 / 3 * (1 - (1 + np.exp(-t / t1) + 2 * np.exp(-t / t2)) / 4)


def readout_limit(length_ns: ArrayLike, t1_us: ArrayLike) -> np.ndarray:
    """The T1-limited readout assignment error (a fraction): ``(1 - e^(-t_ro/T1)) / 2``.

    Parameters
    ----------
    length_ns : array-like
        The readout's length (ns).
    t1_us : array-like
        The qubit's T1 (us).

    Returns
    -------
    ndarray
        The error.
    """
    t = np.asarray(length_ns, dtype=float) * 1e-3
    return (1 - np.exp(-t / np.asarray(t1_us, dtype=float))) / 2


def _qubit_rows(device: str, props: dict) -> list[dict]:
    where = f"props_{device}.json"
    snapshot = datetime.fromisoformat(props["last_update_date"]).date().isoformat()
    qubits = [_values(q, f"{where} qubit {i}") for i, q in enumerate(props["qubits"])]
    one: dict[int, dict[str, Any]] = {}
    for g in props["gates"]:
        if g["gate"] in ONE_QUBIT and len(g["qubits"]) == 1:
            one.setdefault(g["qubits"][0], _values(g["parameters"], f"{where} {g['gate']}"))
    rows = []
    for i, q in enumerate(qubits):
        for key, unit in _UNITS.items():
            found = next((e for e in props["qubits"][i] if e.get("name") == key), None)
            if found is not None and found.get("unit") not in unit:
                raise WHEEL.fail(f"{where} qubit {i}: {key} in unit {found.get('unit')!r}")
        gate = one.get(i, {})
        needed = [q.get("T1"), q.get("T2"), q.get("readout_error"), gate.get("gate_error"),
                  gate.get("gate_length")]
        if any(v is None for v in needed) or max(q["readout_error"], gate["gate_error"]) >= 1:
            continue
        length = q.get("readout_length")
        rows.append({
            "device": device, "snapshot": snapshot, "qubit": i,
            "sx_error": 100 * gate["gate_error"],
            "sx_limit": 100 * float(sx_limit(gate["gate_length"], q["T1"], q["T2"])),
            "readout_error": 100 * q["readout_error"],
            "readout_limit": (100 * float(readout_limit(length, q["T1"]))
                              if length else np.nan),
            "t1_us": q["T1"], "t2_us": q["T2"], "sx_length_ns": gate["gate_length"],
            "readout_length_ns": float(length or 0.0), "n_qubits": len(qubits)})
    return rows


def qubit_table(data_dir: str | os.PathLike[str] | None = None, *,
                download: bool = True) -> pd.DataFrame:
    """Every kept qubit of every snapshot: ``device``, ``snapshot`` (the date), ``qubit``, both
    targets, both priors (``readout_limit`` NaN without a readout length) and the features.

    Parameters
    ----------
    data_dir : str or path-like, default=None
        Where the files are (``None``: the user cache).
    download : bool, default=True
        Whether to fetch (and verify) the files when they are missing.

    Returns
    -------
    pandas.DataFrame
        The qubits.
    """
    directory = WHEEL.directory(data_dir, download=download)
    rows: list[dict] = []
    for name in sorted(WHEEL.files):
        path = Path(directory) / name
        try:
            props = json.loads(path.read_text(encoding="utf-8"))
            rows += _qubit_rows(name[len("props_"):-len(".json")], props)
        except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
            raise WHEEL.fail(f"cannot read {path}: {exc!r}") from exc
    return pd.DataFrame(rows)


def split_mask(table: pd.DataFrame, split: str, split_seed: int = 0) -> np.ndarray:
    """Mark the test rows of ``split``.

    Parameters
    ----------
    table : DataFrame
        The qubits' table (its ``device`` and ``snapshot`` columns).
    split : {"time", "devices"}
        The snapshots from ``TIME_SPLIT`` on, or a share of the devices held out at
        random.
    split_seed : int, default=0
        Seeds the devices held out.

    Returns
    -------
    ndarray of bool
        True on the test rows.

    Raises
    ------
    ValueError
        For an unknown split.
    """
    devices = table["device"]
    if split == "time":
        return (pd.to_datetime(table["snapshot"]) >= pd.Timestamp(TIME_SPLIT)).to_numpy()
    if split == "devices":
        names = np.array(sorted(devices.unique()))
        rng = np.random.default_rng(split_seed)
        held = rng.choice(names, size=round(DEVICES_TEST_FRACTION * len(names)), replace=False)
        return devices.isin(held).to_numpy()
    raise ValueError(f"unknown split {split!r}; the splits are 'time', 'devices'")


def load_ibm_qubits(data_dir: str | os.PathLike[str] | None = None, *,
                    target: Literal["sx", "readout"] = "sx",
                    split: Literal["time", "devices"] = "time", split_seed: int = 0,
                    download: bool = True) -> Dataset:
    """One IBM single-qubit target (see the module docstring) with its ``split``.

    ``groups`` holds each row's device.

    Parameters
    ----------
    data_dir : str or path-like, default=None
        Where the snapshots are (``None``: the loader's cache).
    target : {"sx", "readout"}, default="sx"
        The sx gate error (prior: its coherence limit) or the readout error (prior: its T1
        limit).
    split : {"time", "devices"}, default="time"
        ``"time"``: the snapshots from 2025 on are the test rows; ``"devices"``: 30% of the
        devices, held out at random.
    split_seed : int, default=0
        Which devices the ``"devices"`` split holds out.
    download : bool, default=True
        Whether to fetch (and verify) the wheel when it is missing.

    Returns
    -------
    Dataset
        The data and their split.
    """
    if target not in QUBIT_TARGETS:
        raise ValueError(f"unknown target {target!r}; the targets are {list(QUBIT_TARGETS)}")
    y, prior, features = QUBIT_TARGETS[target]
    table = qubit_table(data_dir, download=download)
    table = table[table[prior].notna()].reset_index(drop=True)
    test = split_mask(table, split, split_seed)
    index = table.index.to_numpy()
    return Dataset(name=f"ibm_{target}", features=table[features].astype(float),
                   prior=table[[prior]].astype(float), targets=table[[y]].astype(float),
                   train_index=index[~test], test_index=index[test],
                   groups=table["device"].copy(), unit="%")
