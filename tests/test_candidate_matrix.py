"""Every kind of model the selection can return, through every command and figure (issue 41).

One small CSV whose five targets each make CV return another kind, from a config that sets
them per target (``[model.targets.<target>]``):

========== ================================================================================
kind       the target's model
========== ================================================================================
ridge      one ridge stage (a BaseBoostCV of one basis)
mean       the mean of a ridge stage added to the prior and one multiplying it (a
           CandidateMean of two links, ensemble = 2): the target is the mean of both forms
stagewise  two stages whose bases are chosen by CV on their residuals (StageChoiceCV)
log        the log link, chosen over the identity by CV (a BasisChoiceCV)
prior      the prior itself (the target is noise around it; a BasisChoiceCV keeps it)
========== ================================================================================

Each command runs once for all five (module fixtures); ``test_kind_through_path[<kind>-
<path>]`` then checks that kind's target in that command's outputs, so a failure names both
(a command that crashes errors all its cases, with its traceback).
The paths: ``evaluate`` tracked (learning curves, SHAP, per-target bars, intervals, the
logged and registered model), ``predict`` from the registry, the scoring server's request
handler, ``evaluate --no-track --out`` (with CV+ intervals: the whole model refitted per
fold), ``evaluate --random-states`` and a tiny ``sweep``.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from workbench.experiment.cli import main

KINDS = {"ridge": "y_ridge", "mean": "y_mean", "stagewise": "y_stagewise", "log": "y_log",
         "prior": "y_prior"}
TARGETS = list(KINDS.values())
N_ROWS = 96

CONFIG = """\
name = "matrix"
random_state = 0
n_jobs = 1

[data]
csv = "matrix.csv"
prior = {priors}
targets = {targets}
features = ["x1", "x2"]
test_fraction = 0.25

[model]
basis = "ridge"
basis_inputs = "prior+features"
input_transform = "standard"
line_search_loss = "absolute_error"
line_search_penalty = 0.0
out_of_bounds = "clip"       # as generic.toml

[model.targets.y_mean]
link = ["identity", "log"]

[model.targets.y_stagewise]
basis = "stagewise"
n_stages = 2

[model.targets.y_stagewise.basis_params]
candidates = ["ridge", "spline"]

[model.targets.y_log]
link = ["identity", "log"]

[model.targets.y_prior]
link = ["identity", "log"]

[selection]
cv = 3
shuffle = true
ensemble = 2

[tracking]
experiment = "matrix"
"""

#: A sweep of the same models: one searched setting, 2 outer and 2 inner folds, 1 trial.
SWEEP = """
[search]
line_search_penalty = { low = 0.0, high = 0.2 }

[cv]
outer_folds = 2
inner_folds = 2
sweep_seed = 0

[study]
trials = 1
storage = "optuna.journal"
"""


def matrix_csv(path: Path) -> None:
    """The five targets (positive, so the log link is a candidate), each from its prior."""
    rng = np.random.default_rng(0)
    x1, x2 = rng.uniform(-1, 1, N_ROWS), rng.uniform(-1, 1, N_ROWS)
    prior = {kind: 2 + 0.5 * rng.uniform(-1, 1, N_ROWS) for kind in KINDS}
    noise = {kind: rng.standard_normal(N_ROWS) for kind in KINDS}
    y = {"ridge": prior["ridge"] + 0.6 * x1 + 0.05 * noise["ridge"],
         # half additive, half multiplicative: the mean of the two links fits it, each
         # alone misses half (in every fold, by more than twice the mean's error)
         "mean": 0.5 * (prior["mean"] + x1) + 0.5 * prior["mean"] * np.exp(0.5 * x1)
         + 0.02 * noise["mean"],
         "stagewise": prior["stagewise"] + 0.5 * x1 + 0.4 * np.abs(x2)
         + 0.05 * noise["stagewise"],
         "log": prior["log"] * np.exp(0.6 * x1) * (1 + 0.01 * noise["log"]),
         "prior": prior["prior"] + 0.2 * noise["prior"]}
    pd.DataFrame({"x1": x1, "x2": x2, **{f"p_{k}": v for k, v in prior.items()},
                  **{KINDS[k]: v for k, v in y.items()}}).to_csv(path, index=False)


def run_main(*argv) -> SimpleNamespace:
    """``main(argv)`` in this process, its standard output and error captured."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in argv])
    return SimpleNamespace(rc=rc, out=out.getvalue(), err=err.getvalue())


def ran(res: SimpleNamespace) -> SimpleNamespace:
    assert res.rc == 0 and "Traceback" not in res.err, res.err[-3000:]
    return res


def text_csv(path) -> pd.DataFrame:
    return pd.read_csv(path, dtype=str, keep_default_na=False)


def floats(frame: pd.DataFrame) -> np.ndarray:
    return frame.map(float).to_numpy()


# --------------------------------------------------------------------------- the commands


@pytest.fixture(scope="module")
def project(tmp_path_factory, new_store):
    root = tmp_path_factory.mktemp("matrix")
    matrix_csv(root / "matrix.csv")
    priors = json.dumps([f"p_{k}" for k in KINDS])
    (root / "c.toml").write_text(CONFIG.format(priors=priors, targets=json.dumps(TARGETS)))
    (root / "sweep.toml").write_text((root / "c.toml").read_text() + SWEEP)
    return SimpleNamespace(root=root, config=root / "c.toml",
                           uri=new_store(root / "store" / "mlflow.db"))


@pytest.fixture(scope="module")
def tracked(project):
    """The default tracked ``evaluate`` (learning curves, SHAP, intervals), registered, with
    ``--out`` and ``--json``; its run's artifacts downloaded."""
    from mlflow import MlflowClient

    root = project.root
    res = ran(run_main("evaluate", project.config, "--tracking-uri", project.uri,
                       "--register", "matrix", "--out", root / "out_tracked",
                       "--json", root / "tracked.json"))
    result = json.loads((root / "tracked.json").read_text())
    client = MlflowClient(project.uri)
    run_id = result["mlflow"]["run_id"]
    local = Path(client.download_artifacts(run_id, "", str(root / "artifacts")))
    return SimpleNamespace(res=res, result=result, client=client, run_id=run_id, root=root,
                           run=client.get_run(run_id), artifacts=local,
                           logged=text_csv(local / "predictions" / "test.csv"))


@pytest.fixture(scope="module")
def loaded(project, tracked):
    """The registered champion as MLflow's pyfunc model (what ``predict`` and the server
    load), and the test rows as a CSV a user would hand to ``predict``."""
    from workbench.experiment.tracking.runs import Tracker

    model = Tracker(project.uri, "matrix").load_model(tracked.result["mlflow"]["model_uri"])
    frame = pd.read_csv(project.root / "matrix.csv")
    rows = tracked.logged["row"].astype(int).tolist()
    csv = project.root / "test_rows.csv"
    frame.iloc[rows].to_csv(csv, index=False)
    return SimpleNamespace(model=model, csv=csv, rows=frame.iloc[rows])


@pytest.fixture(scope="module")
def predicted(project, loaded):
    out = project.root / "predicted.csv"
    ran(run_main("predict", "models:/matrix@champion", loaded.csv, "--out", out,
                 "--tracking-uri", project.uri))
    return text_csv(out)


@pytest.fixture(scope="module")
def served(loaded):
    """The test rows through the scoring server's request handler (``mlflow models serve``
    calls it for ``POST /invocations``; tests/test_predict.py runs the real server)."""
    from mlflow.pyfunc import scoring_server

    X = loaded.rows.drop(columns=TARGETS)
    body = json.dumps({"dataframe_split": {"columns": list(X.columns),
                                           "data": X.to_numpy().tolist()}})
    reply = scoring_server.invocations(body, "application/json", loaded.model,
                                       loaded.model.metadata.get_input_schema())
    assert reply.status == 200, reply.response
    return pd.DataFrame(json.loads(reply.response)["predictions"])


@pytest.fixture(scope="module")
def untracked(project):
    """``evaluate --no-track --out`` with CV+ intervals (the whole model, every choice
    remade, refitted on each of 2 folds' training rows)."""
    root = project.root
    res = ran(run_main("evaluate", project.config, "--no-track", "--out", root / "out",
                       "--set", "intervals.method=cv_plus", "--set", "intervals.cv=2",
                       "--json", root / "untracked.json"))
    return SimpleNamespace(res=res, result=json.loads((root / "untracked.json").read_text()),
                           out=root / "out")


@pytest.fixture(scope="module")
def seeds(project):
    """``evaluate --random-states 0,1``, tracked (a parent run and a child run per seed)."""
    root = project.root
    res = ran(run_main("evaluate", project.config, "--random-states", "0,1", "--tracking-uri",
                       project.uri, "--out", root / "out_seeds", "--json", root / "seeds.json"))
    return SimpleNamespace(res=res, result=json.loads((root / "seeds.json").read_text()),
                           out=root / "out_seeds")


@pytest.fixture(scope="module")
def sweep(project):
    """A tiny ``sweep`` of the same models (untracked), and the states of its trials."""
    import optuna

    from workbench.experiment.storage import open_storage

    root = project.root
    with contextlib.chdir(root):
        res = ran(run_main("sweep", root / "sweep.toml", "--no-track",
                           "--json", root / "sweep.json"))
        journal = open_storage("optuna.journal", root)
        states = {name: [t.state.name for t in
                         optuna.load_study(study_name=name, storage=journal).trials]
                  for name in optuna.get_all_study_names(journal)}
    return SimpleNamespace(res=res, result=json.loads((root / "sweep.json").read_text()),
                           states=states)


# --------------------------------------------------------------------------- the kinds


def test_each_target_is_its_kind(tracked, loaded):
    """The matrix tests what it says: CV returned each kind for its target."""
    from workbench import BaseBoostRegressor, PriorModel, StageChoiceCV
    from workbench.selection import BasisChoiceCV, CandidateMean

    result = tracked.result
    chosen = {t: c["chosen"] for t, c in result["candidates"].items()}
    assert chosen == {"y_mean": "mean of 2", "y_log": "log", "y_prior": "prior"}
    selected = dict(zip(result["targets"], result["model"]["selected"]))
    assert selected == {**{t: "boosted" for t in TARGETS}, "y_prior": "prior"}
    fitted = loaded.model.unwrap_python_model().model
    estimators = dict(zip(TARGETS, fitted.estimator_.estimators_))  # inside the conformal
    best = {t: e.best_estimator_ for t, e in estimators.items()}
    assert isinstance(best["y_mean"], CandidateMean)
    assert [m.link for m in best["y_mean"].members_] == ["identity", "log"]
    assert isinstance(estimators["y_prior"], BasisChoiceCV)
    assert isinstance(best["y_prior"], PriorModel)
    assert best["y_log"].link == "log" and best["y_ridge"].link == "identity"
    assert isinstance(best["y_stagewise"].basis, StageChoiceCV)
    assert len(best["y_stagewise"].estimators_) == 2
    assert all(isinstance(best[t], BaseBoostRegressor) for t in ("y_ridge", "y_log"))


# --------------------------------------------------------------------------- the paths


def check_evaluate(request, target):
    """The tracked run: metrics, predictions and intervals of the target."""
    t = request.getfixturevalue("tracked")
    metrics = t.run.data.metrics
    for name in ("test_mae", "cv_mae", "prior_test_mae", "test_coverage", "test_width"):
        assert np.isfinite(metrics[f"{name}/{target}"]), name
    cols = [target, f"{target}_lower", f"{target}_upper"]
    values = floats(t.logged[cols])
    assert np.isfinite(values).all() and (values[:, 1] < values[:, 0]).all()
    assert (values[:, 0] < values[:, 2]).all()


def check_learning_curve(request, target):
    t = request.getfixturevalue("tracked")
    curve = json.loads((t.artifacts / "learning_curves.json").read_text())[target]
    cv = np.array(curve["cv_error"], dtype=float)
    assert np.isfinite(cv).all() and not curve["fit_errors"], curve["fit_errors"]
    assert (t.artifacts / "plots" / f"learning_curve_{target}.png").stat().st_size > 0


def check_shap(request, target):
    t = request.getfixturevalue("tracked")
    for name in (f"shap_{target}", f"shap_correction_{target}"):
        assert (t.artifacts / "plots" / f"{name}.png").stat().st_size > 0, name


def check_bars(request, target):
    """The per-target bars: the target's test MAE as logged is the one of its
    predictions."""
    t = request.getfixturevalue("tracked")
    for name in ("mae_bars", "mse_bars"):
        assert (t.artifacts / "plots" / f"{name}.png").stat().st_size > 0
    j = TARGETS.index(target)
    measured = floats(text_csv(t.artifacts / "predictions" / "test_measured.csv")[[target]])
    mae = np.mean(np.abs(floats(t.logged[[target]]) - measured))
    assert t.result["model"]["test_mae"][j] == pytest.approx(mae, rel=1e-12)


def interval_rows(path: Path, target: str, around: bool = True) -> np.ndarray:
    """The target's test rows of an intervals table: predicted, lower, upper (``around``:
    each interval holds its prediction, as a symmetric one does; a CV+ interval need not)."""
    table = text_csv(path)
    rows = floats(table.loc[table["target"] == target, ["predicted", "lower", "upper"]])
    assert len(rows) and np.isfinite(rows).all() and (rows[:, 1] < rows[:, 2]).all()
    if around:
        assert (rows[:, 1] <= rows[:, 0]).all() and (rows[:, 0] <= rows[:, 2]).all()
    return rows


def check_intervals(request, target):
    """The intervals table holds the logged predictions and intervals of the target."""
    t = request.getfixturevalue("tracked")
    rows = interval_rows(t.artifacts / "intervals" / "test_intervals.csv", target)
    cols = [target, f"{target}_lower", f"{target}_upper"]
    np.testing.assert_allclose(rows, floats(t.logged[cols]), rtol=1e-12)
    j = TARGETS.index(target)
    assert 0 < t.result["model"]["test_coverage"][j] <= 1
    assert (t.artifacts / "plots" / "intervals.png").stat().st_size > 0


def check_predict(request, target):
    """``predict`` with the registered champion gives evaluate's test predictions and
    intervals exactly."""
    t = request.getfixturevalue("tracked")
    got = request.getfixturevalue("predicted")
    cols = [target, f"{target}_lower", f"{target}_upper"]
    np.testing.assert_array_equal(floats(got[cols]), floats(t.logged[cols]))


def check_serving(request, target):
    t = request.getfixturevalue("tracked")
    served = request.getfixturevalue("served")
    cols = [target, f"{target}_lower", f"{target}_upper"]
    np.testing.assert_array_equal(served[cols].to_numpy(), floats(t.logged[cols]))


def check_registry(request, target):
    """The registered version is the run's model, with its metrics."""
    t = request.getfixturevalue("tracked")
    version = t.client.get_model_version_by_alias("matrix", "champion")
    assert version.run_id == t.run_id
    j = TARGETS.index(target)
    assert t.run.data.metrics[f"test_mae/{target}"] == pytest.approx(
        t.result["model"]["test_mae"][j])


def check_no_track(request, target):
    """``--no-track``: the same model as the tracked run."""
    u = request.getfixturevalue("untracked")
    t = request.getfixturevalue("tracked")
    j = TARGETS.index(target)
    for key in ("test_mae", "cv_mae"):
        assert u.result["model"][key][j] == t.result["model"][key][j], key
    assert u.result["candidates"].get(target) == t.result["candidates"].get(target)


def check_out(request, target):
    """``--out DIR``, tracked and not: the intervals table (the tracked run's as logged) and
    figure."""
    t = request.getfixturevalue("tracked")
    u = request.getfixturevalue("untracked")
    logged = interval_rows(t.artifacts / "intervals" / "test_intervals.csv", target)
    tracked_out = t.root / "out_tracked"
    np.testing.assert_array_equal(interval_rows(tracked_out / "test_intervals.csv", target),
                                  logged)
    for out in (tracked_out, u.out):
        assert (out / "intervals.png").stat().st_size > 0


def check_cv_plus(request, target):
    """CV+ intervals (the untracked run's): around the same predictions, finite, and they
    hold most test rows."""
    t = request.getfixturevalue("tracked")
    u = request.getfixturevalue("untracked")
    rows = interval_rows(u.out / "test_intervals.csv", target, around=False)
    np.testing.assert_array_equal(rows[:, 0], floats(t.logged[[target]])[:, 0])
    j = TARGETS.index(target)
    assert u.result["model"]["test_coverage"][j] >= 0.5


def check_seeds(request, target):
    """``--random-states``: seed 0 is the evaluate of random_state 0; each seed's MAE finite."""
    s = request.getfixturevalue("seeds")
    t = request.getfixturevalue("tracked")
    j = TARGETS.index(target)
    runs = {r["random_state"]: r for r in s.result["runs"]}
    assert runs[0]["model"]["test_mae"][j] == t.result["model"]["test_mae"][j]
    assert np.isfinite(runs[1]["model"]["test_mae"][j])
    table = pd.read_csv(s.out / "seed_test_mae.csv")
    assert np.isfinite(table[target]).all() and len(table) == 2


def check_sweep(request, target):
    """The sweep: every trial of the target's studies completed (none failed on its
    kind), and the final model scores."""
    s = request.getfixturevalue("sweep")
    studies = {n: v for n, v in s.states.items() if n.startswith(f"matrix.{target}.")}
    assert len(studies) == 3  # 2 outer folds and the final study
    assert all(state in ("COMPLETE", "PRUNED") for v in studies.values() for state in v), \
        studies
    j = TARGETS.index(target)
    assert np.isfinite(s.result["nested_cv_mae"][j])
    assert np.isfinite(s.result["model"]["test_mae"][j])


PATHS = {"evaluate": check_evaluate, "learning_curve": check_learning_curve,
         "shap": check_shap, "bars": check_bars, "intervals": check_intervals,
         "predict": check_predict, "serving": check_serving, "registry": check_registry,
         "no_track": check_no_track, "out": check_out, "cv_plus": check_cv_plus,
         "seeds": check_seeds, "sweep": check_sweep}


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("kind", KINDS)
def test_kind_through_path(request, kind, path):
    PATHS[path](request, KINDS[kind])


def test_the_sweep_keeps_each_kind(sweep):
    """The sweep's final models are of the same kinds where its trials keep the lists of
    candidates (the mean of 2, the log link)."""
    chosen = {t: c["chosen"] for t, c in sweep.result["candidates"].items()}
    assert chosen["y_mean"] == "mean of 2" and chosen["y_log"] == "log"
