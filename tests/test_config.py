"""Tests for experiment configs: loading, checking and turning them into models."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest
from sklearn.ensemble import StackingRegressor
from sklearn.linear_model import Ridge
from sklearn.model_selection import KFold

from workbench.bases import BASES, PAPER_PARAMS, TRANSFORMS, NormalQuantileTransformer
from workbench.boosting import BaseBoostRegressor
from workbench.experiment.config import ConfigError, load_dataset
from workbench.experiment.runs.prepare import load_config
from workbench.losses import LOSSES
from workbench.multitarget import MultiTargetBaseBoost
from workbench.selection import BaseBoostCV

PAPER_TOML = Path(__file__).resolve().parents[1] / "experiments" / "paper_main_body.toml"
TARGETS = [f"eeig{i}" for i in range(1, 6)]
PRIORS = [f"peig{i}" for i in range(1, 6)]
VOLTAGES = [f"qvolt{i}" for i in range(5, 10)] + [f"cvolt{i}" for i in range(5, 9)]


def _toml_str(value) -> str:
    return json.dumps(str(value))  # a JSON string is a valid TOML basic string


def write_config(tmp_path: Path, model: str = 'basis = "ridge"', *, extra: str = "",
                 data: str | None = None, top: str = "", name: str = "cfg.toml") -> Path:
    """A cheap config file: ``top`` lines, ``[data]``, ``[model]`` with ``model``, then
    ``extra``."""
    data = data if data is not None else 'source = "google_5q"'
    text = (f'name = "t"\nrandom_state = 0\n{top}\n[data]\n{data}\n\n[model]\n{model}\n\n'
            f"{extra}\n")
    path = tmp_path / name
    path.write_text(text)
    return path


def build_model(cfg, ds):
    return cfg.family.build(cfg, ds)


def _tuples(params: dict) -> dict:
    return {k: tuple(v) if isinstance(v, list) else v for k, v in params.items()}


def _valid_names_listed(message: str, names) -> bool:
    return all(re.search(rf"\b{re.escape(n)}\b", message) for n in names)


# --- the paper config ---------------------------------------------------------------------

def test_paper_config_loads_with_expected_settings():
    cfg = load_config(PAPER_TOML)
    assert cfg.name == "paper_main_body"
    assert cfg.random_state == 0
    assert cfg.data.source == "google_5q"
    assert set(cfg.model.targets) == set(TARGETS)
    assert cfg.selection.cv == 5 and cfg.selection.shuffle is False
    for target in TARGETS:
        s = cfg.model_for(target)
        assert s["basis"] == "paper_stacking"
        assert s["n_stages"] == 1
        assert s["loss"] == "squared_error"
        assert s["line_search_loss"] == "absolute_error"
        assert s["basis_inputs"] == "prior"
        assert s["input_transform"] == "quantile_normal"


@pytest.mark.parametrize("j", range(1, 6))
def test_paper_config_basis_params_match_paper_table(j):
    """Guards the TOML against drifting from ``PAPER_PARAMS`` in code."""
    cfg = load_config(PAPER_TOML)
    assert _tuples(cfg.model_for(f"eeig{j}")["basis_params"]) == PAPER_PARAMS[f"Y{j}"]


# --- errors -------------------------------------------------------------------------------

def test_missing_file(tmp_path):
    missing = tmp_path / "nope.toml"
    with pytest.raises(ConfigError, match=r"config file not found: .*nope\.toml"):
        load_config(missing)


def test_invalid_toml(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('name = "x"\n[model\nbasis = "ridge"\n')
    with pytest.raises(ConfigError, match=r"bad\.toml.*not valid TOML"):
        load_config(path)


@pytest.mark.parametrize("where, kwargs, section", [
    ("top", dict(top="bogus_top = 1"), None),
    ("data", dict(data='source = "google_5q"\nbogus_data = 1'), r"\[data\]"),
    ("model", dict(model='basis = "ridge"\nbogus_model = 1'), r"\[model\]"),
    ("selection", dict(extra="[selection]\nbogus_selection = 1"), r"\[selection\]"),
    ("target", dict(extra="[model.targets.eeig2]\nbogus_target = 1"),
     r"\[model\.targets\.eeig2\]"),
], ids=["top", "data", "model", "selection", "target"])
def test_unknown_keys(tmp_path, where, kwargs, section):
    path = write_config(tmp_path, **kwargs)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    msg = str(info.value)
    assert f"bogus_{where}" in msg
    assert "valid keys are" in msg
    if section:
        assert re.search(section, msg), msg
    # the valid keys of that section are listed
    expected = {"top": ["name", "random_state", "model", "selection"],
                "data": ["source", "data_dir"],
                # (alphabetical; the listing is shortened, "... (N in all)")
                "model": ["alpha", "basis", "basis_inputs", "basis_params", "family"],
                "selection": ["cv", "shuffle", "scoring"],
                "target": ["basis", "basis_params", "input_transform"]}[where]
    assert _valid_names_listed(msg, expected), msg


def test_unknown_basis_lists_valid_names(tmp_path):
    path = write_config(tmp_path, 'basis = "bogus_basis"')
    with pytest.raises(ConfigError, match=r"model\.basis = 'bogus_basis': unknown basis") as info:
        load_config(path)
    assert _valid_names_listed(str(info.value), BASES), str(info.value)


def test_unknown_basis_in_target_names_the_target(tmp_path):
    path = write_config(tmp_path, extra='[model.targets.eeig4]\nbasis = "bogus_basis"')
    with pytest.raises(ConfigError, match=r"model\.targets\.eeig4\.basis = 'bogus_basis'") as info:
        load_config(path)
    assert _valid_names_listed(str(info.value), BASES)


@pytest.mark.parametrize("key", ["loss", "line_search_loss"])
def test_unknown_loss_lists_valid_names(tmp_path, key):
    path = write_config(tmp_path, f'basis = "ridge"\n{key} = "bogus_loss"')
    with pytest.raises(ConfigError, match=rf"model\.{key} = 'bogus_loss'") as info:
        load_config(path)
    assert _valid_names_listed(str(info.value), LOSSES), str(info.value)


def test_unknown_input_transform_lists_valid_names(tmp_path):
    path = write_config(tmp_path, 'basis = "ridge"\ninput_transform = "bogus_transform"')
    with pytest.raises(ConfigError, match=r"model\.input_transform = 'bogus_transform'") as info:
        load_config(path)
    assert _valid_names_listed(str(info.value), ["none", *TRANSFORMS]), str(info.value)


def test_bad_basis_inputs(tmp_path):
    path = write_config(tmp_path, 'basis = "ridge"\nbasis_inputs = "everything"')
    with pytest.raises(ConfigError, match=r"model\.basis_inputs = 'everything'") as info:
        load_config(path)
    assert "'prior'" in str(info.value) and "'prior+features'" in str(info.value)


def test_unknown_data_source(tmp_path):
    path = write_config(tmp_path, data='source = "bogus_source"')
    with pytest.raises(ConfigError,
                       match=r"data\.source = 'bogus_source': .*'google_5q', 'ibm_gates' or 'csv'"):
        load_config(path)


def test_data_source_defaults_to_the_benchmark(tmp_path):
    assert load_config(write_config(tmp_path, data='data_dir = "x"')).data.source == "google_5q"


def test_bad_basis_params_names_the_section(tmp_path):
    path = write_config(tmp_path, 'basis = "ridge"\nbasis_params = { nonsense = 1 }')
    with pytest.raises(ConfigError, match=r"model\.basis_params \(ridge\).*nonsense"):
        load_config(path)


def test_bad_basis_params_in_target_names_the_target(tmp_path):
    path = write_config(tmp_path, extra="[model.targets.eeig3.basis_params]\nnonsense = 1")
    with pytest.raises(ConfigError, match=r"model\.targets\.eeig3\.basis_params.*nonsense"):
        load_config(path)


def test_unknown_target_raised_by_build_model(tmp_path, google_5q):
    path = write_config(tmp_path, extra='[model.targets.eeig9]\nbasis = "ridge"')
    cfg = load_config(path)  # the config alone cannot know the dataset's targets
    with pytest.raises(ConfigError, match=r"\[model\.targets\].*eeig9") as info:
        build_model(cfg, google_5q)
    assert _valid_names_listed(str(info.value), TARGETS), str(info.value)


# --- values are checked at load time, not halfway through a run ---------------------------

def test_unknown_scoring_rejected_at_load(tmp_path):
    path = write_config(tmp_path, extra='[selection]\nscoring = "bogus_scoring"')
    with pytest.raises(ConfigError, match=r"\[selection\].*bogus_scoring"):
        load_config(path)


@pytest.mark.parametrize("model, match", [
    ('basis = "ridge"\nloss = "quantile"\nalpha = 1.5',
     r"model\.alpha = 1\.5: The 'alpha' parameter of BaseBoostRegressor must be a float in the "
     r"range \(0\.0, 1\.0\)\. Got 1\.5 instead\."),
    ('basis = "ridge"\nn_stages = 0',
     r"model\.n_stages = 0: The 'n_stages' parameter of BaseBoostRegressor must be an int in "
     r"the range \[1, inf\)\. Got 0 instead\."),
], ids=["quantile_alpha_1.5", "n_stages_0"])
def test_invalid_model_values_rejected_at_load(tmp_path, model, match):
    path = write_config(tmp_path, model)
    with pytest.raises(ConfigError, match=match) as info:
        load_config(path)
    assert str(path) in str(info.value)


# --- values that are an estimator's parameters are checked by that estimator's constraints ---

def test_boosting_values_are_the_estimators_to_check(tmp_path, monkeypatch):
    """The config declares no range of its own for n_stages: tighten BaseBoostRegressor's
    constraint and a value the estimator no longer takes is refused at load."""
    from numbers import Integral

    from sklearn.utils._param_validation import Interval

    path = write_config(tmp_path, 'basis = "ridge"\nn_stages = 7',
                        extra="[model.targets.eeig2]\nn_stages = 3")
    assert load_config(path).model_for("eeig1")["n_stages"] == 7
    monkeypatch.setitem(BaseBoostRegressor._parameter_constraints, "n_stages",
                        [Interval(Integral, 1, 5, closed="both")])
    with pytest.raises(ConfigError, match=r"model\.n_stages = 7: The 'n_stages' parameter of "
                                          r"BaseBoostRegressor must be an int in the range "
                                          r"\[1, 5\]\. Got 7 instead\."):
        load_config(path)
    path = write_config(tmp_path, 'basis = "ridge"',
                        extra="[model.targets.eeig2]\nn_stages = 6")
    with pytest.raises(ConfigError, match=r"model\.targets\.eeig2\.n_stages = 6: .*\[1, 5\]"):
        load_config(path)


def test_interval_values_are_the_estimators_to_check(tmp_path, monkeypatch):
    from numbers import Real

    from sklearn.utils._param_validation import Interval, StrOptions

    from workbench.conformal import ConformalRegressor

    path = write_config(tmp_path, extra='[intervals]\nalpha = 0.3\nmethod = "split"')
    assert load_config(path).intervals.alpha == 0.3
    monkeypatch.setitem(ConformalRegressor._parameter_constraints, "alpha",
                        [Interval(Real, 0, 0.2, closed="neither")])
    with pytest.raises(ConfigError, match=r"intervals\.alpha = 0\.3: The 'alpha' parameter of "
                                          r"ConformalRegressor"):
        load_config(path)
    monkeypatch.undo()
    monkeypatch.setitem(ConformalRegressor._parameter_constraints, "method",
                        [StrOptions({"cv_plus"})])
    with pytest.raises(ConfigError, match=r"intervals\.method = 'split': .*ConformalRegressor"):
        load_config(path)


def test_the_delegated_keys_and_their_defaults():
    """Which config keys are which estimator's parameters; every default a section gives
    for one satisfies the estimator's constraints."""
    from workbench.conformal import ConformalRegressor
    from workbench.experiment.config import MODEL_DEFAULTS, BoostSettings, IntervalsConfig
    from workbench.experiment.config.schema import check_values, parameters_of
    from workbench.experiment.families.hamiltonian import HamiltonianSettings
    from workbench.param_regressor import HamiltonianParameterRegressor as HPR
    from workbench.param_select import HamiltonianSelectionCV as HSCV

    boost = {k: (BaseBoostRegressor, k)
             for k in ("n_stages", "loss", "line_search_loss", "line_search_penalty", "alpha",
                       "link", "out_of_bounds")}
    assert parameters_of(BoostSettings) == boost
    assert parameters_of(IntervalsConfig) == {
        k: (ConformalRegressor, k) for k in ("alpha", "method", "cv", "calibration_fraction")}
    assert parameters_of(HamiltonianSettings) == {
        **{k: (HPR, k) for k in ("loss", "huber_delta", "alpha", "alpha_l1", "max_iter")},
        "selection_cv": (HSCV, "cv"), "selection_repeats": (HSCV, "n_repeats"),
        "max_steps": (HSCV, "max_steps"), "min_improvement": (HSCV, "min_improvement")}
    for key in boost:
        check_values(BaseBoostRegressor, {key: MODEL_DEFAULTS[key]})
    for section in (IntervalsConfig, HamiltonianSettings):
        defaults = section()
        for key, (estimator, param) in parameters_of(section).items():
            value = getattr(defaults, key)
            if value is not None:  # [intervals] method: the family's default
                check_values(estimator, {param: value})
    with pytest.raises(TypeError, match="declares no parameter 'bogus'"):
        check_values(BaseBoostRegressor, {"n": 1}, rename={"n": "bogus"})


def test_non_table_target_basis_params_is_config_error(tmp_path):
    path = write_config(tmp_path, extra="[model.targets.eeig1]\nbasis_params = 5")
    with pytest.raises(ConfigError, match=r"eeig1.*basis_params"):
        load_config(path)


@pytest.mark.parametrize("selection, match", [
    ("cv = 1", r"selection\.cv = 1: Input should be greater than or equal to 2"),
    ('cv = "five"', r"selection\.cv = 'five': Input should be a valid integer"),
    ('shuffle = "yes"', r"selection\.shuffle = 'yes': Input should be a valid boolean"),
])
def test_bad_selection_values(tmp_path, selection, match):
    path = write_config(tmp_path, extra=f"[selection]\n{selection}")
    with pytest.raises(ConfigError, match=match):
        load_config(path)


def test_target_switching_transform_does_not_inherit_transform_params(tmp_path):
    path = write_config(tmp_path, 'basis = "ridge"\ninput_transform_params = { n_quantiles = 50 }',
                        extra='[model.targets.eeig1]\ninput_transform = "standard"')
    cfg = load_config(path)
    assert cfg.model_for("eeig1")["input_transform_params"] == {}
    assert cfg.model_for("eeig2")["input_transform_params"] == {"n_quantiles": 50}


def test_target_naming_default_basis_inherits_basis_params(tmp_path):
    path = write_config(tmp_path, "basis_params = { mlp_alpha = 3.0 }",
                        extra='[model.targets.eeig1]\nbasis = "paper_stacking"')
    cfg = load_config(path)
    assert cfg.model_for("eeig1")["basis_params"] == {"mlp_alpha": 3.0}


# --- build_model --------------------------------------------------------------------------

@pytest.mark.parametrize("basis_inputs", ["prior", "prior+features"])
def test_build_model_structure(tmp_path, google_5q, basis_inputs):
    path = write_config(tmp_path, f'basis = "ridge"\nbasis_params = {{ alpha = 2.0 }}\n'
                        f'basis_inputs = "{basis_inputs}"\ninput_transform = "none"',
                        top="n_jobs = 1", extra="[selection]\ncv = 4")
    cfg = load_config(path)
    model = build_model(cfg, google_5q)
    assert isinstance(model, MultiTargetBaseBoost)
    assert model.random_state == 0 and model.n_jobs == 1
    assert list(model.target_estimators) == google_5q.target_names == TARGETS
    expected_inputs = PRIORS if basis_inputs == "prior" else PRIORS + VOLTAGES
    for target, prior in zip(TARGETS, PRIORS):
        cv_est = model.target_estimators[target]
        assert isinstance(cv_est, BaseBoostCV)
        assert isinstance(cv_est.cv, KFold)
        assert cv_est.cv.n_splits == 4 and not cv_est.cv.shuffle
        assert cv_est.scoring == "neg_mean_absolute_error"
        booster = cv_est.estimator
        assert isinstance(booster, BaseBoostRegressor)
        assert booster.prior == prior
        assert list(booster.basis_features) == expected_inputs
        assert booster.input_transform is None
        assert isinstance(booster.basis, Ridge) and booster.basis.alpha == 2.0
        assert booster.n_stages == 1
        assert booster.loss == "squared_error"
        assert booster.line_search_loss == "absolute_error"
    # the estimators are distinct objects, not one shared instance
    assert len({id(e) for e in model.target_estimators.values()}) == 5


def test_build_model_default_transform_and_prior_matches_dataset(tmp_path, google_5q):
    cfg = load_config(write_config(tmp_path))
    model = build_model(cfg, google_5q)
    for target, prior in zip(google_5q.target_names, google_5q.prior_names):
        booster = model.target_estimators[target].estimator
        assert booster.prior == prior
        assert isinstance(booster.input_transform, NormalQuantileTransformer)


def test_build_model_fits_and_predicts(tmp_path, google_5q):
    """The built model is usable: fit on the training rows, one prediction column per target."""
    cfg = load_config(write_config(tmp_path))
    X_train, X_test, y_train, _ = google_5q.split()
    model = build_model(cfg, google_5q).fit(X_train, y_train)
    pred = model.predict(X_test)
    assert list(pred.columns) == TARGETS and pred.shape == (len(X_test), 5)
    assert set(model.selected_) <= {"prior", "boosted"}


def test_target_override_changing_basis_does_not_inherit_basis_params(tmp_path, google_5q):
    path = write_config(
        tmp_path,
        'basis = "paper_stacking"\nbasis_params = { mlp_alpha = 3.0, lgbm_n_estimators = 20 }',
        extra=('[model.targets.eeig1]\nbasis = "ridge"\n\n'
               '[model.targets.eeig2]\nbasis = "ridge"\nbasis_params = { alpha = 5.0 }\n\n'
               "[model.targets.eeig3.basis_params]\nlgbm_n_estimators = 7\n"))
    cfg = load_config(path)
    assert cfg.model_for("eeig1")["basis"] == "ridge"
    assert cfg.model_for("eeig1")["basis_params"] == {}
    assert cfg.model_for("eeig2")["basis_params"] == {"alpha": 5.0}
    # same family: the target's params are merged over the parent's
    assert cfg.model_for("eeig3")["basis_params"] == {"mlp_alpha": 3.0, "lgbm_n_estimators": 7}
    assert cfg.model_for("eeig4")["basis_params"] == {"mlp_alpha": 3.0, "lgbm_n_estimators": 20}

    model = build_model(cfg, google_5q)
    ests = {t: model.target_estimators[t].estimator.basis for t in TARGETS}
    assert isinstance(ests["eeig1"], Ridge) and ests["eeig1"].alpha == Ridge().alpha
    assert isinstance(ests["eeig2"], Ridge) and ests["eeig2"].alpha == 5.0
    for t, n_est in [("eeig3", 7), ("eeig4", 20), ("eeig5", 20)]:
        assert isinstance(ests[t], StackingRegressor)
        params = ests[t].get_params()
        assert params["mlp__alpha"] == 3.0
        assert params["lgbm__n_estimators"] == n_est


def test_load_dataset_resolves_data_dir_relative_to_config(tmp_path, google_5q_dir, google_5q):
    sub = tmp_path / "experiments"
    sub.mkdir()
    rel = os.path.relpath(google_5q_dir, sub)
    path = write_config(sub, data=f'source = "google_5q"\ndata_dir = {_toml_str(rel)}')
    ds = load_dataset(load_config(path))
    assert ds.target_names == google_5q.target_names
    assert ds.targets.equals(google_5q.targets)
