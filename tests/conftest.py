import os
import tempfile
from pathlib import Path

import pytest

os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
os.environ.setdefault("MPLCONFIGDIR", tempfile.mkdtemp(prefix="workbench-mpl-"))

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "google_5q"


# `make test` hands whole files to its two workers (--dist loadfile) in the order collected
# (--no-loadscope-reorder). The longest files go first, so that none starts late and runs alone
# at the end while the other worker idles; the rest keep their order. Longest first, as
# measured: a file's share of the suite's time (sum of --durations under `make test` on 2
# cores, 2026-11-26; about 450 s on a quiet machine).
LONG_FILES = [
    "test_reproduce.py",  # 13%, one `reproduce --quick --all`
    "test_lifecycle.py",  # 9%, sweep and evaluate processes killed and rerun
    "test_candidate_matrix.py",  # about 53 CPU-s alone (not a --durations share): five
    # kinds of model through evaluate (tracked, untracked, seeds), predict and a sweep
    "test_interrupts.py",  # 9%, evaluate and sweep processes interrupted
    "test_sweep.py",  # 7.5%, the smoke sweep (stopped by --timeout, resumed)
    "test_services.py",  # 7%, PostgreSQL, an mlflow server, three sweep processes
    "test_hamiltonian_family.py",  # 4%
    "test_docs.py",  # 4%, a Sphinx build of docs/ without the gallery
    "test_cli.py",  # 3.5%
    "test_predict.py",  # 3.3%
    "test_store_restart.py",  # 2.8%
    "test_disk_full.py",  # 2.7%
    "test_param_select.py",  # 2.3%
    "test_init.py",  # 2%
    "test_ui_browser.py",  # 1.9%
    "test_cli_set.py",  # 1.9%
    "test_layering.py",  # 1.8%
    "test_tracking_restart.py",  # 1.6%
    "test_sweep_hamiltonian.py",  # 1.5%
    "test_readme.py",  # 1.5%
]


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(LONG_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: files stay whole


@pytest.fixture(scope="session", autouse=True)
def _mlflow_store(tmp_path_factory):
    """Every test session (each xdist worker) logs to its own temporary MLflow store, never to
    the project's mlruns/."""
    store = tmp_path_factory.mktemp("mlflow") / "mlflow.db"
    os.environ["MLFLOW_TRACKING_URI"] = f"sqlite:///{store}"
    yield store


@pytest.fixture(scope="session")
def _empty_store(tmp_path_factory):
    """An empty MLflow SQLite store, made once per worker: MLflow builds a new one with its
    whole chain of schema migrations (about 1.3 CPU-s, and a disk sync per migration)."""
    import contextlib

    from mlflow import MlflowClient

    folder = tmp_path_factory.mktemp("empty-store")
    with contextlib.chdir(folder):  # MLflow's "Default" experiment points inside it
        MlflowClient(f"sqlite:///{folder / 'mlflow.db'}").search_experiments()
    return folder / "mlflow.db"


@pytest.fixture(scope="session")
def new_store(_empty_store):
    """``new_store(path)``: an empty MLflow store at ``path`` (parents made), a copy of one
    made once; returns its ``sqlite:///`` URI. For tests whose store is incidental, also
    those handing it to a ``workbench`` process or a server. (A new store the product makes
    is itself a copy of the cached template, tracking/store_template.py; the tests of a
    store's first use, test_lifecycle.py's concurrent evaluates on an empty cache,
    test_store_failures.py and test_tracking.py, let the product create theirs.)"""
    import shutil

    def make(path):
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(_empty_store, path)
        return f"sqlite:///{path}"

    return make


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
