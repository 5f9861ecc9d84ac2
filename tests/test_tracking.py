"""MLflow tracking (workbench.experiment.tracking) against a temporary SQLite store."""

import os

os.environ["MLFLOW_DISABLE_TELEMETRY"] = "true"  # before MLflow is imported

import json
import pickle
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import workbench
from workbench.experiment.process.errors import TrackingError
from workbench.experiment.tracking.records import dataset_hash, git_commit
from workbench.experiment.tracking.runs import (
    SKIPPED_METRICS_TAG,
    TRUNCATED_PARAMS_TAG,
    Tracker,
    ensure_store,
)
from workbench.experiment.tracking.uris import (
    default_artifact_root,
    default_tracking_uri,
    resolve_tracking_uri,
)

PROJECT = Path(workbench.__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return tmp_path_factory.mktemp("project")


@pytest.fixture(scope="module")
def tracker(root):
    ensure_store(default_tracking_uri(root), "tests", default_artifact_root(root))
    return Tracker(default_tracking_uri(root), "tests", default_artifact_root(root))


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    X = pd.DataFrame(rng.normal(size=(80, 3)), columns=["a", "b", "c"])
    X["prior_u"] = 2.0 * X["a"]
    X["prior_v"] = X["b"] - 1.0
    Y = pd.DataFrame({"u": X["prior_u"] + 0.5 * X["c"] + rng.normal(0, 0.1, 80),
                      "v": X["prior_v"] + 0.3 * X["a"] ** 2 + rng.normal(0, 0.1, 80)})
    return X, Y


@pytest.fixture(scope="module")
def fitted(data):
    X, Y = data
    model = workbench.MultiTargetBaseBoost(
        workbench.BaseBoostCV(workbench.BaseBoostRegressor(basis=workbench.make_basis("ridge"))),
        priors=["prior_u", "prior_v"])
    return model.fit(X, Y)


@pytest.fixture(scope="module")
def logged_model(tracker, fitted, data):
    X, _ = data
    with tracker.run("model") as run_id:
        start = time.perf_counter()
        uri = tracker.log_model(run_id, fitted, X)
        seconds = time.perf_counter() - start
    print(f"\nlog_model took {seconds:.2f} s")
    return run_id, uri, seconds


# --------------------------------------------------------------------------- URIs


def test_default_uris(tmp_path):
    assert default_tracking_uri(tmp_path) == f"sqlite:///{tmp_path.resolve()}/mlruns/mlflow.db"
    assert default_artifact_root(tmp_path) == (tmp_path.resolve() / "mlruns/artifacts").as_uri()
    assert default_artifact_root(tmp_path).startswith("file:///")


def test_resolve_tracking_uri_precedence(tmp_path, monkeypatch):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    cfg, cli, env = "sqlite:////cfg/x.db", "http://cli:5000", "http://env:5000"
    assert resolve_tracking_uri(None, None, tmp_path) == default_tracking_uri(tmp_path)
    assert resolve_tracking_uri(None, cfg, tmp_path) == cfg
    monkeypatch.setenv("MLFLOW_TRACKING_URI", env)
    assert resolve_tracking_uri(None, cfg, tmp_path) == env
    assert resolve_tracking_uri(cli, cfg, tmp_path) == cli


def test_relative_sqlite_resolves_against_root(tmp_path, monkeypatch):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.chdir(tmp_path)
    root = tmp_path / "proj"
    assert (resolve_tracking_uri(None, "sqlite:///mlruns/mlflow.db", root)
            == f"sqlite:///{root.resolve()}/mlruns/mlflow.db")
    assert (resolve_tracking_uri(None, "sqlite:////abs/m.db", root) == "sqlite:////abs/m.db")
    # on the command line a relative path means the current directory
    assert (resolve_tracking_uri("sqlite:///other.db", None, root)
            == f"sqlite:///{tmp_path.resolve()}/other.db")


# --------------------------------------------------------------------------- runs


def test_store_layout(tracker, root):
    assert (root / "mlruns" / "mlflow.db").is_file()  # parent directory was created
    exp = tracker.client.get_experiment(tracker.experiment_id)
    assert exp.artifact_location == default_artifact_root(root)


def test_parent_with_three_children(tracker):
    with tracker.run("search", params={"n_trials": 3}, tags={"kind": "search"}) as parent:
        for i in range(3):
            with tracker.run(f"trial-{i}", parent_run_id=parent,
                             params={"trial": i, "lr": 0.1 * (i + 1)}) as child:
                tracker.log_metrics(child, {"cv_mae": 1.0 / (i + 1), "fold_mae": 2.0}, step=i)
                tracker.set_tags(child, {"fold": i})
        tracker.log_metrics(parent, {"best_cv_mae": np.float64(1 / 3)})
    kids = tracker.client.search_runs(
        [tracker.experiment_id], filter_string=f"tags.`mlflow.parentRunId` = '{parent}'",
        order_by=["attributes.start_time ASC"])
    assert len(kids) == 3
    assert [k.info.run_name for k in kids] == ["trial-0", "trial-1", "trial-2"]
    client = tracker.client
    for i, kid in enumerate(kids):
        run = client.get_run(kid.info.run_id)
        assert run.info.status == "FINISHED"
        assert run.data.tags["mlflow.parentRunId"] == parent
        assert run.data.tags["fold"] == str(i)
        assert run.data.params == {"trial": str(i), "lr": str(0.1 * (i + 1))}
        assert run.data.metrics["cv_mae"] == pytest.approx(1.0 / (i + 1))
        assert client.get_metric_history(kid.info.run_id, "cv_mae")[0].step == i
    run = client.get_run(parent)
    assert run.info.status == "FINISHED"
    assert run.data.params == {"n_trials": "3"} and run.data.tags["kind"] == "search"
    assert run.data.metrics["best_cv_mae"] == pytest.approx(1 / 3)


def test_failing_run_ends_failed_and_reraises(tracker):
    with pytest.raises(ZeroDivisionError):
        with tracker.run("broken") as run_id:
            raise ZeroDivisionError
    assert tracker.client.get_run(run_id).info.status == "FAILED"
    with pytest.raises(ValueError, match="status"):
        tracker.end_run(run_id, "DONE")


def test_long_params_truncated_and_nonfinite_metrics_skipped(tracker):
    with tracker.run("limits") as run_id:
        tracker.log_params(run_id, {"long": "x" * 7000, **{f"p{i}": i for i in range(150)}})
        tracker.log_metrics(run_id, {"ok": 1.5, "nan": float("nan"), "inf": np.inf,
                                     "third": 1 / 3, "big": 12345.678912})
    run = tracker.client.get_run(run_id)
    assert len(run.data.params) == 151  # more than one batch of 100
    assert len(run.data.params["long"]) == 6000 and "truncated" in run.data.params["long"]
    assert run.data.tags[TRUNCATED_PARAMS_TAG] == "long"
    # 7 significant digits: whole in the runs table
    assert run.data.metrics == {"ok": 1.5, "third": 0.3333333, "big": 12345.68}
    assert set(run.data.tags[SKIPPED_METRICS_TAG].split(",")) == {"nan", "inf"}


def test_experiment_created_once_under_a_race(tracker):
    trackers = [Tracker(tracker.tracking_uri, "raced", tracker.artifact_root) for _ in range(4)]
    ids, errors = [], []
    barrier = threading.Barrier(len(trackers))

    def work(t):
        barrier.wait()
        try:
            ids.append(t.experiment_id)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(t,)) for t in trackers]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not errors and len(set(ids)) == 1 and len(ids) == 4


@pytest.mark.parametrize("error, tries", [
    ("(sqlite3.IntegrityError) UNIQUE constraint failed: datasets.experiment_id, "
     "datasets.name, datasets.digest", 2),
    ('(psycopg2.errors.UniqueViolation) duplicate key value violates unique constraint '
     '"dataset_pk"', 2),
    ("something else", 1),
])
def test_dataset_input_survives_another_process_creating_its_row(tracker, data, monkeypatch,
                                                                  error, tries):
    """Two first runs at once: both look the dataset up, both insert it, the second insert
    violates the unique key (seen under load). The second attempt finds the row and links
    the run to it; other errors are not retried."""
    from mlflow.exceptions import MlflowException

    X, Y = data
    real, calls = tracker.client.log_inputs, []

    def raced(run_id, datasets=None, models=None):
        calls.append(run_id)
        if len(calls) == 1:
            raise MlflowException(error)
        return real(run_id, datasets=datasets, models=models)

    monkeypatch.setattr(tracker.client, "log_inputs", raced)
    with tracker.run("raced dataset") as run_id:
        if tries == 1:
            with pytest.raises(MlflowException, match="something else"):
                tracker.log_dataset(run_id, pd.concat([X, Y], axis=1), name="raced",
                                    context="training")
        else:
            digest = tracker.log_dataset(run_id, pd.concat([X, Y], axis=1), name="raced",
                                         context="training")
            inputs = tracker.client.get_run(run_id).inputs.dataset_inputs
            assert [d.dataset.digest for d in inputs] == [digest]
    assert len(calls) == tries


def test_share_view_retries_a_race_for_its_tag(tracker, monkeypatch):
    """Two first evaluates on a new store set the same shared-view tag at once; the second
    insert violates the unique key (seen on a fresh clone's make test). It tries once more;
    other errors are not retried."""
    from mlflow.exceptions import MlflowException

    real, calls = tracker.client.set_experiment_tag, []

    def raced(experiment_id, key, value, error="UNIQUE constraint failed: experiment_tags"):
        calls.append(key)
        if len(calls) == 1:
            raise MlflowException(error)
        return real(experiment_id, key, value)

    monkeypatch.setattr(tracker.client, "set_experiment_tag", raced)
    tracker.share_view({"orderByKey": "metrics.`test_mae_avg`"})
    assert len(calls) == 2
    tags = tracker.client.get_experiment(tracker.experiment_id).tags
    assert json.loads(tags["mlflow.sharedViewState.workbench"]) == {
        "orderByKey": "metrics.`test_mae_avg`"}
    calls.clear()

    def broken(experiment_id, key, value):
        calls.append(key)
        raise MlflowException("something else")

    monkeypatch.setattr(tracker.client, "set_experiment_tag", broken)
    with pytest.raises(MlflowException, match="something else"):
        tracker.share_view({"orderByKey": "x"})
    assert len(calls) == 1


def test_tracker_pickles_without_its_client(tracker):
    tracker.client  # noqa: B018 - make sure there is one
    clone = pickle.loads(pickle.dumps(tracker))
    assert clone._client is None and clone.experiment_id == tracker.experiment_id


# --------------------------------------------------------------------------- artifacts


def test_artifacts(tracker, root, tmp_path, data):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    X, _ = data
    extra = tmp_path / "notes.md"
    extra.write_text("# notes\n")
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1], [1, 0])
    with tracker.run("artifacts") as run_id:
        tracker.log_figure(run_id, fig, "plots/curve.png")
        tracker.log_dict(run_id, {"a": 1, "b": [1, 2]}, "result.json")
        tracker.log_text(run_id, "hello", "notes/hello.txt")
        tracker.log_file(run_id, extra, "files")
    plt.close(fig)
    png = root / "mlruns" / "artifacts" / run_id / "artifacts" / "plots" / "curve.png"
    assert png.is_file()
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert mpimg.imread(png).ndim == 3
    client = tracker.client
    listed = {a.path for a in client.list_artifacts(run_id)}
    assert listed == {"plots", "result.json", "notes", "files"}
    assert [a.path for a in client.list_artifacts(run_id, "notes")] == ["notes/hello.txt"]
    assert [a.path for a in client.list_artifacts(run_id, "files")] == ["files/notes.md"]
    assert json.loads(Path(client.download_artifacts(run_id, "result.json", str(tmp_path)))
                      .read_text()) == {"a": 1, "b": [1, 2]}


# --------------------------------------------------------------------------- models


def test_log_model_loads_and_predicts_in_process(tracker, logged_model, fitted, data,
                                                 monkeypatch):
    import mlflow

    X, _ = data
    run_id, uri, seconds = logged_model
    assert uri.startswith("models:/m-")
    assert seconds < 30  # sanity bound only (about 0.2-0.7 s here)
    expected = fitted.predict(X)
    loaded = tracker.load_model(uri)
    pred = loaded.predict(X)
    assert list(pred.columns) == ["u", "v"]
    np.testing.assert_allclose(np.asarray(pred), expected.to_numpy())
    sig = loaded.metadata.signature
    assert sig is not None
    assert sig.inputs.input_names() == list(X.columns)
    assert sig.outputs.input_names() == ["u", "v"]
    # the usual MLflow route: tracking URI from the environment, models:/ and runs:/ URIs
    monkeypatch.setenv("MLFLOW_TRACKING_URI", tracker.tracking_uri)
    np.testing.assert_allclose(np.asarray(mlflow.pyfunc.load_model(uri).predict(X)),
                               expected.to_numpy())
    np.testing.assert_allclose(
        np.asarray(mlflow.pyfunc.load_model(f"runs:/{run_id}/model").predict(X)),
        expected.to_numpy())
    outputs = tracker.client.get_run(run_id).outputs.model_outputs
    assert [o.model_id for o in outputs] == [uri.removeprefix("models:/")]
    reqs = Path(tracker.model_artifact_uri(uri).removeprefix("file://"), "requirements.txt")
    assert "scikit-learn==" in reqs.read_text() and "workbench" not in reqs.read_text()


_FRESH = r"""
import importlib, importlib.util, json, sys
# Hide the editable install of the project: the model must bring its own workbench code.
sys.meta_path = [f for f in sys.meta_path if "editable" not in str(getattr(f, "__module__", ""))]
sys.path_hooks = [h for h in sys.path_hooks if "editable" not in str(getattr(h, "__module__", ""))]
sys.path = [p for p in sys.path if "__editable__" not in p]
importlib.invalidate_caches()
hidden = importlib.util.find_spec("workbench") is None
import mlflow, numpy as np, pandas as pd
model = mlflow.pyfunc.load_model(sys.argv[1])
X = pd.read_csv(sys.argv[2], index_col=0)
pred = model.predict(X)
import workbench
print(json.dumps({"hidden": hidden, "pred": np.asarray(pred).tolist(),
                  "columns": list(pred.columns), "workbench": workbench.__file__}))
"""


def test_log_model_loads_in_fresh_subprocess_without_the_project(tracker, logged_model, fitted,
                                                                 data, tmp_path):
    X, _ = data
    _, uri, _ = logged_model
    csv = tmp_path / "x.csv"
    X.to_csv(csv)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(MLFLOW_TRACKING_URI=tracker.tracking_uri, MLFLOW_DISABLE_TELEMETRY="true")
    out = subprocess.run([sys.executable, "-c", _FRESH, uri, str(csv)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["hidden"], "the project was importable in the subprocess"
    assert PROJECT not in Path(got["workbench"]).resolve().parents  # the model's own copy
    assert got["columns"] == ["u", "v"]
    np.testing.assert_allclose(np.array(got["pred"]), fitted.predict(X).to_numpy())


# --------------------------------------------------------------------------- errors


def test_corrupt_store_raises_and_is_left_untouched(tmp_path):
    db = tmp_path / "mlruns" / "mlflow.db"
    db.parent.mkdir()
    garbage = bytes(range(256)) * 16
    db.write_bytes(garbage)
    with pytest.raises(TrackingError, match="not a valid SQLite database") as info:
        Tracker(f"sqlite:///{db}", "x").experiment_id  # noqa: B018
    assert str(db) in str(info.value)
    assert db.read_bytes() == garbage
    assert sorted(p.name for p in db.parent.iterdir()) == ["mlflow.db"]


def test_locked_store_raises_tracking_error(tracker, root):
    """SQLite's connect timeout applies to a new store connection (``?timeout=`` in the URI);
    operations of an already open store wait MLflow's fixed 20 s busy timeout instead, too
    slow for a unit test."""
    db = root / "mlruns" / "mlflow.db"
    holder = sqlite3.connect(db, isolation_level=None)
    try:
        holder.execute("BEGIN EXCLUSIVE")
        start = time.perf_counter()
        with pytest.raises(TrackingError, match="locked") as info:
            Tracker(f"sqlite:///{db}?timeout=0.2", "tests").experiment_id  # noqa: B018
        assert time.perf_counter() - start < 10
        assert str(db) in str(info.value)
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert tracker.client.get_experiment(tracker.experiment_id).name == "tests"


def test_unreachable_server_fails_fast():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nothing listens once the socket is closed
    start = time.perf_counter()
    with pytest.raises(TrackingError, match=f"127.0.0.1:{port}"):
        Tracker(f"http://127.0.0.1:{port}", "x").experiment_id  # noqa: B018
    assert time.perf_counter() - start < 10


# --------------------------------------------------------------------------- provenance


def test_dataset_hash_stable_and_sensitive(data):
    X, Y = data
    h = dataset_hash(X, Y)
    assert len(h) == 64
    assert dataset_hash(X.copy(), Y.copy()) == h
    X2 = X.copy()
    X2.iloc[3, 1] += 1e-9
    assert dataset_hash(X2, Y) != h
    assert dataset_hash(Y, X) != h
    code = ("import sys, pandas as pd; "
            "from workbench.experiment.tracking.records import dataset_hash; "
            "print(dataset_hash(pd.DataFrame({'a': [1.0, 2.5], 'b': ['x', 'y']})))")
    other_process = subprocess.run([sys.executable, "-c", code], capture_output=True,
                                   text=True, check=True).stdout.strip()
    assert other_process == dataset_hash(pd.DataFrame({"a": [1.0, 2.5], "b": ["x", "y"]}))


def test_git_commit(tmp_path):
    sha = git_commit(PROJECT)
    assert sha is not None and len(sha) == 40 and all(c in "0123456789abcdef" for c in sha)
    assert git_commit(tmp_path) is None
    assert git_commit(tmp_path / "missing") is None
