"""Search spaces (workbench.experiment.config.space): every basis family's conditional
parameters are sampled and give a model that fits; bad spaces name the entry."""

from pathlib import Path

import numpy as np
import optuna
import pytest
from optuna.trial import FixedTrial

from workbench.bases import BASES
from workbench.experiment.config.space import SearchSpace, SpaceError
from workbench.experiment.families.stage import make_booster
from workbench.experiment.runs.prepare import load_config

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def test_paper_search_space_samples_every_basis_family_and_fits():
    cfg = load_config(EXPERIMENTS / "paper_search.toml")
    base = cfg.model_for("eeig1")
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    rng = np.random.default_rng(0)
    X = rng.normal(size=(40, 3))
    X[:, 0] *= 5
    y = X[:, 0] + np.sin(X[:, 1])
    seen = {}
    for _ in range(60):
        trial = study.ask()
        settings = cfg.search.sample(trial, base)
        seen.setdefault(settings["basis"], settings)
        study.tell(trial, 0.0)
    assert set(seen) == set(cfg.search.table["basis"])
    for name, settings in seen.items():
        specs = cfg.search.table["basis_params"][name]
        assert set(specs) <= set(settings["basis_params"]), name
        booster = make_booster(settings, prior=0, inputs=[0, 1, 2])
        booster.set_params(random_state=0).fit(X, y)
        assert np.all(np.isfinite(booster.predict(X))), name


def test_fixed_trial_rebuilds_a_finished_trials_settings():
    space = SearchSpace.from_table({"basis": ["ridge", "paper_stacking"], "n_stages": {
        "low": 1, "high": 3}, "basis_params": {"paper_stacking": {"mlp_alpha": {
            "low": 1.0, "high": 20.0}}}})
    base = {"basis": "ridge", "basis_params": {}, "n_stages": 1, "input_transform": "none",
            "input_transform_params": {}}
    settings = space.sample(FixedTrial({"basis": "paper_stacking", "n_stages": 2,
                                        "paper_stacking.mlp_alpha": 7.5}), base)
    assert settings["basis"] == "paper_stacking" and settings["n_stages"] == 2
    assert settings["basis_params"] == {"mlp_alpha": 7.5}
    booster = make_booster({**settings, "loss": "squared_error",
                            "line_search_loss": "absolute_error", "line_search_penalty": 0.1,
                            "alpha": 0.9}, prior=0, inputs=None)
    assert booster.basis.get_params()["mlp__alpha"] == 7.5  # reaches the stacking's MLP
    ridge = space.sample(FixedTrial({"basis": "ridge", "n_stages": 1}), base)
    assert ridge["basis_params"] == {}  # paper_stacking's parameters are not sampled


@pytest.mark.parametrize("table, match", [
    ({"basis": ["ridge", "rigde"]}, r"basis: unknown value\(s\) \['rigde'\]"),
    ({"basis": []}, "basis: empty choice list"),
    ({"n_stages": {"low": 3, "high": 1}}, "low 3 is above high 1"),
    ({"alpha": {"low": 0, "high": 1, "log": True}}, "a log range needs low > 0"),
    ({"n_stages": {"low": 1}}, "a range needs low and high"),
    ({"depth": [1, 2]}, r"unknown key\(s\) \['depth'\]"),
    ({"basis_params": {"forest": {"n": [1]}}}, "basis_params.forest: unknown basis"),
    ({"basis_params": {"ridge": 3}}, "basis_params.ridge must be a table"),
    ({"loss": {"low": 0, "high": 1}}, "loss: unknown value"),
    # the numeric boosting settings: BaseBoostRegressor's constraints
    ({"n_stages": {"low": 0, "high": 3}}, r"n_stages = 0: The 'n_stages' parameter of "
                                          r"BaseBoostRegressor must be an int in the range "
                                          r"\[1, inf\)"),
    ({"n_stages": {"low": 1.0, "high": 3.0}}, r"n_stages = 1\.0: .* must be an int"),
    ({"alpha": [0.5, 1.0]}, r"alpha = 1\.0: The 'alpha' parameter of BaseBoostRegressor"),
    ({"line_search_penalty": -0.1}, r"line_search_penalty = -0\.1: .*\[0\.0, inf\)"),
])
def test_bad_spaces_name_the_entry(table, match):
    with pytest.raises(SpaceError, match=match):
        SearchSpace.from_table(table)


def test_every_registered_basis_can_be_searched():
    space = SearchSpace.from_table({"basis": list(BASES)})
    assert space.table["basis"] == list(BASES)
