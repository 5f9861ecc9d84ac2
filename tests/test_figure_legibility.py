"""Every figure legible on every data set: no text leaves the canvas, no two labels overlap.

Each figure function of :mod:`workbench.experiment.figures`, of the families' figure modules
and the report's IBM figure is drawn on synthetic inputs of data sets of different shapes and
names (one target with a short name; three targets named in 30-40 characters; nine targets; a
unit and none), rendered at the PNG resolution with the Agg canvas, and every visible text
(titles, axis and tick labels, legend entries, annotations) is measured with matplotlib's
renderer. A public figure function missing from :data:`DRAW` fails the test, so a new figure
is covered when it is added.
"""

import itertools
import types
import warnings
from unittest import mock

import numpy as np
import pandas as pd
import pytest

import workbench.experiment.families.hamiltonian_figures as family_figures
import workbench.experiment.families.parametric_figures as parametric_figures
import workbench.experiment.figures as figures
from workbench.curves import LearningCurve
from workbench.experiment.figures import outer_folds
from workbench.experiment.figures.style import PNG_DPI
from workbench.experiment.paper.gates import GATE_SYSTEMS, gates_figure
from workbench.experiment.scoring.explain import ShapValues
from workbench.experiment.scoring.results import OuterFold

#: Data sets: target names, unit, the prior's name and the run's setting line.
SHAPES = {
    "one_short": (["E"], "MHz", "prior", "evaluate of generic"),
    "three_long": (["two_qubit_gate_error_cz_median_2025",  # 35 characters
                    "readout_assignment_error_of_qubit_zero",  # 38
                    "single_qubit_sx_gate_error_mean_pct"],  # 35
                   None, "coherence-limited error estimate", "evaluate of user_gates_generic"),
    "nine": ([f"eigenenergy_{j}" for j in range(1, 10)], "%", "prior", "evaluate of nine"),
}

RNG_SEED = 0


def _rng():
    return np.random.default_rng(RNG_SEED)


def _features(targets):
    """Feature names of a data set: two inputs and one prior column per target."""
    return ["control_voltage_of_the_first_qubit", "drive_amplitude"] + [
        f"{t}_prior" for t in targets]


def _errors(n, scale=1.0):
    return scale * (1.0 + _rng().random(n))


def _ci(values):
    values = np.append(values, values.mean())
    return np.column_stack([values * 0.8, values * 1.25])


def _mae_bars(targets, unit, prior_label, setting):
    prior, model = _errors(len(targets), 2.0), _errors(len(targets))
    yield figures.mae_bars(targets, prior, model, unit=unit, labels=(prior_label,
                                                                     "base boosting"),
                           title="Test MAE per target", setting=setting,
                           prior_ci=_ci(prior), model_ci=_ci(model))
    yield figures.mae_bars(targets, prior, model, unit=unit, metric="MSE")  # default title


def _error_bars(targets, unit, prior_label, setting):
    from types import SimpleNamespace

    def scores(values):  # what error_bars reads of a Result's prior and model scores
        return SimpleNamespace(test_mae=values, test_mse=values ** 2,
                               ci=lambda key: _ci(values if key == "test_mae" else values ** 2))

    result = SimpleNamespace(targets=list(targets), prior=scores(_errors(len(targets), 2.0)),
                             model=scores(_errors(len(targets))))
    for metric in ("MAE", "MSE"):
        yield figures.error_bars(result, metric, unit=unit, setting=setting,
                                 labels=(prior_label, "base boosting"),
                                 title=f"Test {metric} per target")


def _comparison(targets, unit, prior_label, setting):
    names = [prior_label, "LightGBM from the prior, tuned by CV",
             "base boosting, generic config"]
    values = {name: _errors(len(targets), 3 - i) for i, name in enumerate(names)}
    yield figures.model_comparison_bars(targets, values, unit=unit, setting=setting,
                                        intervals={k: _ci(v) for k, v in values.items()})
    yield figures.model_comparison_bars(targets, values, unit=unit, log=True)


def _curve(n_folds=5):
    sizes = np.array([20, 40, 80, 160])
    rows = np.repeat(sizes[:, None], n_folds, axis=1)
    err = 1.0 / np.sqrt(rows) + 0.05 * _rng().random(rows.shape)
    return LearningCurve(train_sizes=sizes, n_train_rows=rows, train_error=0.5 * err,
                         cv_error=err, incumbent_error=np.full(rows.shape, 0.3),
                         n_validation_rows=np.full(n_folds, 40))


def _learning_curve(targets, unit, prior_label, setting):
    target = max(targets, key=len)
    yield figures.learning_curve_figure(_curve(), target=target, unit=unit, setting=setting)


def _shap_rows(targets):
    names = _features(targets)[:10]
    return pd.DataFrame(_rng().normal(size=(40, len(names))), columns=names)


def _shap_figure(targets, unit, prior_label, setting):
    X = _shap_rows(targets)
    values = X.to_numpy() * np.linspace(1.0, 0.1, X.shape[1])
    for target, explained in ((targets[0], "correction"), (targets[-1], "prediction"),
                              (targets[0], None)):
        yield figures.shap_figure(values, 0.0, X, target=target, unit=unit, setting=setting,
                                  explained=explained)


def _shap_summary(targets, unit, prior_label, setting):
    X = _shap_rows(targets)[:4]
    X = X.iloc[:, :4]
    fig, _ = figures.shap_summary(lambda a: a @ np.arange(1.0, a.shape[1] + 1), X,
                                  target=targets[-1], unit=unit, background_size=4,
                                  setting=setting)
    yield fig


def _correction_shap(targets, unit, prior_label, setting):
    X = _shap_rows(targets)
    target = max(targets, key=len)
    yield figures.correction_shap_figure(None, target=target, unit=unit,
                                         note="CV chose the prior", setting=setting)
    yield figures.correction_shap_figure(ShapValues(X.to_numpy() * 0.1, 0.0, X),
                                         target=target, unit=unit, setting=setting)


def _frame(names, rows=30):
    return pd.DataFrame(_rng().normal(size=(rows, len(names))), columns=names)


def _correlation(targets, unit, prior_label, setting):
    names = _features(targets)[:2] + targets + [f"{targets[0]}_prior"]
    yield figures.correlation_heatmap(_frame(names), setting=setting)


def _voltages(targets, unit, prior_label, setting):
    names = [f"q{t}" for t in targets] + [f"c{t}" for t in targets[:-1] or targets]
    yield figures.voltage_boxplots(_frame(names))


def _prior_targets(targets, unit, prior_label, setting):
    yield figures.prior_target_boxplots(_frame([f"{t}_prior" for t in targets]),
                                        _frame(targets), unit=unit,
                                        labels=(f"{prior_label} (X)", "measured (Y)"))


def _intervals(targets, unit, prior_label, setting):
    rng = _rng()
    parts = []
    for target in targets:
        pred = rng.normal(size=12)
        meas = pred + rng.normal(scale=0.5, size=12)
        parts.append(pd.DataFrame({"target": target, "measured": meas, "predicted": pred,
                                   "lower": pred - 0.6, "upper": pred + 0.6}))
    yield figures.interval_figure(pd.concat(parts), level=0.9, unit=unit, setting=setting,
                                  title="90% conformal intervals (jackknife+), test rows")


def _seed_spread(targets, unit, prior_label, setting):
    seeds = list(range(10))
    errors = _rng().random((len(seeds), len(targets))) + 1.0
    yield figures.seed_spread(targets, errors, random_states=seeds,
                              prior=_errors(len(targets), 2.0),
                              unit=unit, setting=setting, prior_label=prior_label)


def _outer_folds(targets, unit, prior_label, setting):
    params = {"basis": "lightgbm", "learning_rate": 0.0512345, "num_leaves": 31,
              "min_child_samples": 20, "reg_lambda": 1.234e-3, "subsample": 0.8}
    folds = [OuterFold(block=block, fold=k, study=f"s.{block}.outer{k}", mae=1.0,
                       prior_mae=1.5, selected="boosted", n_train=80, n_val=20,
                       params=params if k else None, target_mae={}, target_prior_mae={})
             for block in targets[:3] for k in range(3)]
    yield outer_folds.outer_folds_figure(folds, unit, prior_label=prior_label)


def _parameter_corrections(targets, unit, prior_label, setting):
    names = [f"omega_{t}" for t in targets]
    control = _frame(names, 20)
    corrected = control + 0.1 * _frame(names, 20).to_numpy()
    yield family_figures.parameter_corrections(
        control, corrected, groups={"training rows": range(15), "test rows": range(15, 20)},
        unit=unit, setting=setting)


def _selection_path(targets, unit, prior_label, setting):
    steps = [("", "")] + [(f"omega_{t}", f"control_voltage_{t}") for t in targets]
    path = pd.DataFrame({"step": range(len(steps)), "parameter": [p for p, _ in steps],
                         "covariate": [c for _, c in steps],
                         "cv_mae": np.linspace(1.0, 0.5, len(steps))})
    yield family_figures.selection_path_figure(
        path, unit=unit, setting=setting,
        title="Forward covariate selection (120 training rows, CV MAE over all targets)")


def _parameter_drift(targets, unit, prior_label, setting):
    names = [f"E_J_{t}" for t in targets]
    corrected = _frame(names, 20)
    day = np.arange(20.0)
    axes_by = {name: (f"days_since_cooldown_{name}", day) for name in names}
    yield parametric_figures.parameter_drift_figure(
        corrected, axes_by, calibrated={name: 0.0 for name in names},
        groups={"training rows": range(15), "test rows": range(15, 20)}, setting=setting)


def _gates(targets, unit, prior_label, setting):
    def scores(values):
        return types.SimpleNamespace(test_mae=list(values), ci=lambda key: _ci(values))

    def result(prior, model):
        return types.SimpleNamespace(targets=targets, prior=scores(prior), model=scores(model))

    n = len(targets)
    gates = types.SimpleNamespace(generic=result(_errors(n, 3), _errors(n)),
                                  peer=result(_errors(n, 3), _errors(n, 1.2)),
                                  dataset=types.SimpleNamespace(unit=unit))
    assert len(GATE_SYSTEMS) == 3
    yield gates_figure(gates)


#: Every public figure function -> draws its figures for a data set (targets, unit, prior
#: label, setting).
DRAW = {
    figures.mae_bars: _mae_bars,
    figures.error_bars: _error_bars,
    figures.model_comparison_bars: _comparison,
    figures.learning_curve_figure: _learning_curve,
    figures.shap_figure: _shap_figure,
    figures.shap_summary: _shap_summary,
    figures.correction_shap_figure: _correction_shap,
    figures.correlation_heatmap: _correlation,
    figures.voltage_boxplots: _voltages,
    figures.prior_target_boxplots: _prior_targets,
    figures.interval_figure: _intervals,
    figures.seed_spread: _seed_spread,
    outer_folds.outer_folds_figure: _outer_folds,
    family_figures.parameter_corrections: _parameter_corrections,
    family_figures.selection_path_figure: _selection_path,
    parametric_figures.parameter_drift_figure: _parameter_drift,
    gates_figure: _gates,
}

#: Public functions of those modules that draw no figure.
NOT_FIGURES = {figures.save_figure, outer_folds.configuration_label,
               parametric_figures.covariate_axis, parametric_figures.drift_axes}


def _public_functions():
    for module in (figures, outer_folds, family_figures, parametric_figures):
        for name in module.__all__:
            yield getattr(module, name)


def test_every_public_figure_function_is_drawn():
    missing = [f.__qualname__ for f in _public_functions()
               if f not in DRAW and f not in NOT_FIGURES]
    assert not missing, f"figure functions this test does not draw: {missing}"


def _drawn_texts(fig):
    """Draw ``fig`` on its canvas; return the texts drawn (visible and non-empty).

    The texts are those whose ``draw`` runs and does not return at once: a tick beyond the
    axis' limits, a hidden axes' labels or an annotation clipped away are not drawn, and not
    measured.
    """
    from matplotlib.text import Text

    drawn = {}
    draw = Text.draw

    def spy(text, renderer):
        if text.get_visible() and text.get_text().strip():
            drawn[id(text)] = text
        return draw(text, renderer)

    with mock.patch.object(Text, "draw", spy), warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. constrained layout giving up
        fig.canvas.draw()
    return list(drawn.values())


def _corners(text, box, renderer):
    """The corners of ``text``'s own (rotated) rectangle, whose bounding box is ``box``.

    A rotated rectangle's bounding box has the rectangle's centre: the rectangle is the
    text's extent unrotated, turned about that centre.
    """
    angle = text.get_rotation()
    if angle % 90 == 0:
        return np.array([[box.x0, box.y0], [box.x1, box.y0], [box.x1, box.y1],
                         [box.x0, box.y1]])
    text.set_rotation(0)
    flat = text.get_window_extent(renderer)
    text.set_rotation(angle)
    half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [flat.width / 2, flat.height / 2]
    turn = np.deg2rad(angle)
    rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    return half @ rotation.T + [(box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2]


def _overlap(a, b, pad=1.0):
    """Whether two convex polygons overlap by more than ``pad`` pixels (separating axes)."""
    for poly in (a, b):
        for i in range(len(poly)):
            edge = poly[(i + 1) % len(poly)] - poly[i]
            axis = np.array([-edge[1], edge[0]]) / np.hypot(*edge)
            pa, pb = a @ axis, b @ axis
            if pa.max() - pad <= pb.min() + pad or pb.max() - pad <= pa.min() + pad:
                return False
    return True


def _describe(text):
    return f"{type(text).__name__} {text.get_text()!r}"


def illegible(fig):
    """What leaves the canvas or overlaps in ``fig``, rendered as ``save_figure`` writes it.

    Returns a list of problems (empty: legible): texts whose extent leaves the figure's
    canvas, and pairs of texts that overlap (tick labels of one axis, legend entries, axis
    labels and titles, bar annotations).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.set_dpi(PNG_DPI)
    texts = _drawn_texts(fig)
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox
    problems = []
    boxes = {}
    for text in texts:
        box = text.get_window_extent(renderer)
        boxes[text] = box
        if (box.x0 < canvas.x0 - 1 or box.y0 < canvas.y0 - 1 or box.x1 > canvas.x1 + 1
                or box.y1 > canvas.y1 + 1):
            problems.append(f"{_describe(text)} leaves the canvas: {box.bounds} outside "
                            f"{canvas.bounds}")
    corners = {text: _corners(text, boxes[text], renderer) for text in texts}
    for a, b in itertools.combinations(texts, 2):
        if boxes[a].overlaps(boxes[b]) and _overlap(corners[a], corners[b]):
            problems.append(f"{_describe(a)} overlaps {_describe(b)}")
    return problems


CASES = [(draw, shape) for draw in DRAW for shape in SHAPES]


@pytest.mark.parametrize(("function", "shape"), CASES,
                         ids=[f"{f.__name__}-{s}" for f, s in CASES])
def test_figure_is_legible(function, shape):
    targets, unit, prior_label, setting = SHAPES[shape]
    for i, fig in enumerate(DRAW[function](targets, unit, prior_label, setting)):
        problems = illegible(fig)
        assert not problems, f"figure {i} of {function.__name__}:\n" + "\n".join(problems)


def test_the_check_finds_a_title_off_the_canvas_and_overlapping_labels():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3, 2))
    ax = fig.add_subplot()
    ax.set_title("a title much too long for a figure three inches wide, cut at both ends")
    ax.set_xticks([0, 0.2], ["a long tick label", "another long tick label"])
    ax.set_xlim(0, 1)
    problems = illegible(fig)
    assert any("leaves the canvas" in p and "a title much" in p for p in problems)
    assert any("overlaps" in p and "a long tick label" in p for p in problems)


# --------------------------------------------------------------------------- the prior's name


def _csv(tmp_path):
    rng = _rng()
    x = rng.normal(size=30)
    frame = pd.DataFrame({"v": x, "model_E": x + 1.0, "measured_E": x + 1.1})
    path = tmp_path / "lab.csv"
    frame.to_csv(path, index=False)
    return {"csv": path.name, "prior": ["model_E"], "targets": ["measured_E"],
            "features": ["v"], "test_fraction": 0.3}


def test_the_figures_call_the_prior_as_the_data_set_names_it(tmp_path):
    from workbench.datasets import load_source
    from workbench.experiment.config import DataConfig
    from workbench.experiment.runs.run_outputs import _run_bars

    options = _csv(tmp_path)
    assert load_source("csv", options, tmp_path, "lab").prior_label == "prior"
    named = DataConfig(**options, prior_label="mass formula").model_dump()
    ds = load_source("csv", named, tmp_path, "lab")
    assert ds.prior_label == "mass formula"
    scores = types.SimpleNamespace(test_mae=[1.0], test_mse=[1.0], ci=lambda key: None)
    result = types.SimpleNamespace(targets=ds.target_names, prior=scores, model=scores)
    for fig in _run_bars(result, ds, "evaluate of lab").values():
        legend = fig.axes[0].get_legend() or fig.legends[0]
        assert [t.get_text() for t in legend.get_texts()] == ["mass formula", "base boosting"]
    with pytest.raises(ValueError, match="apply to source"):
        DataConfig(source="google_5q", prior_label="control program")


def test_the_benchmarks_name_their_priors(google_5q, ibm_gates_dir):
    from workbench.datasets import load_ibm_gates

    assert google_5q.prior_label == "control program"
    assert load_ibm_gates(ibm_gates_dir, download=False).prior_label == "coherence limit"
