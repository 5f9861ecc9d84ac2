"""workbench.experiment.tracking.compare: two runs' test errors side by side, on a real MLflow
store."""

import numpy as np
import pandas as pd
import pytest
from mlflow import MlflowClient

from workbench.experiment.process.errors import UsageError
from workbench.experiment.scoring.bootstrap import bootstrap_error_interval
from workbench.experiment.tracking.compare import (
    MEASURED,
    PREDICTIONS,
    compare_runs,
    format_comparison,
)

ROWS = [3, 5, 8, 13, 21, 34]


@pytest.fixture()
def client(tmp_path, new_store):
    client = MlflowClient(new_store(tmp_path / "mlflow.db"))
    client.create_experiment("x", artifact_location=(tmp_path / "artifacts").as_uri())
    return client


def _run(client, name, predicted, measured=None, rows=ROWS):
    exp = client.get_experiment_by_name("x").experiment_id
    run = client.create_run(exp, run_name=name)
    frame = pd.DataFrame(predicted, index=pd.Index(rows, name="row"), columns=["y1", "y2"])
    client.log_text(run.info.run_id, frame.to_csv(index_label="row"), PREDICTIONS)
    if measured is not None:
        truth = pd.DataFrame(measured, index=frame.index, columns=["y1", "y2"])
        client.log_text(run.info.run_id, truth.to_csv(index_label="row"), MEASURED)
    client.set_terminated(run.info.run_id)
    return run.info.run_id


def test_paired_interval_by_name_and_id(client):
    rng = np.random.default_rng(0)
    y = rng.normal(size=(6, 2))
    pa, pb = y + 0.1 * rng.normal(size=(6, 2)), y + rng.normal(size=(6, 2))
    id_a = _run(client, "good", pa, y)
    _run(client, "bad", pb, y)
    c = compare_runs(client, "good", "bad")
    assert c.runs == ("good", "bad") and c.run_ids[0] == id_a and c.n_rows == 6
    np.testing.assert_allclose(c.mae_a, np.abs(y - pa).mean(axis=0))
    expected = bootstrap_error_interval(y - pa, baseline=y - pb)
    assert c.diff_ci == [*expected.per_target, expected.average]
    assert compare_runs(client, id_a, "bad").diff_ci == c.diff_ci
    text = format_comparison(c, unit="MHz")
    assert "test MAE on 6 rows, MHz: a = good, b = bad" in text
    assert text.splitlines()[-1].startswith("average")


def test_errors_name_the_problem(client):
    y = np.zeros((6, 2))
    _run(client, "twin", y, y)
    _run(client, "twin", y, y)
    _run(client, "old", y)  # no measured targets logged
    _run(client, "other rows", y, y, rows=[1, 2, 3, 4, 5, 6])
    _run(client, "one", y, y)
    with pytest.raises(UsageError, match="2 runs are named 'twin' .*: give a run id"):
        compare_runs(client, "twin", "one")
    with pytest.raises(UsageError, match="no run with the id or name 'nope'"):
        compare_runs(client, "nope", "one")
    with pytest.raises(UsageError, match="run old has no predictions/test_measured.csv"):
        compare_runs(client, "old", "one")
    with pytest.raises(UsageError, match="different test rows"):
        compare_runs(client, "other rows", "one")


def test_command_prints_the_table(client, tmp_path, capsys):
    from workbench.experiment.cli import main

    y = np.arange(12.0).reshape(6, 2)
    _run(client, "a", y + 0.5, y)
    _run(client, "b", y + 1.0, y)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    assert main(["compare", "a", "b", "--tracking-uri", uri]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("test MAE on 6 rows: a = a, b = b")
    assert lines[-1].split()[:4] == ["average", "0.500", "1.000", "-0.500"]
    assert main(["compare", "a", "nope", "--tracking-uri", uri]) == 2
    assert "no run with the id or name 'nope'" in capsys.readouterr().err
