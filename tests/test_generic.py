"""The recommended generic config's parts: losses and drawn basis settings as CV candidates
(``[model] loss = [...]``, ranges in ``[model.basis_params.<basis>]`` with ``draws``), and
experiments/generic.toml itself."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.experiment.config import ConfigError
from workbench.experiment.config.space import draw_params
from workbench.experiment.families.stage import candidate_settings, has_candidates
from workbench.experiment.runs.prepare import load_config
from workbench.selection import BasisChoiceCV

ROOT = Path(__file__).resolve().parents[1]
LGBM_RANGES = ('[model.basis_params.lightgbm]\n'
               'n_estimators = { low = 10, high = 80, log = true }\n'
               'learning_rate = { low = 0.05, high = 0.3, log = true }\n'
               'subsample = { low = 0.5, high = 1.0 }\nsubsample_freq = 1\n')


def _config(tmp_path: Path, model: str, data: str | None = None) -> Path:
    path = tmp_path / "c.toml"
    path.write_text(f"name = \"c\"\nrandom_state = 3\n{data or ''}\n[model]\n{model}")
    return path


def test_draws_are_seeded_inside_their_ranges() -> None:
    params = {"n": {"low": 10, "high": 80, "log": True}, "lr": {"low": 0.05, "high": 0.3},
              "step": {"low": 0.0, "high": 1.0, "step": 0.25}, "fixed": 1, "kept": [4, 8]}
    a, b = draw_params(params, 50, 7), draw_params(params, 50, 7)
    assert a == b and a != draw_params(params, 50, 8)
    assert all(10 <= d["n"] <= 80 and isinstance(d["n"], int) for d in a)
    assert all(0.05 <= d["lr"] <= 0.3 for d in a)
    assert {d["step"] for d in a} <= {0.0, 0.25, 0.5, 0.75, 1.0}
    assert all(d["fixed"] == 1 and d["kept"] == [4, 8] for d in a)  # a list is a value
    assert len({d["n"] for d in a}) > 10  # spread over the range, log-uniform
    assert np.median([d["n"] for d in a]) < 45


def test_choices_are_drawn_too() -> None:
    from workbench.experiment.config.space import check_ranges

    params = {"objective": {"choices": ["regression", "regression_l1", "huber"]},
              "n": {"low": 1, "high": 9}, "fixed": [4, 8]}
    drawn = draw_params(params, 60, 0)
    assert {d["objective"] for d in drawn} == {"regression", "regression_l1", "huber"}
    assert all(d["fixed"] == [4, 8] for d in drawn)
    # the settings validated against the basis: each choice, each end of each range
    ends = check_ranges("lightgbm", params)
    assert [e["objective"] for e in ends] == ["regression", "regression_l1", "huber"]
    assert [e["n"] for e in ends] == [1, 9, 9]


def test_candidates_are_bases_draws_and_losses(tmp_path: Path) -> None:
    cfg = load_config(_config(tmp_path, 'basis = ["ridge", "lightgbm"]\n'
                              'loss = ["squared_error", "huber"]\ndraws = 3\n' + LGBM_RANGES))
    s = cfg.model_for("t")
    assert has_candidates(s)
    cands = candidate_settings(s, cfg.random_state)
    assert [n for n, _ in cands] == [
        "ridge/squared_error", "ridge/huber", *(f"lightgbm#{i:02d}/{loss}" for i in range(3)
                                                for loss in ("squared_error", "huber"))]
    drawn = [c["basis_params"] for n, c in cands if n.startswith("lightgbm")]
    assert drawn[0] == drawn[1] and drawn[0] != drawn[2]  # one draw, every loss
    assert candidate_settings(s, cfg.random_state) == cands  # the seed decides
    assert all(c["basis_params"] == {} for n, c in cands if n.startswith("ridge"))
    # one basis with ranges, one loss: the draws alone
    one = load_config(_config(tmp_path, 'basis = "lightgbm"\ndraws = 2\n'
                              + LGBM_RANGES.replace("basis_params.lightgbm", "basis_params")))
    assert [n for n, _ in candidate_settings(one.model_for("t"), 0)] == \
        ["lightgbm#00", "lightgbm#01"]
    plain = load_config(_config(tmp_path, 'basis = "ridge"\n'))
    assert not has_candidates(plain.model_for("t"))


def test_line_search_losses_are_candidates_too(tmp_path: Path) -> None:
    """``line_search_loss`` as a list: every basis and loss with each, named ``line:<loss>``
    (the stage loss and the line-search loss can share a name)."""
    cfg = load_config(_config(tmp_path, 'basis = "ridge"\nloss = ["squared_error", "huber"]\n'
                              'line_search_loss = ["absolute_error", "huber"]\n'))
    s = cfg.model_for("t")
    assert has_candidates(s)
    cands = candidate_settings(s, cfg.random_state)
    assert [n for n, _ in cands] == [
        "squared_error/line:absolute_error", "squared_error/line:huber",
        "huber/line:absolute_error", "huber/line:huber"]
    assert [(c["loss"], c["line_search_loss"]) for _, c in cands] == [
        ("squared_error", "absolute_error"), ("squared_error", "huber"),
        ("huber", "absolute_error"), ("huber", "huber")]
    with pytest.raises(ConfigError, match="line_search_loss"):
        load_config(_config(tmp_path, 'line_search_loss = ["absolute_error", "bogus"]\n'))


@pytest.mark.parametrize("model, message", [
    ('loss = ["huber", "huber"]', "distinct loss"),
    ('loss = ["huber", "bogus"]', "loss"),
    ('basis = "lightgbm"\n[model.basis_params]\nn_estimators = { low = 0, high = 5 }',
     "n_estimators"),
    ('basis = "lightgbm"\n[model.basis_params]\nlearning_rate = { low = 0.3, high = '
     '0.1 }', "low 0.3 is above high 0.1"),
    ('basis = "lightgbm"\n[model.basis_params]\nlearning_rate = { low = 0.1 }',
     "a range needs low and high"),
    ('basis = "lightgbm"\ndraws = 0', "draws"),
])
def test_bad_candidates_are_refused(tmp_path: Path, model: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as exc:
        load_config(_config(tmp_path, model))
    assert len(str(exc.value).splitlines()) == 1 and len(str(exc.value)) < 300


def test_the_loss_that_fits_heavy_tails_is_chosen(tmp_path: Path) -> None:
    """Outliers in the targets: CV prefers the Huber loss over the squared one."""
    rng = np.random.default_rng(0)
    n = 300
    x = rng.uniform(-2, 2, n)
    prior = 2 * x
    y = prior + 0.5 * x + 0.05 * rng.standard_normal(n)
    wild = rng.random(n) < 0.1
    y[wild] += rng.choice([-8.0, 8.0], wild.sum())
    frame = pd.DataFrame({"x": x, "prior": prior, "y": y,
                          "split": np.where(np.arange(n) < 240, "train", "test")})
    frame.to_csv(tmp_path / "d.csv", index=False)
    data = ('[data]\ncsv = "d.csv"\nprior = ["prior"]\ntargets = ["y"]\nfeatures = ["x"]\n'
            'split_column = "split"\n[selection]\ncv = 5\nshuffle = true\n')
    cfg = load_config(_config(tmp_path, 'basis = "ridge"\nbasis_inputs = "prior+features"\n'
                                        'loss = ["squared_error", "huber"]\n'
                                        'line_search_penalty = 0.0\n', data))
    from workbench.experiment.config import load_dataset

    ds = load_dataset(cfg)
    model = cfg.family.build(cfg, ds)
    X_train, _, y_train, _ = ds.split()
    model.fit(X_train, y_train)
    (est,) = model.estimators_
    assert isinstance(est, BasisChoiceCV) and est.selected_candidate_ == "huber"


def test_generic_config_is_the_init_template() -> None:
    """experiments/generic.toml is the recommended config: its sections besides [data] are
    what `workbench init` writes."""
    import tomllib

    cfg = load_config(ROOT / "experiments" / "generic.toml")
    assert cfg.data.source == "ibm_gates" and cfg.data.split == "time"
    s = cfg.model_for("gate_error")
    assert s["basis"] == ["ridge", "lightgbm"] and s["loss"] == "squared_error"
    assert s["link"] == ["identity", "log"]
    names = [n for n, _ in candidate_settings(s, cfg.random_state)]
    assert names == [f"{b}/{link}" for b in ["ridge", *(f"lightgbm#{i:02d}"
                                                        for i in range(s["draws"]))]
                     for link in ("identity", "log")]
    assert cfg.selection.groups and cfg.selection.shuffle and cfg.selection.ensemble == 5
    template = ROOT / "workbench" / "experiment" / "templates" / "generic.toml"
    ours = tomllib.loads((ROOT / "experiments" / "generic.toml").read_text())
    theirs = tomllib.loads(template.read_text())  # what `workbench init` writes
    assert {k: v for k, v in ours.items() if k not in ("data", "name", "random_state")} \
        == theirs


def test_label_group_kfold_holds_whole_groups_out() -> None:
    from sklearn.base import clone

    from workbench.selection import LabelGroupKFold

    labels = np.arange(100, 160)
    groups = pd.Series(np.repeat(list("abcdefghij"), 6), index=labels)
    X = pd.DataFrame({"x": np.arange(60.0)}, index=labels)
    cv = LabelGroupKFold(groups, 5, shuffle=True, random_state=0)
    assert cv.get_n_splits() == 5
    copied = clone(BasisChoiceCV([], cv=cv)).cv  # an estimator's clone copies its splitter
    assert copied.n_splits == 5 and copied.groups.equals(groups)
    splits = list(cv.split(X))
    assert len(splits) == 5
    for train, test in splits:  # positions in X; no group on both sides
        assert not set(groups.iloc[train]) & set(groups.iloc[test])
    assert sorted(np.concatenate([t for _, t in splits])) == list(range(60))
    assert [t.tolist() for _, t in splits] == [t.tolist() for _, t in cv.split(X)]  # seeded
    subset = X.iloc[::2]  # any subset of the dataset: the groups follow the labels
    for train, test in cv.split(subset):
        assert not set(groups.loc[subset.index[train]]) & set(groups.loc[subset.index[test]])
    with pytest.raises(ValueError, match="2 group.*fewer than the 5 folds"):
        list(cv.split(X.iloc[:12]))
    with pytest.raises(ValueError, match="have no group"):
        list(cv.split(pd.DataFrame({"x": [1.0]}, index=[7])))
    with pytest.raises(TypeError, match="DataFrame"):
        list(cv.split(np.zeros((60, 1))))


def test_a_dataset_with_groups_gets_grouped_folds(tmp_path: Path, ibm_gates_dir: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    from workbench.experiment.config import load_dataset
    from workbench.selection import LabelGroupKFold

    monkeypatch.setenv("WORKBENCH_IBM_DATA_DIR", str(ibm_gates_dir))
    data = '[data]\nsource = "ibm_gates"\n[selection]\ncv = 5\nshuffle = true\n'
    cfg = load_config(_config(tmp_path, 'basis = "ridge"\n', data))
    ds = load_dataset(cfg)
    est = cfg.family.build(cfg, ds).target_estimators["gate_error"]
    assert isinstance(est.cv, LabelGroupKFold) and est.cv.groups is ds.groups
    X_train = ds.split()[0]
    for train, test in est.cv.split(X_train):
        assert not set(ds.groups[X_train.index[train]]) & set(ds.groups[X_train.index[test]])
    plain = load_config(_config(tmp_path, 'basis = "ridge"\n', data + "groups = false\n"))
    assert not isinstance(plain.family.build(plain, ds).target_estimators["gate_error"].cv,
                          LabelGroupKFold)


def test_csv_group_column(tmp_path: Path) -> None:
    from workbench.datasets import DatasetError
    from workbench.experiment.config import load_dataset
    from workbench.selection import LabelGroupKFold

    rng = np.random.default_rng(1)
    n = 80
    frame = pd.DataFrame({"x": rng.normal(size=n), "prior": rng.normal(size=n),
                          "device": [f"dev {i % 8}" for i in range(n)]})
    frame["y"] = frame["prior"] + 0.3 * frame["x"]
    frame.to_csv(tmp_path / "d.csv", index=False)
    data = ('[data]\ncsv = "d.csv"\nprior = ["prior"]\ntargets = ["y"]\nfeatures = ["x"]\n'
            'test_fraction = 0.25\ngroup_column = "device"\n')
    cfg = load_config(_config(tmp_path, 'basis = "ridge"\n', data))
    ds = load_dataset(cfg)
    assert ds.groups is not None and set(ds.groups) == {f"dev {i}" for i in range(8)}
    est = cfg.family.build(cfg, ds).target_estimators["y"]
    assert isinstance(est.cv, LabelGroupKFold)
    frame.loc[5, "device"] = " "
    frame.to_csv(tmp_path / "d.csv", index=False)
    with pytest.raises(DatasetError, match="group column 'device' is empty at line 7"):
        load_dataset(cfg)
    twice = load_config(_config(tmp_path, 'basis = "ridge"\n',
                                data.replace('group_column = "device"', 'group_column = "x"')))
    with pytest.raises(DatasetError, match="group column 'x' is also named"):
        load_dataset(twice)
