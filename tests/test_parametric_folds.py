"""The parametric family's own CVs follow the data (issue 41): its covariate selection, its
choice among prior / calibrated / drift and its out-of-fold priors chain forward by ``[data]
order_column`` and keep ``[data] group_column``'s groups whole, as BaseBoostCV's folds do;
without either, its folds are what they were (shuffled K-fold, seeded by ``random_state``)."""

import numpy as np
import pandas as pd
import pytest
from sklearn.model_selection import KFold

from workbench.experiment.process.errors import ConfigError
from workbench.experiment.runs.prepare import load_config, prepare
from workbench.selection import LabelGroupKFold, LabelTimeSeriesSplit

DECAY = """import numpy as np

PARAMETERS = {"amplitude": 2.0, "tau": 1.0, "offset": 0.0}


def predict(params, data):
    t = data["t"].to_numpy()
    return params["amplitude"] * np.exp(-t / params["tau"]) + params["offset"]
"""


def _write(tmp_path, extra_data="", extra="", n=72):
    """A decay whose lifetime drifts with temp, a run number and a device per row."""
    rng = np.random.default_rng(0)
    t, temp = rng.uniform(0, 3, n), rng.normal(size=n)
    y = 2.5 * np.exp(-t / (1.5 + 0.3 * temp)) + 0.1 + rng.normal(0, 0.01, n)
    pd.DataFrame({"run": rng.permutation(n), "device": [f"d{k % 6}" for k in range(n)],
                  "t": t, "temp": temp, "y": y}).to_csv(tmp_path / "decay.csv", index=False)
    (tmp_path / "models").mkdir(exist_ok=True)
    (tmp_path / "models" / "decay.py").write_text(DECAY)
    config = tmp_path / "c.toml"
    config.write_text('random_state = 0\n[data]\ncsv = "decay.csv"\ntargets = ["y"]\n'
                      'features = ["t", "temp"]\ntest_fraction = 0.25\n' + extra_data +
                      '[model]\nfamily = "parametric"\nbasis = "ridge"\n'
                      '[selection]\ncv = 3\n[model.parametric]\nmodel = "models/decay.py"\n'
                      'loss = "squared_error"\nmax_steps = 1\nproducts = false\n'
                      'squares = false\nprior_cv = 3\nselection_cv = 3\n' + extra)
    return config


def _fit(config, monkeypatch):
    """Build and fit the family's model on the training rows; record the out-of-fold
    priors' refits (training and held-out row labels)."""
    import workbench.fitted_prior as fitted_prior

    refits = []
    original = fitted_prior._fold_prediction

    def spy(model, fit_params, X, Y, train, val):
        refits.append((X.index[train], X.index[val]))
        return original(model, fit_params, X, Y, train, val)

    monkeypatch.setattr(fitted_prior, "_fold_prediction", spy)
    run = prepare(load_config(config))
    cfg, ds, family = run.config, run.dataset, run.family
    X = family.inputs(cfg, ds).loc[ds.train_index]
    model = family.build(cfg, ds).set_params(n_jobs=1)  # the spy runs in this process
    model.fit(X, ds.targets.loc[ds.train_index])
    return cfg, ds, family, X, model, refits


def test_an_order_column_chains_every_parametric_cv_forward(tmp_path, monkeypatch):
    config = _write(tmp_path, 'order_column = "run"\n')
    cfg, ds, family, X, model, refits = _fit(config, monkeypatch)
    order = ds.order.loc[X.index]
    physics = model.physics_
    assert isinstance(physics.cv, LabelTimeSeriesSplit) and isinstance(model.cv,
                                                                       LabelTimeSeriesSplit)
    # the selection and the choice: every validation row after every row it was fitted on
    assert len(physics.cv_splits_) == 3
    for fit, val in physics.cv_splits_:
        assert order.iloc[fit].max() < order.iloc[val].min()
    # the out-of-fold priors: each fold's refit saw earlier rows only; the earliest block,
    # held out by none, is refitted on itself (no later row reaches its prior)
    *folds, (own_fit, own_val) = refits
    assert len(folds) == 3
    for fit, val in folds:
        assert order.loc[fit].max() < order.loc[val].min()
    assert list(own_fit) == list(own_val)
    assert order.loc[own_val].max() < min(order.loc[val].min() for _, val in folds)
    assert (model.prior_folds_[X.index.get_indexer(own_val)] == -1).all()
    # the stage on top too, and the table says which folds were used
    (stage,) = model.boost_.estimators_
    for fit, val in stage.cv_splits_:
        assert order.iloc[fit].max() < order.iloc[val].min()
    assert family.folds_used(cfg, ds) == "3 forward-chaining by `run`"


def test_repeats_are_refused_where_the_folds_follow_the_data(tmp_path):
    config = _write(tmp_path, 'order_column = "run"\n', "selection_repeats = 2\n")
    run = prepare(load_config(config))
    with pytest.raises(ConfigError, match="selection_repeats = 2") as err:
        run.family.build(run.config, run.dataset)
    assert "\n" not in str(err.value) and "forward-chaining by `run`" in str(err.value)


def test_groups_are_kept_whole_in_every_parametric_cv(tmp_path, monkeypatch):
    config = _write(tmp_path, 'group_column = "device"\n')
    cfg, ds, family, X, model, refits = _fit(config, monkeypatch)
    groups = ds.groups.loc[X.index]
    assert isinstance(model.physics_.cv, LabelGroupKFold)
    assert isinstance(model.cv, LabelGroupKFold)
    for fit, val in model.physics_.cv_splits_:
        assert not set(groups.iloc[fit]) & set(groups.iloc[val])
    assert len(refits) == 3  # every row held out once: no refit on itself
    for fit, val in refits:
        assert not set(groups.loc[fit]) & set(groups.loc[val])
    assert family.folds_used(cfg, ds) == "3 by groups `device`"


def test_without_an_order_or_groups_the_folds_are_unchanged(tmp_path, monkeypatch):
    """The selection's folds stay the estimator's own repeated shuffled K-fold (an int
    ``cv``), the out-of-fold priors' a shuffled KFold seeded by random_state: the splits the
    family made before its folds followed the data."""
    from sklearn.model_selection import RepeatedKFold

    config = _write(tmp_path, extra="selection_repeats = 2\n")
    cfg, ds, family, X, model, refits = _fit(config, monkeypatch)
    physics = model.physics_
    assert physics.cv == 3 and physics.n_repeats == 2
    old = list(RepeatedKFold(n_splits=3, n_repeats=2, random_state=0).split(np.arange(len(X))))
    assert len(physics.cv_splits_) == 6
    for (a, b), (c, d) in zip(physics.cv_splits_, old, strict=True):
        np.testing.assert_array_equal(a, c)
        np.testing.assert_array_equal(b, d)
    assert isinstance(model.cv, KFold) and model.cv.shuffle
    old_prior = list(KFold(3, shuffle=True, random_state=0).split(X))
    for (fit, val), (c, d) in zip(refits, old_prior, strict=True):
        assert list(fit) == list(X.index[c]) and list(val) == list(X.index[d])
    assert family.folds_used(cfg, ds) == ("stage 3 contiguous; parametric choice 3 shuffled x "
                                          "2 repeats; out-of-fold priors 3 shuffled")


def test_a_splitter_s_folds_are_the_repeated_k_fold_s_first_repeat():
    """The core estimator takes a splitter as its cv: a shuffled KFold seeded as the int
    cv's RepeatedKFold makes the same folds, so the same choice and predictions."""
    from workbench.parametric import ParametricModel
    from workbench.parametric_boost import ParametricBoostRegressor

    rng = np.random.default_rng(1)
    X = pd.DataFrame({"t": rng.uniform(0, 3, 40), "temp": rng.normal(size=40)},
                     index=rng.permutation(1000)[:40])
    y = 2.5 * np.exp(-X["t"] / (1.5 + 0.3 * X["temp"])) + rng.normal(0, 0.01, 40)
    model = ParametricModel.from_functions(
        {"amplitude": 2.0, "tau": 1.0},
        lambda p, d: p["amplitude"] * np.exp(-d["t"].to_numpy() / p["tau"]))
    common = dict(model=model, features=["temp"], squares=False, products=False,
                  max_steps=1, loss="squared_error", random_state=3)
    by_int = ParametricBoostRegressor(cv=4, **common).fit(X, y)
    by_splitter = ParametricBoostRegressor(
        cv=KFold(4, shuffle=True, random_state=3), **common).fit(X, y)
    pd.testing.assert_frame_equal(by_int.choices_, by_splitter.choices_)
    np.testing.assert_array_equal(by_int.predict(X), by_splitter.predict(X))
    with pytest.raises(ValueError, match="n_repeats = 2"):
        ParametricBoostRegressor(cv=KFold(4), n_repeats=2, **common).fit(X, y)


def test_the_outside_benchmark_s_order_flag_writes_the_order_column(tmp_path):
    """benchmarks/parametric_outside.py --order Z: init's --order-column, a number that is no
    time (the direction the test nuclei lie in) is an order column, Z still a feature."""
    import importlib
    import sys
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    if str(root / "benchmarks") not in sys.path:
        sys.path.insert(0, str(root / "benchmarks"))
    bench = importlib.import_module("parametric_outside")
    csv = tmp_path / "nuclides.csv"
    pd.DataFrame({"Z": np.arange(8, 28), "N": [8, 9, 10, 12] * 5,
                  "mass_excess_MeV": np.arange(20.0),
                  "split": ["train"] * 15 + ["test"] * 5}).to_csv(csv, index=False)
    (tmp_path / bench.MODEL.name).write_text(bench.MODEL.read_text())
    zn = ["Z", "N"]  # this CSV's features (the benchmark's field names six)
    data = tomllib.loads(bench.init_config(tmp_path, csv, order="Z", features=zn)
                         .read_text())["data"]
    assert data["order_column"] == "Z" and data["features"] == ["Z", "N"]
    assert "order_column" not in tomllib.loads(bench.init_config(tmp_path, csv, features=zn)
                                               .read_text())["data"]


def test_the_folds_line_names_only_the_cvs_a_run_uses(tmp_path):
    """Without a stage, the stage's folds are not named; the priors' only where the
    out-of-fold intervals need them."""
    config = _write(tmp_path, extra="boost_stage = false\nselection_repeats = 2\n")
    run = prepare(load_config(config))
    assert run.family.folds_used(run.config, run.dataset) == (  # oof intervals: the priors
        "parametric choice 3 shuffled x 2 repeats; out-of-fold priors 3 shuffled")
    config.write_text(config.read_text() + "[intervals]\nenabled = false\n")
    run = prepare(load_config(config))
    assert run.family.folds_used(run.config, run.dataset) == "3 shuffled x 2 repeats"
