"""A run's figures, tables and predictions are computed once, before the record; the MLflow
record logs them and computes nothing (issue 32)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure
from mlflow import MlflowClient

from workbench.experiment import figures
from workbench.experiment.families import Artifacts
from workbench.experiment.families.eigenvalue import EigenvalueFamily
from workbench.experiment.runs import intervals, run_outputs
from workbench.experiment.runs.evaluate import evaluate
from workbench.experiment.runs.prepare import load_config
from workbench.experiment.runs.record import record
from workbench.experiment.runs.run_outputs import computed_outputs
from workbench.experiment.tracking import serving


def _config(tmp_path: Path) -> object:
    """A small CSV (48 rows, 2 targets), ridge stages, intervals on ("oof")."""
    rng = np.random.default_rng(0)
    n = 48
    f = rng.normal(size=(n, 2))
    prior = rng.normal(size=(n, 2)) * 3
    y = prior + 0.5 * f[:, [0]] - 0.3 * f[:, [1]] ** 2 + rng.normal(scale=0.1, size=(n, 2))
    pd.DataFrame({"f1": f[:, 0], "f2": f[:, 1], "p1": prior[:, 0], "p2": prior[:, 1],
                  "y1": y[:, 0], "y2": y[:, 1]}).to_csv(tmp_path / "data.csv", index=False)
    (tmp_path / "c.toml").write_text(
        'name = "computed"\nrandom_state = 0\nn_jobs = 1\n[data]\ncsv = "data.csv"\n'
        'prior = ["p1", "p2"]\ntargets = ["y1", "y2"]\nfeatures = ["f1", "f2"]\n'
        'test_fraction = 0.25\n[model]\nbasis = "ridge"\n')
    return load_config(tmp_path / "c.toml")


class Calls:
    """Counts the calls of the functions that compute a run's outputs."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}

    def counted(self, name: str, fn):
        def wrapper(*args, **kwargs):
            self.counts[name] = self.counts.get(name, 0) + 1
            return fn(*args, **kwargs)

        return wrapper


def _run_figures(self, cfg, ds, model, setting, quick=False):
    """The eigenvalue family's run figures, cheap: a figure, a table and data per target."""
    def finish(emit=None):
        fig = Figure()
        fig.add_subplot().plot([0, 1], [1, 0])
        return Artifacts(figures={"curve_y1": fig},
                         tables={"curve_table": pd.DataFrame({"size": [10, 20]})},
                         data={"learning_curves": {"y1": [1.0, 0.5]}})

    return finish


def _forbidden(name: str):
    def raises(*args, **kwargs):
        raise AssertionError(f"the record computed: {name}")

    return raises


#: Every function that computes a run's figures, tables or predictions, by where the
#: experiment layer looks it up.
COMPUTING = [(run_outputs, "compute_outputs"), (run_outputs, "interval_artifacts"),
             (run_outputs, "error_bars"), (run_outputs, "_png"),
             (run_outputs, "write_artifacts"), (intervals, "interval_artifacts"),
             (intervals, "interval_figure"), (figures, "mae_bars"), (figures, "error_bars"),
             (figures, "save_figure"),
             (serving, "prediction_frame"), (EigenvalueFamily, "begin_artifacts"),
             (EigenvalueFamily, "outputs"), (Figure, "__init__"), (Figure, "savefig")]


@pytest.fixture
def fitted(tmp_path, monkeypatch):
    monkeypatch.setattr(EigenvalueFamily, "begin_artifacts", _run_figures)
    cfg = _config(tmp_path)
    return cfg, evaluate(cfg, return_model=True)


def test_the_record_computes_nothing(fitted, tmp_path, monkeypatch, new_store):
    """Each output is computed once, before the record; with every computing function
    raising, the record still logs every figure (as the files computed), table, data and
    prediction."""
    cfg, run = fitted
    calls = Calls()
    for owner, name in [(run_outputs, "interval_artifacts"), (run_outputs, "error_bars"),
                        (run_outputs, "_png"), (serving, "prediction_frame"),
                        (EigenvalueFamily, "begin_artifacts")]:
        monkeypatch.setattr(owner, name, calls.counted(name, getattr(owner, name)))
    with computed_outputs(cfg, run.result, run.model, run.dataset,
                          setting="evaluate of computed") as computed:
        assert calls.counts == {"interval_artifacts": 1, "error_bars": 2, "begin_artifacts": 1,
                                "prediction_frame": 1, "_png": 4}
        assert set(computed.files) == set(computed.figures) == {
            "plots/mae_bars.png", "plots/mse_bars.png", "plots/intervals.png",
            "plots/curve_y1.png"}
        assert all(p.is_file() for p in computed.files.values())
        with pytest.MonkeyPatch.context() as mp:
            for owner, name in COMPUTING:
                mp.setattr(owner, name, _forbidden(name))
            for name in ("predict", "predict_interval"):  # no prediction
                mp.setattr(type(run.model), name, _forbidden(name))
            ids = record(cfg, run.result, run.model, run.dataset, computed, kind="evaluate",
                         tracking_uri=new_store(tmp_path / "mlflow.db"))
        logged = {path: Path(file).read_bytes() for path, file in computed.files.items()}
        scratch = next(iter(computed.files.values())).parent
    assert not scratch.exists()  # the PNG files are removed once recorded
    client = MlflowClient(ids["tracking_uri"])
    run_id = ids["run_id"]

    def artifacts(folder: str) -> set[str]:
        return {a.path for a in client.list_artifacts(run_id, folder)}

    assert artifacts("plots") == set(logged)
    for path, data in logged.items():  # the files computed, byte for byte
        assert Path(client.download_artifacts(run_id, path, str(tmp_path))).read_bytes() == data
    assert artifacts("intervals") == {"intervals/test_intervals.csv"}
    assert artifacts("eigenvalue") == {"eigenvalue/curve_table.csv"}
    assert artifacts("predictions") == {"predictions/test.csv", "predictions/test_measured.csv"}
    assert "learning_curves.json" in {a.path for a in client.list_artifacts(run_id)}
    table = pd.read_csv(client.download_artifacts(run_id, "intervals/test_intervals.csv",
                                                  str(tmp_path)))
    pd.testing.assert_frame_equal(table, computed.tables["intervals/test_intervals.csv"],
                                  check_dtype=False)
    predicted = pd.read_csv(client.download_artifacts(run_id, "predictions/test.csv",
                                                      str(tmp_path)), index_col="row")
    assert np.allclose(predicted[["y1", "y2"]].to_numpy(),
                       computed.predictions[["y1", "y2"]].to_numpy())


def test_out_alone_writes_what_a_run_logs_but_the_predictions(fitted, tmp_path):
    """``--out`` without tracking: the bars, the intervals' figure and table, the family's
    run figures, tables and data, written; no predictions and no scratch directory."""
    cfg, run = fitted
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(serving, "prediction_frame", _forbidden("prediction_frame"))
        with computed_outputs(cfg, run.result, run.model, run.dataset, setting="s",
                              track=False, out=tmp_path / "out") as computed:
            assert not computed.files and computed.predictions is None
    assert set(computed.written) == {"mae_bars", "mse_bars", "intervals", "test_intervals",
                                     "curve_y1", "curve_table", "learning_curves"}
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "curve_table.csv", "curve_y1.png", "intervals.png", "learning_curves.json",
        "mae_bars.png", "mse_bars.png", "test_intervals.csv"]


def test_out_and_tracking_log_the_files_out_wrote(fitted, tmp_path):
    """With ``--out`` and tracking, a figure ``--out`` wrote is not rendered again: the record
    logs that file."""
    cfg, run = fitted
    with computed_outputs(cfg, run.result, run.model, run.dataset, setting="s",
                          out=tmp_path / "out") as computed:
        for name in ("intervals", "mae_bars", "curve_y1"):
            assert computed.files[f"plots/{name}.png"] == tmp_path / "out" / f"{name}.png"
        bars = computed.files["plots/mae_bars.png"]
        # a run's PNG is the bytes --out (save_figure) writes of the same figure
        again = figures.save_figure(computed.figures["plots/mae_bars.png"], tmp_path / "a.png")
        assert bars.read_bytes() == again.read_bytes()
