"""The data and comparison figures of the paper: Fig. 3, S2, S3, S6/S7 (experiment layer)."""

import matplotlib.image
import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch

import workbench.experiment.figures as figures  # a missing dependency fails, never skips

SHORT = ["Y1", "Y2", "Y3", "Y4", "Y5"]
TABULA = [15.3, 14.6, 18.9, 25.5, 24.9]
PRIOR_MAE = [2.417, 1.400, 0.819, 0.972, 1.098]
MODEL_MAE = [1.750, 1.036, 0.802, 0.801, 1.004]
SYSTEMS = {"tabula rasa MLP": TABULA, "control program": PRIOR_MAE, "base boosting": MODEL_MAE}


@pytest.fixture(scope="module")
def train(google_5q):
    """The training rows: voltages, prior (as X1..X5) and targets (as Y1..Y5)."""
    X_train, _, y_train, _ = google_5q.split()
    prior = X_train[google_5q.prior_names].set_axis([f"X{j}" for j in range(1, 6)], axis=1)
    targets = y_train[google_5q.target_names].set_axis(SHORT, axis=1)
    return X_train[google_5q.feature_names], prior, targets


def _png(fig, tmp_path, name):
    path = figures.save_figure(fig, tmp_path / name)
    img = matplotlib.image.imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    return path


def _no_pyplot_figures():
    import matplotlib.pyplot as plt

    return plt.get_fignums() == []


def _boxes(ax):
    return [p for p in ax.patches if isinstance(p, PathPatch)]


# --------------------------------------------------------------------------- Fig. 3


def test_correlation_heatmap_shows_frame_corr(train, tmp_path):
    _, prior, targets = train
    frame = prior.join(targets)
    fig = figures.correlation_heatmap(frame, title="Fig. 3", setting="training rows")
    assert isinstance(fig, Figure)
    ax, bar_ax = fig.axes
    expected = frame.corr().to_numpy()
    # the colours: the image array is the correlation matrix, on a colour map fixed to [-1, 1]
    image = ax.images[0]
    np.testing.assert_allclose(np.asarray(image.get_array()), expected)
    assert image.get_clim() == (-1.0, 1.0)
    # the annotations: one per cell, row by row, 2 decimals
    texts = [t.get_text() for t in ax.texts]
    assert len(texts) == 100
    np.testing.assert_allclose(np.array(texts, dtype=float).reshape(10, 10), expected,
                               atol=0.005 + 1e-12)
    assert all(len(t.split(".")[1]) == 2 for t in texts)
    assert texts[0] == "1.00"
    assert "-0.00" not in texts
    names = [*prior.columns, *targets.columns]
    assert [t.get_text() for t in ax.get_xticklabels()] == names
    assert [t.get_text() for t in ax.get_yticklabels()] == names
    assert bar_ax.get_ylabel() == "Pearson correlation"
    assert "Fig. 3" in ax.get_title() and "training rows" in ax.get_title()
    _png(fig, tmp_path, "corr.png")
    assert _no_pyplot_figures()


def test_correlation_heatmap_marks_a_constant_column():
    frame = pd.DataFrame({"a": [1.0, 2.0, 3.0], "b": [3.0, 1.0, 2.0], "c": [5.0, 5.0, 5.0]})
    fig = figures.correlation_heatmap(frame)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert texts[2] == "n/a" and texts[0] == "1.00" and texts[1] == "-0.50"


@pytest.mark.parametrize("frame, match", [
    (pd.DataFrame({"a": [1.0, 2.0]}), "at least 2 columns"),
    (pd.DataFrame({"a": [1.0], "b": [2.0]}), "at least 2 rows"),
    (pd.DataFrame({"a": [1.0, 2.0], "b": ["x", "y"]}), r"non-numeric columns: \['b'\]"),
    (pd.DataFrame(), "empty"),
])
def test_correlation_heatmap_refuses_bad_frames(frame, match):
    with pytest.raises(ValueError, match=match):
        figures.correlation_heatmap(frame)


# --------------------------------------------------------------------------- Fig. S2


def test_voltage_boxplots_has_a_qubit_and_a_coupler_panel(train, tmp_path):
    voltages, _, _ = train
    fig = figures.voltage_boxplots(voltages, title="Fig. S2")
    assert isinstance(fig, Figure)
    qubit_ax, coupler_ax = fig.axes
    assert len(_boxes(qubit_ax)) == 5 and len(_boxes(coupler_ax)) == 4
    assert [t.get_text() for t in qubit_ax.get_xticklabels()] == list(voltages.columns[:5])
    assert [t.get_text() for t in coupler_ax.get_xticklabels()] == list(voltages.columns[5:])
    assert list(voltages.columns[5:]) == [f"cvolt{i}" for i in range(5, 9)]
    for ax in (qubit_ax, coupler_ax):
        assert ax.get_ylabel() == "bias voltage (a.u.)"
    assert "qubit" in qubit_ax.get_title() and "coupler" in coupler_ax.get_title()
    # each panel has its own y axis, fitted to its own range
    assert np.ptp(coupler_ax.get_ylim()) > 5 * np.ptp(qubit_ax.get_ylim())
    lo, hi = qubit_ax.get_ylim()
    assert lo <= voltages["qvolt6"].min() and hi >= voltages["qvolt9"].max()
    assert fig.get_suptitle() == "Fig. S2"
    _png(fig, tmp_path, "volt.png")
    assert _no_pyplot_figures()


def test_voltage_boxplots_medians_are_the_data_medians(train):
    voltages, _, _ = train
    fig = figures.voltage_boxplots(voltages)
    medians = [line.get_ydata()[0] for ax in fig.axes for line in ax.get_lines()
               if line.get_color() == "#000000" and len(line.get_xdata()) == 2
               and line.get_linewidth() == 1.5]
    np.testing.assert_allclose(medians, voltages.median().to_numpy())


def test_voltage_boxplots_refuses_unknown_columns():
    with pytest.raises(ValueError, match=r"\['x1'\].*neither 'q' \(qubit\) nor 'c' \(coupler\)"):
        figures.voltage_boxplots(pd.DataFrame({"qvolt5": [0.1, 0.2], "x1": [1.0, 2.0]}))
    with pytest.raises(ValueError, match="no finite values"):
        figures.voltage_boxplots(pd.DataFrame({"qvolt5": [np.nan, np.nan], "cvolt5": [1.0, 2.0]}))


# --------------------------------------------------------------------------- Fig. S3


def test_prior_target_boxplots_pairs_each_eigenenergy(train, tmp_path):
    _, prior, targets = train
    fig = figures.prior_target_boxplots(prior, targets, unit="MHz", title="Fig. S3")
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    boxes = _boxes(ax)
    assert len(boxes) == 10
    colours = {tuple(np.round(b.get_facecolor(), 3)) for b in boxes}
    assert len(colours) == 2
    assert ax.get_ylabel() == "eigenenergy (MHz)"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["prior (X)", "measured (Y)"]
    assert [t.get_text() for t in ax.get_xticklabels()] == [f"X{j} | Y{j}" for j in range(1, 6)]
    lo, hi = ax.get_ylim()  # plotted as given, about -6000 MHz
    assert -6100 < lo <= min(prior.min().min(), targets.min().min())
    assert max(prior.max().max(), targets.max().max()) <= hi < -5800
    assert ax.get_title() == "Fig. S3"
    _png(fig, tmp_path, "s3.png")
    assert _no_pyplot_figures()


def test_prior_target_boxplots_names_other_columns(google_5q):
    X_train, _, y_train, _ = google_5q.split()
    fig = figures.prior_target_boxplots(X_train[google_5q.prior_names],
                                        y_train[google_5q.target_names], unit="GHz")
    ax = fig.axes[0]
    assert ax.get_xticklabels()[0].get_text() == "X1 | Y1\npeig1 | eeig1"
    assert ax.get_ylabel() == "eigenenergy (GHz)"


def test_prior_target_boxplots_refuses_mismatched_frames(train):
    _, prior, targets = train
    with pytest.raises(ValueError, match="prior has 5 columns, targets 4"):
        figures.prior_target_boxplots(prior, targets.iloc[:, :4])
    with pytest.raises(ValueError, match="prior has 95 rows, targets 90"):
        figures.prior_target_boxplots(prior, targets.iloc[:90])


# --------------------------------------------------------------------------- Fig. S6/S7


def test_model_comparison_bars_heights_are_the_values(tmp_path):
    fig = figures.model_comparison_bars(SHORT, SYSTEMS, unit="MHz", log=True, setting="seed 0")
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert len(ax.containers) == 3
    for container, (system, values) in zip(ax.containers, SYSTEMS.items(), strict=True):
        assert container.get_label() == system
        heights = [bar.get_height() for bar in container]
        np.testing.assert_allclose(heights, [*values, np.mean(values)])
    assert ax.get_yscale() == "log"
    assert "MAE" in ax.get_ylabel() and "MHz" in ax.get_ylabel()
    assert [t.get_text() for t in ax.get_xticklabels()] == [*SHORT, "average"]
    assert [t.get_text() for t in fig.legends[0].get_texts()] == list(SYSTEMS)
    annotations = [t.get_text() for t in ax.texts]
    assert {"15.30", "1.34", "1.08", f"{np.mean(TABULA):.2f}"} <= set(annotations)
    assert "seed 0" in ax.get_title() and "tabula rasa MLP" in ax.get_title()
    # the known systems keep the colours of mae_bars
    assert ax.containers[1][0].get_facecolor()[:3] == pytest.approx((0.498, 0.498, 0.498),
                                                                    abs=1e-3)
    _png(fig, tmp_path, "s6.png")
    assert _no_pyplot_figures()


def test_model_comparison_bars_linear_mse_and_four_systems():
    values = {**SYSTEMS, "other": [1.0, 2.0, 3.0, 4.0, 5.0]}
    fig = figures.model_comparison_bars(SHORT, values, metric="MSE", unit="MHz²",
                                        average=False)
    ax = fig.axes[0]
    assert ax.get_yscale() == "linear" and ax.get_ylim()[0] == 0
    assert ax.get_ylabel() == "MSE (MHz²)"
    assert len(ax.containers) == 4 and all(len(c) == 5 for c in ax.containers)
    colours = {tuple(c[0].get_facecolor()) for c in ax.containers}
    assert len(colours) == 4


def test_model_comparison_bars_draws_the_intervals_given(tmp_path):
    rows = [[v * 0.8, v * 1.3] for v in [*TABULA, np.mean(TABULA)]]
    fig = figures.model_comparison_bars(SHORT, SYSTEMS, log=True,
                                        intervals={"tabula rasa MLP": rows})
    ax = fig.axes[0]
    bars = [c for c in ax.containers if hasattr(c, "patches")]
    assert [c.errorbar is not None for c in bars] == [True, False, False]
    segments = bars[0].errorbar.lines[2][0].get_segments()
    np.testing.assert_allclose([[s[:, 1].min(), s[:, 1].max()] for s in segments], rows)
    assert ax.get_ylim()[1] > max(r[1] for r in rows)
    assert [t.get_text() for t in fig.legends[0].get_texts()] == list(SYSTEMS)
    assert any("95% bootstrap intervals" in t.get_text() for t in ax.texts)
    _png(fig, tmp_path, "s6_ci.png")
    with pytest.raises(ValueError, match=r"unknown systems \['MLP'\]"):
        figures.model_comparison_bars(SHORT, SYSTEMS, intervals={"MLP": rows})


def test_model_comparison_bars_with_two_systems_matches_mae_bars_geometry():
    fig = figures.model_comparison_bars(SHORT, {"control program": PRIOR_MAE,
                                                "base boosting": MODEL_MAE})
    ref = figures.mae_bars(SHORT, PRIOR_MAE, MODEL_MAE)
    for ours, theirs in zip(fig.axes[0].containers, ref.axes[0].containers, strict=True):
        assert [b.get_x() for b in ours] == [b.get_x() for b in theirs]
        assert [b.get_height() for b in ours] == [b.get_height() for b in theirs]
        assert ours[0].get_facecolor() == theirs[0].get_facecolor()


@pytest.mark.parametrize("values, kwargs, match", [
    ({"only one": PRIOR_MAE}, {}, r"2 to 6 systems; got 1: \['only one'\]"),
    ({f"s{i}": PRIOR_MAE for i in range(7)}, {}, "2 to 6 systems; got 7"),
    ({f"s{i}": PRIOR_MAE for i in range(5)}, {}, "more than 4 systems other than the prior"),
    ({"a": PRIOR_MAE, "b": MODEL_MAE[:4]}, {}, r"values\['b'\] must have one value per target"),
    ({"a": PRIOR_MAE, "b": [np.nan, 1, 1, 1, 1]}, {}, r"values\['b'\] has non-finite"),
    ({"a": PRIOR_MAE, "b": [0.0, 1, 1, 1, 1]}, {"log": True}, r"log=True needs positive.*'b'"),
])
def test_model_comparison_bars_refuses_bad_values(values, kwargs, match):
    with pytest.raises(ValueError, match=match):
        figures.model_comparison_bars(SHORT, values, **kwargs)


def test_model_comparison_bars_refuses_no_targets_and_non_mappings():
    with pytest.raises(ValueError, match="targets is empty"):
        figures.model_comparison_bars([], {"a": [], "b": []})
    with pytest.raises(TypeError, match="map each system"):
        figures.model_comparison_bars(SHORT, [PRIOR_MAE, MODEL_MAE])


# --------------------------------------------------------------------------- all of them


def test_paper_figures_are_deterministic(train, tmp_path):
    voltages, prior, targets = train

    def build():
        return {"corr": figures.correlation_heatmap(prior.join(targets)),
                "volt": figures.voltage_boxplots(voltages),
                "s3": figures.prior_target_boxplots(prior, targets),
                "bars": figures.model_comparison_bars(SHORT, SYSTEMS, log=True)}

    first = {k: figures.save_figure(f, tmp_path / f"{k}0.png").read_bytes()
             for k, f in build().items()}
    second = {k: figures.save_figure(f, tmp_path / f"{k}1.png").read_bytes()
              for k, f in build().items()}
    assert first == second
    assert _no_pyplot_figures()
