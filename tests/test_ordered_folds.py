"""Folds that follow the data's order: forward-chaining CV by a column of dates or run numbers.

LabelTimeSeriesSplit against scikit-learn's TimeSeriesSplit, equal values kept together, the
CSV's order column and its time split, the config's checks, what ``init`` finds and writes,
and an ``evaluate`` end to end whose every fold trains on earlier rows only.
"""

from __future__ import annotations

import contextlib
import io
import tomllib

import numpy as np
import pandas as pd
import pytest
from sklearn.model_selection import KFold, TimeSeriesSplit

from workbench.datasets import DatasetError, load_csv_dataset
from workbench.experiment.cli import main
from workbench.experiment.config import DataConfig, load_dataset
from workbench.experiment.process.errors import ConfigError
from workbench.experiment.runs.prepare import load_config, parse_config
from workbench.experiment.splits.folds import (
    describe_folds,
    largest_curve_size,
    make_folds,
    selection_cv,
    sweep_inner_cv,
)
from workbench.selection import LabelGroupKFold, LabelTimeSeriesSplit, ordered_splits


def write_csv(path, n=80, order="date", seed=0, **extra):
    """One target with its prior, two features and a drift in time the prior misses; two
    rows per date (``order="date"``), or a run number per row (``"run"``), or neither."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 2))
    prior = rng.normal(5, 1, n)
    frame = pd.DataFrame({"v1": x[:, 0], "v2": x[:, 1], "prior_E": prior,
                          "E": prior + 0.5 * np.sin(3 * x[:, 0]) + 0.01 * np.arange(n)
                          + rng.normal(0, 0.05, n)})
    if order == "date":
        frame.insert(0, "date", pd.date_range("2024-01-01", periods=n // 2, freq="D")
                     .repeat(2).strftime("%Y-%m-%d"))
    elif order == "run":
        frame.insert(0, "run_number", np.arange(100, 100 + n))
    for key, value in extra.items():
        frame[key] = value
    frame.to_csv(path, index=False)
    return path


def run(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()


# ---------------------------------------------------------------- the splitter


def test_distinct_values_give_time_series_split_s_folds():
    values = np.arange(23)
    for k in (2, 3, 5):
        ours = ordered_splits(values, k)
        theirs = list(TimeSeriesSplit(k).split(values))
        assert len(ours) == k
        for (a, b), (c, d) in zip(ours, theirs):
            np.testing.assert_array_equal(a, c)
            np.testing.assert_array_equal(b, d)


@pytest.mark.parametrize("seed", range(5))
def test_training_rows_are_earlier_and_equal_values_stay_together(seed):
    rng = np.random.default_rng(seed)
    values = rng.integers(0, 15, 60)  # many ties, rows in no order
    order = pd.Series(values, index=rng.permutation(1000)[:60], name="run")
    X = pd.DataFrame({"x": np.zeros(60)}, index=order.index)
    splits = list(LabelTimeSeriesSplit(order, 4).split(X))
    assert len(splits) == 4
    for train, test in splits:
        assert len(train) and len(test)
        assert values[train].max() < values[test].min()  # no later row in training
        assert not set(values[train]) & set(values[test])  # no value on both sides
    # forward chaining: each fold trains on every row before its block
    for (tr1, te1), (tr2, _) in zip(splits, splits[1:]):
        assert set(tr2) == set(tr1) | set(te1)


def test_rows_are_looked_up_by_label_on_any_subset():
    order = pd.Series(pd.to_datetime(["2024-01-03", "2024-01-01", "2024-01-02", "2024-01-05",
                                      "2024-01-04", "2024-01-06"]), index=list("abcdef"))
    X = pd.DataFrame({"x": range(4)}, index=["d", "b", "f", "c"])  # a subset, shuffled
    train, test = next(iter(LabelTimeSeriesSplit(order, 2).split(X)))
    assert list(X.index[train]) == ["b", "c"] and list(X.index[test]) == ["d"]
    with pytest.raises(ValueError, match="no order value"):
        next(LabelTimeSeriesSplit(order, 2).split(pd.DataFrame({"x": [0]}, index=["z"])))


def test_too_few_distinct_values_and_missing_values_are_errors():
    with pytest.raises(ValueError, match="2 distinct order value"):
        ordered_splits([1, 1, 1, 2, 2, 2], 3)
    with pytest.raises(ValueError, match="without an order value"):
        ordered_splits([1.0, np.nan, 2.0, 3.0], 2)


def test_the_folds_say_what_they_follow():
    order = pd.Series([1, 2], name="date")
    groups = pd.Series(["a", "b"], name="device")
    assert describe_folds(LabelTimeSeriesSplit(order, 5)) == "5 forward-chaining by `date`"
    assert describe_folds(LabelGroupKFold(groups, 5)) == "5 by groups `device`"
    assert describe_folds(KFold(5, shuffle=True, random_state=0)) == "5 shuffled"
    assert describe_folds(KFold(4)) == "4 contiguous"


# ---------------------------------------------------------------- the CSV and the config


def test_a_csv_s_dates_order_the_rows_and_split_off_the_latest(tmp_path):
    path = write_csv(tmp_path / "d.csv")
    ds = load_csv_dataset(path, prior=["prior_E"], targets=["E"], features=["v1", "v2"],
                          test_fraction=0.25, order_column="date", split="time")
    assert ds.order is not None and pd.api.types.is_datetime64_any_dtype(ds.order)
    assert "date" not in ds.feature_names and "date" not in ds.X.columns
    assert ds.order[ds.train_index].max() < ds.order[ds.test_index].min()
    assert len(ds.test_index) == 20
    # run numbers, and a random split: the order still reaches the folds
    runs = load_csv_dataset(write_csv(tmp_path / "r.csv", order="run"), prior=["prior_E"],
                            targets=["E"], test_fraction=0.25, order_column="run_number")
    assert runs.order.dtype == float and len(runs.test_index) == 20
    assert isinstance(make_folds(runs, 5), LabelTimeSeriesSplit)


def test_equal_times_at_the_cut_are_all_test_rows(tmp_path):
    path = write_csv(tmp_path / "d.csv", n=10)  # 5 dates, two rows each
    ds = load_csv_dataset(path, prior=["prior_E"], targets=["E"], test_fraction=0.3,
                          order_column="date", split="time")
    assert len(ds.test_index) == 4  # 3 rows asked, the cut's date kept whole
    assert not set(ds.order[ds.train_index]) & set(ds.order[ds.test_index])


@pytest.mark.parametrize("cells, message", [
    (None, r"missing column\(s\) \['when'\]"),
    (["2024-01-01"] * 9 + ["yesterday"], r"order column 'when' holds values that are neither "
                                         r"numbers nor dates .* at line 11"),
    (["2024-01-01"] * 9 + [""], r"order column 'when' is empty or NaN at line 11"),
    (["2024-01-01"] * 8 + ["NaN", "2024-02-01"], r"order column 'when' is empty or NaN at "
                                                 r"line 10"),
])
def test_a_bad_order_column_is_one_line_naming_it(tmp_path, cells, message):
    extra = {} if cells is None else {"when": cells}
    path = write_csv(tmp_path / "d.csv", n=10, order=None, **extra)
    with pytest.raises(DatasetError, match=message) as info:
        load_csv_dataset(path, prior=["prior_E"], targets=["E"], test_fraction=0.3,
                         order_column="when")
    assert "\n" not in str(info.value)


def _config(tmp_path, data=None, **tables):
    write_csv(tmp_path / "d.csv")
    raw = {"name": "t", "random_state": 0,
           "data": {"csv": "d.csv", "prior": ["prior_E"], "targets": ["E"],
                    "features": ["v1", "v2"], "test_fraction": 0.25, "split": "time",
                    "order_column": "date", **(data or {})},
           "model": {"basis": "ridge"}, "selection": {"cv": 4}, **tables}
    return parse_config(raw, tmp_path / "t.toml")


def test_the_config_round_trips_through_the_schema(tmp_path):
    cfg = _config(tmp_path)
    again = DataConfig.model_validate(cfg.data.model_dump())
    assert again == cfg.data and again.order_column == "date" and again.split == "time"
    ds = load_dataset(cfg)
    assert isinstance(selection_cv(cfg, ds), LabelTimeSeriesSplit)
    assert isinstance(sweep_inner_cv(cfg, ds), LabelTimeSeriesSplit)
    # the learning curves train on at most the smallest fold's rows: the first block's
    X = ds.X.loc[ds.train_index]
    assert largest_curve_size(selection_cv(cfg, ds), X) == len(X) // 5


@pytest.mark.parametrize("data, tables, message", [
    ({"order_column": None}, {}, "split = \"time\" tests on the latest test_fraction"),
    ({"group_column": "date"}, {}, "give group_column or order_column, not both"),
    ({"split": "devices"}, {}, "split = \"devices\" applies to source = \"ibm_gates\""),
    ({}, {"intervals": {"method": "cv_plus"}}, r"\[intervals\] method = 'cv_plus' needs every "
                                               r"training row"),
    ({}, {"evaluation": {"cv_repeats": 2}}, r"\[evaluation\] cv_repeats: its folds are "
                                            r"shuffled, and \[data\] order_column = 'date'"),
    ({}, {"evaluation": {"nested_folds": 3}}, r"\[evaluation\] nested_folds"),
    ({}, {"cv": {"repeats": 2}}, r"\[cv\] repeats = 2"),
    ({}, {"model": {"family": "hamiltonian"}}, "order_column = 'date': family = \"hamiltonian\""),
])
def test_settings_whose_folds_cannot_follow_the_order_are_one_line(tmp_path, data, tables,
                                                                   message):
    with pytest.raises(ConfigError, match=message) as info:
        _config(tmp_path, data, **tables)
    assert "\n" not in str(info.value)


def test_too_few_dates_for_the_folds_is_one_line(tmp_path):
    cfg = _config(tmp_path, selection={"cv": 4}, intervals={"enabled": False})
    write_csv(tmp_path / "d.csv", n=12)  # 6 dates, 4 in training: too few for 4 folds
    with pytest.raises(DatasetError, match="order column 'date': the 8 training rows hold 4 "
                                           "distinct value"):
        load_dataset(cfg)
    # the out-of-fold intervals calibrate on the rows the folds hold out, not the first block
    cfg = _config(tmp_path, selection={"cv": 2}, intervals={"alpha": 0.2})
    write_csv(tmp_path / "d.csv", n=16)  # 12 training rows, 4 never held out
    assert len(load_dataset(cfg).train_index) == 12
    cfg = _config(tmp_path, selection={"cv": 2}, intervals={"alpha": 0.1})
    write_csv(tmp_path / "d.csv", n=16)  # (_config wrote 80 rows)
    with pytest.raises(DatasetError, match=r"\[intervals\] method = 'oof': the forward-"
                                           r"chaining folds hold out 8 of the 12 training rows"):
        load_dataset(cfg)


# ---------------------------------------------------------------- init


@pytest.mark.parametrize("order, column, kind", [("date", "date", "dates"),
                                                 ("run", "run_number", "numbers")])
def test_init_finds_the_order_column_and_tests_on_the_latest_rows(tmp_path, order, column,
                                                                  kind):
    data = write_csv(tmp_path / "d.csv", order=order, device=["a", "b"] * 40)
    rc, out, err = run("init", data, "--prior", "prior_E", "--target", "E",
                       "--out", tmp_path / "c.toml")
    assert rc == 0, err
    assert f"order: found column {column!r} holds {kind}" in out
    assert "the test rows are the latest 24" in out
    # the device may group the rows instead (--group-column turns the order off); the time
    # column is no group
    assert "--group-column device" in out and f"--group-column {column}" not in out
    written = tomllib.loads((tmp_path / "c.toml").read_text())["data"]
    assert written["order_column"] == column and written["split"] == "time"
    assert "split_seed" not in written
    assert column not in written["features"]  # not a feature unless listed
    cfg = load_config(tmp_path / "c.toml")  # round trip through the project's parser
    assert cfg.data.order_column == column
    ds = load_dataset(cfg)
    assert ds.order[ds.train_index].max() < ds.order[ds.test_index].min()


def test_init_without_an_order_column_keeps_a_random_split(tmp_path):
    # a numeric column named like an order but not increasing is no order either
    data = write_csv(tmp_path / "d.csv", order=None,
                     time=np.random.default_rng(1).integers(0, 50, 80))
    rc, out, err = run("init", data, "--prior", "prior_E", "--target", "E",
                       "--out", tmp_path / "c.toml")
    assert rc == 0, err
    assert "order: no column of dates or run numbers found" in out
    written = tomllib.loads((tmp_path / "c.toml").read_text())["data"]
    assert "order_column" not in written and written["split_seed"] == 0
    assert "time" in written["features"]


def test_init_order_column_none_and_a_seed_keep_a_random_split(tmp_path):
    data = write_csv(tmp_path / "d.csv")
    rc, out, _ = run("init", data, "--prior", "prior_E", "--target", "E", "--order-column",
                     "none", "--out", tmp_path / "a.toml")
    assert rc == 0 and "order:" not in out
    assert "order_column" not in tomllib.loads((tmp_path / "a.toml").read_text())["data"]
    rc, out, _ = run("init", data, "--prior", "prior_E", "--target", "E", "--split-seed", "3",
                     "--out", tmp_path / "b.toml")
    written = tomllib.loads((tmp_path / "b.toml").read_text())["data"]
    assert rc == 0 and written["order_column"] == "date" and written["split_seed"] == 3
    assert "split" not in written and "latest" not in out


def test_init_with_a_bad_order_column_is_one_line(tmp_path):
    data = write_csv(tmp_path / "d.csv", order=None, when=["2024-01-01"] * 79 + ["soon"])
    rc, _, err = run("init", data, "--prior", "prior_E", "--target", "E", "--order-column",
                     "when", "--out", tmp_path / "c.toml")
    assert rc != 0 and not (tmp_path / "c.toml").exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "order column 'when'" in lines[0] and "line 81" in lines[0]


# ---------------------------------------------------------------- evaluate end to end


def test_evaluate_with_ordered_folds_trains_every_fold_on_earlier_rows(tmp_path):
    from workbench.experiment.runs.evaluate import evaluate, format_table
    from workbench.experiment.runs.intervals import family_model

    cfg = _config(tmp_path, model={"basis": ["ridge", "spline"]})
    done = evaluate(cfg, return_model=True)
    assert done.result.folds == "4 forward-chaining by `date`"
    assert "folds: 4 forward-chaining by `date`" in format_table(done.result)
    assert done.result.to_json()["folds"] == done.result.folds
    ds = done.dataset
    order = ds.order.loc[ds.train_index].to_numpy()
    (est,) = family_model(done.model).estimators_
    assert len(est.cv_splits_) == 4
    for train, test in est.cv_splits_:
        assert order[train].max() < order[test].min()
    # the earliest block is never held out: no out-of-fold prediction, and the intervals
    # calibrate on the others
    assert np.isnan(est.cv_predictions_prior_).sum() == len(order) // 5
    assert np.isfinite(done.result.model.cv_mae).all()


def test_a_sweep_s_outer_and_inner_folds_chain_forward(tmp_path):
    from workbench.experiment.sweep.search import inner_cv, outer_splits, study_names

    cfg = _config(tmp_path, cv={"outer_folds": 3, "inner_folds": 2},
                  search={"line_search_penalty": {"low": 0.0, "high": 0.5}})
    ds = load_dataset(cfg)
    order = ds.order.loc[ds.train_index].to_numpy()
    outer = outer_splits(cfg, len(order), ds)
    assert len(outer) == 3 == sum(s.fold is not None for s in study_names(cfg, ["E"]))
    for train, val in outer:
        assert order[train].max() < order[val].min()
        # an outer fold's training rows keep their labels: the inner folds chain on them
        X = ds.X.loc[ds.train_index].iloc[train]
        for inner_train, inner_val in inner_cv(cfg, ds).split(X):
            assert order[train][inner_train].max() < order[train][inner_val].min()


def _grouped(n_groups: int):
    from workbench.datasets import Dataset

    rng = np.random.default_rng(0)
    prior = pd.DataFrame({"p": rng.normal(size=40)})
    groups = pd.Series(np.arange(40) % n_groups, name="device")
    return Dataset(name="g", features=pd.DataFrame(index=prior.index), prior=prior,
                   targets=pd.DataFrame({"y": prior["p"] + 0.1}), groups=groups,
                   train_index=np.arange(30), test_index=np.arange(30, 40))


def test_fewer_training_groups_than_folds_hold_one_group_out_each():
    ds = _grouped(4)  # 4 devices, 5 folds asked for: 4 folds, one device held out in each
    with pytest.warns(UserWarning, match="4 groups of `device`, fewer than the 5 folds"):
        folds = make_folds(ds, 5, groups=True)
    X = ds.prior.loc[ds.train_index]
    splits = list(folds.split(X))
    assert len(splits) == 4
    for train, test in splits:
        assert len(set(ds.groups.iloc[test])) == 1
        assert not set(ds.groups.iloc[train]) & set(ds.groups.iloc[test])
    assert make_folds(_grouped(8), 5, groups=True).n_splits == 5
    with pytest.raises(ConfigError, match="1 group\\(s\\) of `device`: grouped folds need at "
                                          "least 2"):
        make_folds(_grouped(1), 5, groups=True)
