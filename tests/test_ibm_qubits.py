"""Tests for the IBM single-qubit targets' loader (on the real, checksummed snapshots)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.datasets import ibm_qubits as iq
from workbench.datasets.ibm_gates import TIME_SPLIT


@pytest.fixture(scope="module")
def table(ibm_gates_dir: Path) -> pd.DataFrame:
    return iq.qubit_table(ibm_gates_dir, download=False)


def test_one_qubit_by_hand(ibm_gates_dir: Path, table: pd.DataFrame) -> None:
    """brisbane's qubit 3 from the file, both limits computed here."""
    props = json.loads((ibm_gates_dir / "props_brisbane.json").read_text())
    q = {x["name"]: x["value"] for x in props["qubits"][3]}
    sx = next(g for g in props["gates"] if g["gate"] == "sx" and g["qubits"] == [3])
    p = {x["name"]: x["value"] for x in sx["parameters"]}
    t = p["gate_length"] * 1e-3
    f = (1 + np.exp(-t / q["T1"]) + 2 * np.exp(-t / min(q["T2"], 2 * q["T1"]))) / 4
    row = table[(table["device"] == "brisbane") & (table["qubit"] == 3)].iloc[0]
    assert row["sx_error"] == pytest.approx(100 * p["gate_error"])
    assert row["sx_limit"] == pytest.approx(100 * 2 / 3 * (1 - f))
    assert row["readout_error"] == pytest.approx(100 * q["readout_error"])
    ro = q["readout_length"] * 1e-3
    assert row["readout_limit"] == pytest.approx(100 * (1 - np.exp(-ro / q["T1"])) / 2)
    assert row["n_qubits"] == 127 and row["snapshot"] == "2025-02-26"


def test_table(table: pd.DataFrame) -> None:
    numeric = table.drop(columns=["device", "snapshot", "qubit", "readout_limit"])
    assert np.isfinite(numeric.to_numpy(dtype=float)).all()
    assert ((table["sx_error"] > 0) & (table["sx_error"] < 100)).all()
    # the limits are lower bounds for most qubits (T1, T2 drift between measurements)
    assert (table["sx_error"] >= table["sx_limit"]).mean() > 0.7
    has = table["readout_limit"].notna()
    assert (table.loc[has, "readout_error"] >= table.loc[has, "readout_limit"]).mean() > 0.7
    assert (table.loc[~has, "readout_length_ns"] == 0).all()


@pytest.mark.parametrize("target", ["sx", "readout"])
def test_splits(ibm_gates_dir: Path, target: str) -> None:
    ds = iq.load_ibm_qubits(ibm_gates_dir, target=target, download=False)
    table = iq.qubit_table(ibm_gates_dir, download=False)
    table = table[table[iq.QUBIT_TARGETS[target][1]].notna()].reset_index(drop=True)
    dates = pd.to_datetime(table["snapshot"])
    assert (dates[ds.test_index] >= pd.Timestamp(TIME_SPLIT)).all()
    assert (dates[ds.train_index] < pd.Timestamp(TIME_SPLIT)).all()
    assert ds.prior_names == [iq.QUBIT_TARGETS[target][1]] and ds.unit == "%"
    dev = iq.load_ibm_qubits(ibm_gates_dir, target=target, split="devices", download=False)
    held = set(dev.groups[dev.test_index])
    assert not held & set(dev.groups[dev.train_index])
    assert len(held) == round(0.3 * dev.groups.nunique())


def test_unknown_target_and_split(ibm_gates_dir: Path) -> None:
    with pytest.raises(ValueError, match="unknown target 'cz'.*'sx', 'readout'"):
        iq.load_ibm_qubits(ibm_gates_dir, target="cz", download=False)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="unknown split 'random'"):
        iq.load_ibm_qubits(ibm_gates_dir, split="random", download=False)  # type: ignore[arg-type]
