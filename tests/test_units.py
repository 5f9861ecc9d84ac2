"""Units carried by the data: an ``evaluate`` of a CSV with ``[data] unit = "meV"`` labels
every figure axis, summary and run description in meV, never in the benchmark's MHz."""

import numpy as np
import pandas as pd
import pytest
from mlflow import MlflowClient

from workbench.experiment.runs.evaluate import evaluate, format_table
from workbench.experiment.runs.prepare import load_config
from workbench.experiment.runs.record import record
from workbench.experiment.runs.run_fields import NOTE_TAG
from workbench.experiment.runs.run_outputs import computed_outputs


def _config(tmp_path, unit: str | None) -> object:
    rng = np.random.default_rng(0)
    n = 48
    f = rng.normal(size=(n, 2))
    prior = rng.normal(size=(n, 2)) * 3
    y = prior + 0.5 * f[:, [0]] - 0.3 * f[:, [1]] ** 2 + rng.normal(scale=0.1, size=(n, 2))
    pd.DataFrame({"f1": f[:, 0], "f2": f[:, 1], "p1": prior[:, 0], "p2": prior[:, 1],
                  "y1": y[:, 0], "y2": y[:, 1]}).to_csv(tmp_path / "data.csv", index=False)
    line = f'unit = "{unit}"\n' if unit else ""
    (tmp_path / "c.toml").write_text(
        'name = "units"\nrandom_state = 0\nn_jobs = 1\n[data]\ncsv = "data.csv"\n'
        'prior = ["p1", "p2"]\ntargets = ["y1", "y2"]\nfeatures = ["f1", "f2"]\n'
        f'test_fraction = 0.25\n{line}[model]\nbasis = "ridge"\n')
    return load_config(tmp_path / "c.toml")


def _labels(fig) -> list[str]:
    """Every axis label and title of a figure, and its texts."""
    out = [t.get_text() for t in fig.texts]
    if fig._suptitle is not None:
        out.append(fig._suptitle.get_text())
    for ax in fig.axes:
        out += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
        out += [t.get_text() for t in ax.texts]
    return [t for t in out if t]


def _record(cfg, run, tmp_path, new_store) -> tuple[dict, dict]:
    """Compute a run's outputs and record them: the record's ids and every figure it logs,
    by artifact name."""
    with computed_outputs(cfg, run.result, run.model, run.dataset,
                          setting=f"evaluate of {cfg.name}") as computed:
        ids = record(cfg, run.result, run.model, run.dataset, computed, kind="evaluate",
                     tracking_uri=new_store(tmp_path / "mlflow.db"))
    assert set(computed.figures) == set(computed.files)
    return ids, computed.figures


def test_a_csv_s_unit_labels_every_figure_summary_and_description(tmp_path, new_store):
    cfg = _config(tmp_path, "meV")
    run = evaluate(cfg, return_model=True)
    assert run.dataset.unit == run.result.unit == "meV"
    assert run.result.to_json()["unit"] == "meV"
    assert "test MAE in meV" in format_table(run.result)
    ids, drawn = _record(cfg, run, tmp_path, new_store)
    note = MlflowClient(ids["tracking_uri"]).get_run(ids["run_id"]).data.tags[NOTE_TAG]
    assert "in meV (MSE: squared)" in note and "MHz" not in note
    expected = {"plots/mae_bars.png": ("y", "MAE (meV)"), "plots/mse_bars.png": ("y", "MSE (meV²)"),
                "plots/learning_curve_y1.png": ("y", "MAE (meV)"),
                "plots/shap_y1.png": ("x", "SHAP value: effect on the whole prediction of y1 "
                                           "(meV)"),
                "plots/intervals.png": ("y", "measured (meV)")}
    assert set(expected) <= set(drawn)
    for name, (axis, label) in expected.items():
        ax = drawn[name].axes[0]
        assert (ax.get_xlabel() if axis == "x" else ax.get_ylabel()) == label, name
    for name, fig in drawn.items():  # no figure says MHz; every unit it names is meV
        labels = _labels(fig)
        assert not [t for t in labels if "MHz" in t], (name, labels)
    correction = drawn["plots/shap_correction_y1.png"]
    text = " ".join(_labels(correction))
    assert "meV" in text  # a beeswarm's axis, or the note that the correction is 0 meV


def test_data_without_a_unit_show_none(tmp_path, new_store):
    cfg = _config(tmp_path, None)
    run = evaluate(cfg, return_model=True)
    assert run.dataset.unit is None and run.result.to_json()["unit"] is None
    assert "test MAE in the targets' units" in format_table(run.result)
    _, drawn = _record(cfg, run, tmp_path, new_store)
    assert drawn["plots/mae_bars.png"].axes[0].get_ylabel() == "MAE"
    assert drawn["plots/intervals.png"].axes[0].get_ylabel() == "measured"


def test_the_unit_is_a_csv_key_only(tmp_path):
    from workbench.experiment.process.errors import ConfigError
    from workbench.experiment.runs.prepare import parse_config

    with pytest.raises(ConfigError, match="unit"):
        parse_config({"data": {"source": "google_5q", "unit": "meV"}})
