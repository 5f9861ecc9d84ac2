"""Tests for the IBM two-qubit gate benchmark's loader (on the real, checksummed files)."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from workbench.datasets import DataUnavailableError, load_ibm_gates
from workbench.datasets import ibm_gates as ibm


@pytest.fixture(scope="module")
def table(ibm_gates_dir: Path):
    return ibm.gate_table(ibm_gates_dir, download=False)


def test_every_file_checked(ibm_gates_dir: Path) -> None:
    assert len(ibm.WHEEL.files) == 67
    for name, (member, sha) in ibm.WHEEL.files.items():
        assert member.endswith("/" + name)
        assert hashlib.sha256((ibm_gates_dir / name).read_bytes()).hexdigest() == sha
    assert "props_cambridge_alt.json" not in ibm.WHEEL.files
    assert "props_fractional.json" not in ibm.WHEEL.files


def test_table(table) -> None:
    assert len(table) == 6648 and table["device"].nunique() == 65
    assert list(table.columns[:3]) == ["device", "snapshot", "gate"]
    numeric = table[[ibm.TARGET, ibm.PRIOR, *ibm.FEATURES]]
    assert np.isfinite(numeric.to_numpy()).all()
    assert (table[ibm.TARGET] < 100).all() and (table[ibm.TARGET] > 0).all()
    assert (table[[f"gate_{g}" for g in ibm.GATES]].sum(axis=1) == 1).all()
    assert "kyoto" not in set(table["device"])  # every gate out of service (error 1)
    # the coherence limit is a lower bound for most gates, not all (T1 and T2 drift between
    # their measurement and the gate's)
    assert 0.8 < (table[ibm.TARGET] > table[ibm.PRIOR]).mean() < 0.95


def test_one_row_by_hand(ibm_gates_dir: Path, table) -> None:
    """brisbane's ecr62_72 from the file, the coherence limit computed here."""
    props = json.loads((ibm_gates_dir / "props_brisbane.json").read_text())
    gate = next(g for g in props["gates"] if g["name"] == "ecr62_72")
    p = {x["name"]: x["value"] for x in gate["parameters"]}
    q = [{x["name"]: x["value"] for x in props["qubits"][i]} for i in (62, 72)]
    t = p["gate_length"] * 1e-3
    f = [(1 + np.exp(-t / x["T1"]) + 2 * np.exp(-t / min(x["T2"], 2 * x["T1"]))) / 4 for x in q]
    row = table[(table["device"] == "brisbane") & (table["gate"] == "ecr62_72")].iloc[0]
    assert row[ibm.TARGET] == pytest.approx(100 * p["gate_error"])
    assert row[ibm.PRIOR] == pytest.approx(100 * 0.8 * (1 - f[0] * f[1]))
    assert row["t2_b_us"] == pytest.approx(q[1]["T2"]) and row["gate_ecr"] == 1.0
    assert row["snapshot"] == "2025-02-26" and row["n_qubits"] == 127


def test_time_split(ibm_gates_dir: Path) -> None:
    ds = load_ibm_gates(ibm_gates_dir, download=False)
    assert (len(ds.train_index), len(ds.test_index)) == (1935, 4713)
    assert ds.target_names == [ibm.TARGET] and ds.prior_names == [ibm.PRIOR]
    assert ds.unit == "%"  # the gate error in percent: figures and summaries say so
    assert ds.feature_names == ibm.FEATURES
    assert ds.groups is not None
    train, test = set(ds.groups[ds.train_index]), set(ds.groups[ds.test_index])
    assert not train & test and len(test) == 19  # whole devices, and later ones
    err = np.abs(ds.prior.to_numpy() - ds.targets.to_numpy())[:, 0]
    assert err[ds.test_index].mean() == pytest.approx(0.5779, abs=1e-4)


def test_devices_split(ibm_gates_dir: Path) -> None:
    a = load_ibm_gates(ibm_gates_dir, split="devices", split_seed=0, download=False)
    b = load_ibm_gates(ibm_gates_dir, split="devices", split_seed=0, download=False)
    c = load_ibm_gates(ibm_gates_dir, split="devices", split_seed=1, download=False)
    np.testing.assert_array_equal(a.test_index, b.test_index)
    assert not np.array_equal(a.test_index, c.test_index)
    held = set(a.groups[a.test_index])
    assert len(held) == 20 and not held & set(a.groups[a.train_index])
    with pytest.raises(ValueError, match="unknown split 'rows'.*'time', 'devices'"):
        load_ibm_gates(ibm_gates_dir, split="rows", download=False)  # type: ignore[arg-type]


def test_damaged_file_is_refused(ibm_gates_dir: Path, tmp_path: Path) -> None:
    for name in ibm.WHEEL.files:
        shutil.copy(ibm_gates_dir / name, tmp_path / name)
    target = tmp_path / "props_lima.json"
    target.write_bytes(target.read_bytes().replace(b"0.0", b"0.1", 1))
    with pytest.raises(DataUnavailableError) as exc:
        load_ibm_gates(tmp_path, download=True)  # a user's file is never replaced
    msg = str(exc.value)
    assert "sha256 mismatch" in msg and "props_lima.json" in msg
    assert "WORKBENCH_IBM_DATA_DIR" in msg and "qiskit-ibm-runtime==0.51.0" in msg
    assert target.read_bytes() != (ibm_gates_dir / "props_lima.json").read_bytes()


def test_missing_files_without_download(tmp_path: Path) -> None:
    with pytest.raises(DataUnavailableError, match="missing file .*and 64 more.*download=False"):
        load_ibm_gates(tmp_path, download=False)
