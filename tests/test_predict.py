"""``workbench predict``, the logged pyfunc model, the registry round trip, serving with
``mlflow models serve``, and outputs that are checked before work and written all or nothing.

One ``evaluate --register`` on the Google benchmark (ridge basis, paper split) feeds the
module; its figures are skipped (they are tested elsewhere), so it takes a few seconds."""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import shutil
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import workbench._io
from workbench.experiment.cli import main
from workbench.experiment.families import Artifacts
from workbench.experiment.families.eigenvalue import EigenvalueFamily

from services import free_port, stop_process_group, wait_until_answering

ROOT = Path(__file__).resolve().parents[1]
TARGETS = [f"eeig{i}" for i in range(1, 6)]
NAME = "device"


def run_main(*argv) -> SimpleNamespace:
    """``main(argv)`` with its standard output and error captured."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in argv])
    return SimpleNamespace(rc=rc, out=out.getvalue(), err=err.getvalue())


def assert_one_line_error(res, *needles: str) -> str:
    """Exit code 2, no traceback, exactly one ``workbench: error:`` line (progress lines may
    precede it) containing every needle; returns the line."""
    assert res.rc == 2, (res.rc, res.err)
    assert "Traceback" not in res.err, res.err
    errors = [x for x in res.err.splitlines() if x.startswith("workbench: error:")]
    assert len(errors) == 1, res.err
    for needle in needles:
        assert needle in errors[0], (needle, errors[0])
    return errors[0]


def floats(frame: pd.DataFrame) -> np.ndarray:
    """Text cells parsed with Python's float (exact for what ``to_csv`` wrote)."""
    return frame.map(float).to_numpy()


def read_text_csv(path) -> pd.DataFrame:
    return pd.read_csv(path, dtype=str, keep_default_na=False)


class FullDisk:
    """``os`` for the atomic writer, with every fsync failing as on a full disk."""

    def __getattr__(self, name):
        return getattr(os, name)

    @staticmethod
    def fsync(fd):
        raise OSError(errno.ENOSPC, "No space left on device")


def _no_figures(self, *args, **kwargs):
    """``begin_artifacts`` of a family without its learning curves and SHAP figures:
    ``record`` calls it (not ``artifacts``), so nothing is fitted or drawn for them."""
    return lambda emit=None: Artifacts()


CONFIG = """\
name = "predict_test"
random_state = 0
[data]
source = "google_5q"
data_dir = {data_dir}
[model]
basis = "ridge"
[tracking]
experiment = "predict_test"
"""


def write_config(directory: Path, data_dir: Path) -> Path:
    path = directory / "bench.toml"
    path.write_text(CONFIG.format(data_dir=json.dumps(str(data_dir))))
    return path


@contextlib.contextmanager
def read_only_directory(path: Path):
    """``path`` made unwritable for this process: ``chmod`` for a normal user; as root (who
    ignores permissions) the immutable attribute (``chattr +i``); skips when neither works."""
    path.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        path.chmod(0o555)
        undo = lambda: path.chmod(0o755)  # noqa: E731
    else:
        if shutil.which("chattr") is None or subprocess.run(
                ["chattr", "+i", str(path)], capture_output=True).returncode != 0:
            pytest.skip("running as root and cannot make a directory immutable (chattr +i): "
                        "no read-only directory to test with")
        undo = lambda: subprocess.run(["chattr", "-i", str(path)], check=True)  # noqa: E731
    try:
        probe = path / "probe"
        try:
            probe.write_text("x")
        except OSError:
            pass
        else:
            probe.unlink()
            pytest.skip(f"{path} stayed writable")
        yield path
    finally:
        undo()


# --------------------------------------------------------------------------- the logged model


class IntervalModel:
    """Two targets (``a + b``, ``a - b``) with symmetric intervals; ``kind`` picks the form
    ``predict_interval`` returns."""

    def __init__(self, kind="pair", half=0.5):
        self.kind, self.half = kind, half

    def predict(self, X):
        return pd.DataFrame({"u": X["a"] + X["b"], "v": X["a"] - X["b"]}, index=X.index)

    def predict_interval(self, X):
        p = self.predict(X).to_numpy()
        lo, hi = p - self.half, p + self.half
        if self.kind == "pair":
            return lo, hi
        if self.kind == "array":
            return np.stack([lo, hi], axis=-1)
        return pd.DataFrame({"v_upper": hi[:, 1], "u_lower": lo[:, 0], "u_upper": hi[:, 0],
                             "v_lower": lo[:, 1]}, index=X.index)


@pytest.mark.parametrize("kind", ["pair", "array", "frame"])
def test_prediction_frame_adds_interval_columns(kind):
    from workbench.experiment.tracking.serving import prediction_frame

    X = pd.DataFrame({"a": [1.0, 2.0], "b": [0.5, 0.0]}, index=[10, 11])
    out = prediction_frame(IntervalModel(kind), X, ["u", "v"])
    assert list(out.columns) == ["u", "v", "u_lower", "u_upper", "v_lower", "v_upper"]
    assert list(out.index) == [10, 11]
    np.testing.assert_array_equal(out["u_lower"], [1.0, 1.5])
    np.testing.assert_array_equal(out["v_upper"], [1.0, 2.5])


def test_check_inputs_names_the_problem_in_one_line():
    from workbench.experiment.tracking.serving import InputError, check_inputs

    X = pd.DataFrame({"id": ["p", "q"], "b": [1, 2], "a": [0.5, 1.5]}, index=[7, 8])
    got = check_inputs(X, ["a", "b"])
    assert list(got.columns) == ["a", "b"] and got.dtypes.tolist() == [float, float]
    assert got.loc[8].tolist() == [1.5, 2.0]
    text = X.assign(a=["0.1", "2.5e3"])  # text that holds numbers: parsed exactly
    assert check_inputs(text, ["a"])["a"].tolist() == [0.1, 2500.0]
    for frame, needle in [
            (X.drop(columns="a"), "input: missing column(s) a (the model reads 2 columns: a, b)"),
            (X.assign(a=[0.5, np.nan]), "input: column 'a' has a missing or NaN value at row 8"),
            (X.assign(b=[np.inf, 1]), "input: column 'b' has an infinite value (inf) at row 7"),
            (X.assign(a=[0.5, "x"]), "input: column 'a' has a non-numeric value 'x' at row 8"),
            (X.assign(a=[True, False]), "input: column 'a' has a non-numeric value True at row 7")]:
        with pytest.raises(InputError) as err:
            check_inputs(frame, ["a", "b"])
        assert str(err.value) == needle


@pytest.fixture(scope="module")
def logged_interval_model(bench):
    from workbench.experiment.tracking.runs import Tracker

    tracker = Tracker(bench.uri, "pyfunc")  # the module's store (created once)
    X = pd.DataFrame({"a": [1.0, 2.0, 3.0], "b": [0.5, 0.25, 0.0]})
    with tracker.run("interval model") as run_id:
        uri = tracker.log_model(run_id, IntervalModel(), X)
    return tracker, uri, X


def test_logged_model_returns_intervals_and_checks_inputs_in_one_line(logged_interval_model):
    from mlflow.exceptions import MlflowException

    tracker, uri, X = logged_interval_model
    model = tracker.load_model(uri)
    sig = model.metadata.signature
    assert sig.inputs.input_names() == ["a", "b"]
    assert sig.outputs.input_names() == ["u", "v", "u_lower", "u_upper", "v_lower", "v_upper"]
    pred = model.predict(X)
    np.testing.assert_array_equal(pred["u_upper"], (X["a"] + X["b"] + 0.5).to_numpy())
    # integer columns are accepted; extra columns ignored
    ints = pd.DataFrame({"id": ["x", "y"], "a": [1, 2], "b": [3, 4]})
    np.testing.assert_array_equal(model.predict(ints)["v"], [-2.0, -2.0])
    big = pd.DataFrame({"a": np.arange(5000.0)})  # MLflow's own check would print the table
    with pytest.raises(MlflowException) as err:
        model.predict(big)
    message = str(err.value)
    assert message == ("model input: missing column(s) b (the model reads 2 columns: a, b)")
    with pytest.raises(MlflowException, match=r"^model input: column 'b' has a missing or NaN "
                                              r"value at row 1$"):
        model.predict(pd.DataFrame({"a": [1.0, 2.0], "b": [0.0, None]}))
    # the input example is the REST request's template
    example = json.loads(Path(tracker.model_artifact_uri(uri).removeprefix("file://"),
                              "serving_input_example.json").read_text())
    assert example["dataframe_split"]["columns"] == ["a", "b"]


# --------------------------------------------------------------------------- the module's run


@pytest.fixture(scope="module")
def bench(google_5q_dir, tmp_path_factory, new_store):
    """``evaluate --register device`` on the benchmark, the test rows as a CSV (an id column,
    the measured targets, the model's inputs in another order) and evaluate's own test
    predictions (the run's ``predictions/test.csv``)."""
    from mlflow import MlflowClient

    from workbench.datasets import load_google_5q

    root = tmp_path_factory.mktemp("predict")
    uri = new_store(root / "mlruns" / "mlflow.db")
    config = write_config(root, google_5q_dir)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(EigenvalueFamily, "begin_artifacts", _no_figures)
        res = run_main("evaluate", config, "--tracking-uri", uri, "--register", NAME,
                       "--json", root / "eval.json")
    assert res.rc == 0, res.err
    assert f"registered {NAME} version 1 (models:/{NAME}@champion)" in res.out
    result = json.loads((root / "eval.json").read_text())
    client = MlflowClient(uri)
    run_id = result["mlflow"]["run_id"]
    logged = read_text_csv(client.download_artifacts(run_id, "predictions/test.csv",
                                                     str(root)))
    ds = load_google_5q(google_5q_dir)
    rows = ds.test_index
    table = pd.concat([ds.targets.loc[rows], ds.X.loc[rows].iloc[:, ::-1]], axis=1)
    table.insert(0, "id", [f"exp-{i:03d}" for i in rows])
    csv = root / "test_rows.csv"
    table.to_csv(csv, index=False)
    assert logged["row"].astype(int).tolist() == list(rows)
    return SimpleNamespace(root=root, uri=uri, config=config, result=result, run_id=run_id,
                           client=client, expected=floats(logged[TARGETS]), table=table,
                           logged=logged,
                           csv=csv, dataset=ds)


def predict(bench, model, csv, out):
    return run_main("predict", model, csv, "--out", out, "--tracking-uri", bench.uri)


def test_champion_reproduces_evaluate_test_predictions_exactly(bench, tmp_path):
    out = tmp_path / "sub" / "predictions.csv"
    res = predict(bench, f"models:/{NAME}@champion", bench.csv, out)
    assert res.rc == 0, res.err
    assert f"wrote {out} (41 rows: {', '.join(TARGETS)} with intervals)" in res.out
    got = read_text_csv(out)
    # passed through first (the id with its row; measured targets renamed), then predictions
    # and the conformal intervals ([intervals] is on by default), as evaluate logged them
    bounds = [f"{t}_{side}" for t in TARGETS for side in ("lower", "upper")]
    assert list(got.columns[:11]) == ["id", *[f"{t}_input" for t in TARGETS], *TARGETS]
    assert sorted(got.columns[11:]) == sorted(bounds)
    np.testing.assert_array_equal(floats(got[bounds]), floats(bench.logged[bounds]))
    assert (floats(got[[f"{t}_lower" for t in TARGETS]])
            < floats(got[TARGETS])).all()
    assert got["id"].tolist() == bench.table["id"].tolist()
    np.testing.assert_array_equal(floats(got[TARGETS]), bench.expected)
    # ... which are evaluate's: its test MAE from them, to the last bit
    measured = bench.dataset.targets.loc[bench.dataset.test_index].to_numpy()
    mae = np.mean(np.abs(floats(got[TARGETS]) - measured), axis=0)
    assert mae.tolist() == pytest.approx(bench.result["model"]["test_mae"], rel=1e-12)
    assert sorted(p.name for p in out.parent.iterdir()) == ["predictions.csv"]


def test_every_way_to_name_the_model_gives_the_same_table(bench, tmp_path):
    model_id = bench.result["mlflow"]["model_uri"].removeprefix("models:/")
    first = None
    for i, spec in enumerate([bench.run_id, f"runs:/{bench.run_id}/model", f"models:/{NAME}/1",
                              f"models:/{model_id}"]):
        out = tmp_path / f"p{i}.csv"
        res = predict(bench, spec, bench.csv, out)
        assert res.rc == 0, (spec, res.err)
        first = first or out.read_bytes()
        assert out.read_bytes() == first, spec


def test_registered_version_carries_config_dataset_and_metrics(bench):
    client = bench.client
    version = client.get_model_version_by_alias(NAME, "champion")
    assert str(version.version) == "1" and version.run_id == bench.run_id
    tags = version.tags
    run = client.get_run(bench.run_id)
    assert tags["dataset_hash"] == run.data.tags["dataset_hash"] and len(tags["dataset_hash"]) == 64
    assert tags["config"] == str(bench.config) and tags["config_name"] == "predict_test"
    assert float(tags["test_mae_avg"]) == pytest.approx(bench.result["model"]["test_mae_avg"],
                                                        rel=1e-5)
    assert run.data.metrics["test_mae_avg"] == pytest.approx(
        bench.result["model"]["test_mae_avg"])
    # the config travels with the model
    model_dir = Path(version.source.removeprefix("file://"))
    assert (model_dir / "config.toml").read_text() == bench.config.read_text()
    assert run.data.tags["registered_model"] == f"{NAME}/1"


def test_a_new_registration_moves_the_champion_alias(bench):
    from workbench.experiment.tracking.runs import Tracker

    tracker = Tracker(bench.uri, "predict_test")
    version = tracker.register_model(bench.result["mlflow"]["model_uri"], NAME,
                                     run_id=bench.run_id, tags={"note": "again"})
    assert version == "2"
    assert str(bench.client.get_model_version_by_alias(NAME, "champion").version) == "2"
    assert {k: str(v) for k, v in bench.client.get_registered_model(NAME).aliases.items()} \
        == {"champion": "2"}
    tracker.client.set_registered_model_alias(NAME, "champion", "1")  # as the module had it


def test_runs_record_dataset_inputs_source_and_a_model_training_experiment(bench):
    run = bench.client.get_run(bench.run_id)
    inputs = run.inputs.dataset_inputs
    contexts = sorted(t.value for d in inputs for t in d.tags if t.key == "mlflow.data.context")
    assert contexts == ["test", "training"]
    for d in inputs:
        assert d.dataset.name == "google_5q" and d.dataset.digest
        schema = json.loads(d.dataset.schema)["mlflow_colspec"]
        assert {c["name"] for c in schema} >= {"peig1", "qvolt5", "eeig1"}
    tags = run.data.tags
    assert tags["mlflow.source.type"] == "LOCAL"
    assert tags["mlflow.source.name"] == f"workbench evaluate {bench.config}"
    assert tags["mlflow.source.git.commit"] == tags["git_commit"]
    experiment = bench.client.get_experiment(run.info.experiment_id)
    assert experiment.tags["mlflow.experimentKind"] == "custom_model_development"
    assert run.info.status == "FINISHED"


def test_sweep_register_then_predict_the_test_rows(bench, tmp_path, monkeypatch):
    """``sweep --register``: the chosen model is the champion, and ``predict`` on the CSV's
    test rows gives the sweep's test predictions exactly (a CSV dataset, a small sweep)."""
    from mlflow import MlflowClient

    from workbench.experiment.sweep import report as sweep_report

    from services import tiny_sweep

    config = tiny_sweep(tmp_path, trials=2)
    monkeypatch.chdir(tmp_path)
    uri = bench.uri  # the module's store (created once)
    monkeypatch.setattr(EigenvalueFamily, "begin_artifacts", _no_figures)
    # nor the studies' Optuna figures (drawn on the command's workers; checked by
    # test_sweep.py's tracked smoke sweep): the registered model is the check here
    monkeypatch.setattr(sweep_report, "figures_of_sweep", lambda *args, **kwargs: None)
    res = run_main("sweep", config, "--tracking-uri", uri, "--register", "tiny")
    assert res.rc == 0, res.err
    assert "registered tiny version 1 (models:/tiny@champion)" in res.out
    client = MlflowClient(uri)
    version = client.get_model_version_by_alias("tiny", "champion")
    assert version.tags["workbench.kind"] == "sweep"
    logged = read_text_csv(client.download_artifacts(version.run_id, "predictions/test.csv",
                                                     str(tmp_path)))
    rows = read_text_csv(tmp_path / "sim.csv").iloc[logged["row"].astype(int)]
    rows.to_csv(tmp_path / "test_rows.csv", index=False)
    res = run_main("predict", "models:/tiny@champion", tmp_path / "test_rows.csv", "--out",
                   tmp_path / "p.csv", "--tracking-uri", uri)
    assert res.rc == 0, res.err
    got = read_text_csv(tmp_path / "p.csv")
    np.testing.assert_array_equal(floats(got[["measured_E1"]]), floats(logged[["measured_E1"]]))
    assert got["measured_E1_input"].tolist() == rows["measured_E1"].tolist()


@pytest.mark.slow
@pytest.mark.parametrize("config", ["paper_main_body.toml", "hamiltonian.toml"])
def test_shipped_configs_predict_reproduces_evaluate(config, google_5q_dir, tmp_path,
                                                     monkeypatch):
    """The paper's settings and the parameter-space model (its own, wider inputs): register,
    then ``predict`` on the benchmark's test rows gives evaluate's test predictions."""
    from mlflow import MlflowClient

    from workbench.datasets import load_google_5q

    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    res = run_main("evaluate", ROOT / "experiments" / config, "--tracking-uri", uri,
                   "--register", "shipped", "--json", tmp_path / "r.json")
    assert res.rc == 0, res.err
    run_id = json.loads((tmp_path / "r.json").read_text())["mlflow"]["run_id"]
    logged = read_text_csv(MlflowClient(uri).download_artifacts(run_id, "predictions/test.csv",
                                                                str(tmp_path)))
    ds = load_google_5q(google_5q_dir)
    X = pd.concat([ds.X_physics, ds.targets], axis=1).loc[ds.test_index]
    X.to_csv(tmp_path / "test_rows.csv", index=False)
    res = run_main("predict", "models:/shipped@champion", tmp_path / "test_rows.csv", "--out",
                   tmp_path / "p.csv", "--tracking-uri", uri)
    assert res.rc == 0, res.err
    got = read_text_csv(tmp_path / "p.csv")
    np.testing.assert_array_equal(floats(got[TARGETS]), floats(logged[TARGETS]))


def test_an_existing_experiment_becomes_a_model_training_one(bench):
    from mlflow import MlflowClient

    from workbench.experiment.tracking.runs import Tracker

    uri = bench.uri  # the module's store (created once)
    client = MlflowClient(uri)
    old = client.create_experiment("made elsewhere")
    assert "mlflow.experimentKind" not in client.get_experiment(old).tags
    assert Tracker(uri, "made elsewhere").experiment_id == old
    assert client.get_experiment(old).tags["mlflow.experimentKind"] == "custom_model_development"
    client.set_experiment_tag(old, "mlflow.experimentKind", "genai_development")
    Tracker(uri, "made elsewhere").experiment_id  # noqa: B018 - a user's choice is kept
    assert client.get_experiment(old).tags["mlflow.experimentKind"] == "genai_development"


def test_register_without_tracking_or_with_a_bad_name_is_one_line(google_5q_dir, tmp_path):
    config = write_config(tmp_path, google_5q_dir)
    res = run_main("evaluate", config, "--no-track", "--register", "x")
    assert_one_line_error(res, "--register needs the tracking store")
    assert "fitting" not in res.err
    for bad in ("a/b", "dev@champion", " x", ""):
        res = run_main("evaluate", config, "--tracking-uri", f"sqlite:///{tmp_path}/m.db",
                       "--register", bad)
        assert_one_line_error(res, f"--register {bad!r}: a registered model's name cannot")
        assert "fitting" not in res.err and not (tmp_path / "m.db").exists()


# --------------------------------------------------------------------------- bad input


def _bad(table: pd.DataFrame, case: str) -> tuple[pd.DataFrame, tuple[str, ...]]:
    t = table.astype(str)
    if case == "missing column":
        return t.drop(columns=["peig3", "qvolt7"]), ("missing column(s) qvolt7, peig3",)
    if case == "empty cell":
        t.loc[t.index[3], "qvolt6"] = ""
        return t, ("column 'qvolt6' has a missing or NaN value at line 5",)
    if case == "NaN":
        t.loc[t.index[0], "peig2"] = "nan"
        return t, ("column 'peig2' has a missing or NaN value at line 2",)
    if case == "infinite":
        t.loc[t.index[40], "cvolt5"] = "-inf"
        return t, ("column 'cvolt5' has an infinite value (-inf) at line 42",)
    if case == "non-numeric":
        t.loc[t.index[7], "peig1"] = "12,5"
        return t, ("column 'peig1' has a non-numeric value '12,5' at line 9",)
    raise ValueError(case)


@pytest.mark.parametrize("case", ["missing column", "empty cell", "NaN", "infinite",
                                  "non-numeric"])
def test_bad_rows_end_with_one_line_naming_column_and_line(bench, tmp_path, case):
    table, needles = _bad(bench.table, case)
    csv = tmp_path / "in.csv"
    table.to_csv(csv, index=False)
    out = tmp_path / "out" / "p.csv"
    res = predict(bench, f"models:/{NAME}@champion", csv, out)
    assert_one_line_error(res, str(csv), *needles)
    assert not out.parent.exists()  # nothing written, not even the directory


def test_integer_columns_are_accepted(bench, tmp_path):
    table = bench.table.copy()
    table["peig3"] = np.round(table["peig3"]).astype(int)
    as_int, as_float = tmp_path / "int.csv", tmp_path / "float.csv"
    table.to_csv(as_int, index=False)
    table.assign(peig3=table["peig3"].astype(float)).to_csv(as_float, index=False)
    assert read_text_csv(as_int)["peig3"].str.fullmatch(r"-?\d+").all()  # written as integers
    for path in (as_int, as_float):
        assert predict(bench, f"models:/{NAME}@champion", path, path.with_suffix(".out")).rc == 0
    got = [floats(read_text_csv(p.with_suffix(".out"))[TARGETS]) for p in (as_int, as_float)]
    np.testing.assert_array_equal(got[0], got[1])
    assert not np.array_equal(got[0], bench.expected)  # the rounding did change the input


@pytest.mark.parametrize("spec, needles", [
    ("models:/nobody@champion", ("not found in SQLite database",)),
    (f"models:/{NAME}@nobody", ("not found", "nobody")),
    (f"models:/{NAME}/99", ("not found",)),
    ("0" * 32, ("not found",)),
    ("model.pkl", ("expected a run id, runs:/<run_id>/<name>, models:/NAME/VERSION",)),
])
def test_a_model_that_is_not_there_is_one_line(bench, tmp_path, spec, needles):
    res = predict(bench, spec, bench.csv, tmp_path / "p.csv")
    assert_one_line_error(res, *needles)
    assert not (tmp_path / "p.csv").exists()


def test_a_missing_csv_or_store_is_one_line(bench, tmp_path):
    assert_one_line_error(predict(bench, f"models:/{NAME}@champion", tmp_path / "none.csv",
                                  tmp_path / "p.csv"), "CSV file not found")
    res = run_main("predict", f"models:/{NAME}@champion", bench.csv, "--out", tmp_path / "p.csv",
                   "--tracking-uri", f"sqlite:///{tmp_path}/none.db")
    assert_one_line_error(res, "no MLflow store at")
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no store was created


# --------------------------------------------------------------------------- outputs


def test_predict_out_that_cannot_be_written_fails_before_loading(bench, tmp_path):
    (tmp_path / "a_dir").mkdir()
    (tmp_path / "a_file").write_text("keep")
    cases = [(tmp_path / "a_dir", "is a directory"),
             (tmp_path / "a_file" / "p.csv", "a_file is a file, not a directory")]
    for out, needle in cases:
        res = predict(bench, f"models:/{NAME}@champion", bench.csv, out)
        assert_one_line_error(res, "--out", needle)
        assert "predicting" not in res.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_dir", "a_file"]
    assert not any((tmp_path / "a_dir").iterdir()) and (tmp_path / "a_file").read_text() == "keep"


def test_predict_into_a_read_only_directory(bench, tmp_path):
    with read_only_directory(tmp_path / "ro") as ro:
        res = predict(bench, f"models:/{NAME}@champion", bench.csv, ro / "p.csv")
        assert_one_line_error(res, "--out", "cannot write in")
        assert not any(ro.iterdir())


def test_predict_on_a_full_disk_keeps_the_old_file_and_leaves_no_temporary(bench, tmp_path,
                                                                          monkeypatch):
    out = tmp_path / "p.csv"
    out.write_text("old")
    monkeypatch.setattr(workbench._io, "os", FullDisk())
    res = predict(bench, f"models:/{NAME}@champion", bench.csv, out)
    assert_one_line_error(res, f"--out {out}: cannot write: No space left on device")
    assert out.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["p.csv"]


@pytest.fixture()
def fresh_store(tmp_path):
    path = tmp_path / "store" / "mlflow.db"
    return path, f"sqlite:///{path}"


@pytest.mark.parametrize("case", ["json is a directory", "json under a file", "out is a file"])
def test_evaluate_outputs_are_checked_before_anything_runs(google_5q_dir, tmp_path, fresh_store,
                                                            case, monkeypatch):
    db, uri = fresh_store
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    (tmp_path / "dir").mkdir()
    (tmp_path / "file").write_text("keep")
    config, extra, needle = write_config(tmp_path, google_5q_dir), [], ""
    if case == "json is a directory":
        extra, needle = ["--json", tmp_path / "dir"], "--json"
    elif case == "json under a file":
        extra, needle = ["--json", tmp_path / "file" / "r.json"], "file is a file"
    else:  # a family that writes tables (hamiltonian), --out onto a file
        config = ROOT / "experiments" / "hamiltonian.toml"
        extra, needle = ["--out", tmp_path / "file"], "--out"
    res = run_main("evaluate", config, "--tracking-uri", uri, *extra)
    assert_one_line_error(res, needle)
    assert "fitting" not in res.err and not db.exists()  # nothing fitted, no run created
    assert not any((tmp_path / "dir").iterdir()) and (tmp_path / "file").read_text() == "keep"


def test_evaluate_json_into_a_read_only_directory(google_5q_dir, tmp_path, fresh_store):
    db, uri = fresh_store
    config = write_config(tmp_path, google_5q_dir)
    with read_only_directory(tmp_path / "ro") as ro:
        res = run_main("evaluate", config, "--tracking-uri", uri, "--json", ro / "r.json")
        assert_one_line_error(res, "--json", "cannot write in")
        assert "fitting" not in res.err and not db.exists() and not any(ro.iterdir())


def test_evaluate_on_a_full_disk_leaves_nothing_and_the_run_failed(google_5q_dir, tmp_path,
                                                                   fresh_store, monkeypatch):
    """The JSON is written inside the run: a full disk ends the command with one line, leaves
    no file and no temporary, and the MLflow run is FAILED, never FINISHED."""
    from mlflow import MlflowClient

    _, uri = fresh_store
    config = write_config(tmp_path, google_5q_dir)
    monkeypatch.setattr(EigenvalueFamily, "begin_artifacts", _no_figures)
    monkeypatch.setattr(workbench._io, "os", FullDisk())
    out = tmp_path / "results" / "r.json"
    res = run_main("evaluate", config, "--tracking-uri", uri, "--json", out)
    assert_one_line_error(res, f"--json {out}: cannot write: No space left on device")
    assert "fitting" in res.err  # it failed after the fit, at the write
    assert not out.parent.exists() or not any(out.parent.iterdir())
    client = MlflowClient(uri)
    runs = client.search_runs([client.get_experiment_by_name("predict_test").experiment_id])
    assert [r.info.status for r in runs] == ["FAILED"]


def test_out_tables_are_written_all_or_nothing(tmp_path, monkeypatch):
    from workbench.experiment.process.outputs import OutputError, write_artifacts

    tables = Artifacts(tables={"a": pd.DataFrame({"x": [1.0]}), "b": pd.DataFrame({"y": [2.0]})})
    calls = []
    real = os.fsync

    class SecondWriteFails(FullDisk):
        @staticmethod
        def fsync(fd):
            calls.append(fd)
            if len(calls) == 2:
                raise OSError(errno.ENOSPC, "No space left on device")
            return real(fd)

    monkeypatch.setattr(workbench._io, "os", SecondWriteFails())
    with pytest.raises(OutputError, match="No space left on device"):
        write_artifacts(tables, tmp_path / "new" / "out")
    assert not (tmp_path / "new").exists()  # the directories it made are gone too
    existing = tmp_path / "old"
    existing.mkdir()
    (existing / "a.csv").write_text("old a")
    calls.clear()
    with pytest.raises(OutputError):
        write_artifacts(tables, existing)
    assert [p.name for p in existing.iterdir()] == ["a.csv"]
    assert (existing / "a.csv").read_text() == "old a"
    monkeypatch.setattr(workbench._io, "os", os)
    written = write_artifacts(tables, existing)
    assert sorted(p.name for p in existing.iterdir()) == ["a.csv", "b.csv"]
    assert written["a"].read_text() == "x\n1.0\n"


# --------------------------------------------------------------------------- serving


def test_served_model_gives_the_same_numbers(bench, tmp_path):
    """``mlflow models serve`` on the champion (a real process on 127.0.0.1): the test rows
    as ``dataframe_split`` give evaluate's test predictions; a missing column is one line, a
    request without rows a short answer."""
    port = free_port()
    bindir = str(Path(sys.executable).parent)  # mlflow execs uvicorn from PATH
    env = dict(os.environ, MLFLOW_TRACKING_URI=bench.uri, MLFLOW_DISABLE_TELEMETRY="true",
               PATH=bindir + os.pathsep + os.environ.get("PATH", ""))
    log = open(tmp_path / "serve.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "mlflow", "models", "serve", "-m",
                             f"models:/{NAME}@champion", "--env-manager", "local",
                             "-h", "127.0.0.1", "-p", str(port)],
                            stdout=log, stderr=subprocess.STDOUT, env=env,
                            start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        took = wait_until_answering(f"{base}/ping", proc, tmp_path / "serve.log", 180)
        print(f"\nmlflow models serve answered after {took:.1f} s")
        X = bench.table.drop(columns=["id", *TARGETS])
        body = {"dataframe_split": {"columns": list(X.columns), "data": X.to_numpy().tolist()}}
        status, reply = _post(f"{base}/invocations", body)
        assert status == 200, reply
        served = pd.DataFrame(reply["predictions"])
        bounds = [f"{t}_{side}" for t in TARGETS for side in ("lower", "upper")]
        assert list(served.columns[:5]) == TARGETS and sorted(served.columns[5:]) == sorted(bounds)
        np.testing.assert_array_equal(served[TARGETS].to_numpy(), bench.expected)
        np.testing.assert_array_equal(served[bounds].to_numpy(), floats(bench.logged[bounds]))
        columns = body["dataframe_split"]["columns"]
        columns[columns.index("qvolt5")] = "renamed"
        status, reply = _post(f"{base}/invocations", body)
        assert status == 400 and "missing column(s) qvolt5" in reply["message"]
        body["dataframe_split"]["data"] = []  # no rows: a short answer, no stack trace
        status, reply = _post(f"{base}/invocations", body)
        assert status == 400 and "model input: no rows to predict" in reply["message"]
        assert "stack_trace" not in reply and len(json.dumps(reply)) < 500, reply
    finally:
        stop_process_group(proc)
        log.close()


def _post(url: str, body: dict) -> tuple[int, dict]:
    request = urllib.request.Request(url, data=json.dumps(body).encode(),
                                     headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=60) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())
