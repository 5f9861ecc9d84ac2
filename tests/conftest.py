import os
import tempfile
from pathlib import Path

import pytest

os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
os.environ.setdefault("MPLCONFIGDIR", tempfile.mkdtemp(prefix="workbench-mpl-"))

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "google_5q"


@pytest.fixture(scope="session", autouse=True)
def _mlflow_store(tmp_path_factory):
    """Every test session (each xdist worker) logs to its own temporary MLflow store, never to
    the project's mlruns/."""
    store = tmp_path_factory.mktemp("mlflow") / "mlflow.db"
    os.environ["MLFLOW_TRACKING_URI"] = f"sqlite:///{store}"
    yield store


@pytest.fixture(scope="session")
def google_5q_dir():
    """A directory with the benchmark files: the shared copy when present, otherwise the
    loader's cache, filled by a real (verified) download."""
    from workbench.datasets.google_5q import google_5q_csv_path, load_google_5q

    if SHARED_DATA.is_dir():
        return SHARED_DATA
    load_google_5q()  # downloads into the user cache when missing
    return google_5q_csv_path().parent


@pytest.fixture(scope="session")
def ibm_gates_dir():
    """A directory with the IBM snapshots: the loader's cache, filled by a real (verified)
    download of the wheel when missing."""
    from workbench.datasets.ibm_gates import WHEEL

    return WHEEL.directory()


@pytest.fixture(scope="session")
def google_5q(google_5q_dir):
    from workbench.datasets import load_google_5q

    return load_google_5q(google_5q_dir)
