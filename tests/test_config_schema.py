"""Table-driven: every numeric key of every config section, given a wrong type or a value out
of its range, and every choice key given an unknown name, ends at load time with one short
line naming ``section.key`` (and, through the command, exit code 2 before any fit). The
ranges and choices come from the schema, and for a key that is an estimator's parameter
(``ParameterOf``) from that estimator's ``_parameter_constraints``."""

from __future__ import annotations

import re
import types
import typing
from pathlib import Path

import annotated_types as at
import pytest
from sklearn.utils._param_validation import Interval, StrOptions, make_constraint

from workbench.experiment import config as C
from workbench.experiment.cli import main
from workbench.experiment.config import ConfigError
from workbench.experiment.config.schema import parameters_of
from workbench.experiment.families import FAMILIES
from workbench.experiment.runs.prepare import load_config

#: section path in the file -> (its schema, the config lines it needs besides itself)
SECTIONS = {
    "": (C.TopLevel, ""),
    "data": (C.DataConfig, ""),
    "model": (C.ModelConfig, ""),
    "model.targets.eeig1": (C.BoostSettings, ""),
    "model.hamiltonian": (FAMILIES["hamiltonian"].settings, 'family = "hamiltonian"'),
    "selection": (C.SelectionConfig, ""),
    "evaluation": (C.EvaluationConfig, ""),
    "intervals": (C.IntervalsConfig, ""),
    "cv": (C.CVConfig, ""),
    "study": (C.StudyConfig, ""),
    "tracking": (C.TrackingConfig, ""),
}


def _base_type(annotation):
    """int / float / bool / str / 'literal' of a field's annotation (optional and
    ``Annotated`` unwrapped)."""
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    if typing.get_origin(annotation) is typing.Literal:
        return "literal"
    if typing.get_origin(annotation) is typing.Annotated:
        return _base_type(args[0])
    if args and typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return _base_type(args[0])
    return annotation


def _estimator_bounds(estimator, param):
    """The bounds (``annotated_types``) and choices the estimator's constraints declare for
    ``param`` (an Interval's ends; a StrOptions' names)."""
    bounds, choices = [], False
    declared = [make_constraint(c) for c in estimator._parameter_constraints[param]]
    # "cv_object" holds an Interval of its own (the int folds)
    for constraint in [i for c in declared for i in getattr(c, "_constraints", [c])]:
        if isinstance(constraint, Interval):
            if constraint.left is not None:
                bounds.append(at.Ge(constraint.left) if constraint.closed in ("left", "both")
                              else at.Gt(constraint.left))
            if constraint.right is not None:
                bounds.append(at.Le(constraint.right) if constraint.closed in ("right", "both")
                              else at.Lt(constraint.right))
        elif isinstance(constraint, StrOptions):
            choices = True
    return bounds, choices


def _bad_values():
    """(section, key, TOML value, why) for every numeric, boolean and choice key."""
    cases = []
    for section, (schema, _) in SECTIONS.items():
        delegated = parameters_of(schema)
        for key, field in schema.model_fields.items():
            kind = _base_type(field.annotation)
            metadata, choices = list(field.metadata), False
            if key in delegated:
                bounds, choices = _estimator_bounds(*delegated[key])
                metadata += bounds
            if kind in (int, float):
                cases.append((section, key, '"abc"', "type"))
                cases.append((section, key, "[1, 2]", "type"))
                for meta in metadata:
                    if isinstance(meta, (at.Ge, at.Gt)):
                        low = meta.ge if isinstance(meta, at.Ge) else meta.gt
                        below = low - 1 if isinstance(meta, at.Ge) else low
                        cases.append((section, key, repr(below) if kind is int else
                                      f"{float(below)}", "low"))
                    if isinstance(meta, (at.Le, at.Lt)):
                        high = meta.le if isinstance(meta, at.Le) else meta.lt
                        above = high + 1 if isinstance(meta, at.Le) else high
                        cases.append((section, key, repr(above) if kind is int else
                                      f"{float(above)}", "high"))
                if kind is int:
                    cases.append((section, key, "1.5", "type"))
                    cases.append((section, key, "9" * 5000, "huge"))  # beyond Python's limit
            elif kind is bool:
                cases.append((section, key, '"yes"', "type"))
            elif kind == "literal" or choices:
                cases.append((section, key, '"bogus_choice"', "choice"))
            if kind is str:
                cases.append((section, key, "5", "type"))
    return cases


CASES = _bad_values()


def _config_text(section: str, key: str, value: str) -> str:
    needs = SECTIONS[section][1]
    model = [] if (section == "model" and key == "basis") else ['basis = "ridge"']
    tables = {"": [], "data": [], "model": model, "selection": []}
    if needs:
        tables["model"].append(needs)
    if section in tables:
        tables[section].append(f"{key} = {value}")
    else:
        tables[section] = [f"{key} = {value}"]
    top = "\n".join(tables.pop(""))
    body = "\n\n".join(f"[{name}]\n" + "\n".join(lines) for name, lines in tables.items())
    head = "" if (section == "" and key == "name") else 'name = "t"\n'
    return f'{head}{top}\n\n{body}\n'


def test_every_section_and_kind_is_covered():
    covered = {(s, why) for s, _, _, why in CASES}
    for section in SECTIONS:
        assert any(s == section for s, _ in covered), section
    assert {"type", "low", "high", "choice", "huge"} <= {why for _, why in covered}
    assert len(CASES) > 80
    # the keys the estimators check are covered from their constraints
    keys = {(s, k, why) for s, k, _, why in CASES}
    for section, key, why in [("model", "n_stages", "low"), ("model", "alpha", "high"),
                              ("model", "loss", "choice"), ("intervals", "method", "choice"),
                              ("intervals", "calibration_fraction", "high"),
                              ("model.hamiltonian", "selection_cv", "low"),
                              ("model.hamiltonian", "loss", "choice"),
                              ("model.targets.eeig1", "line_search_penalty", "low")]:
        assert (section, key, why) in keys, (section, key, why)


@pytest.mark.parametrize("section, key, value, why", CASES,
                         ids=[f"{s or 'top'}.{k}-{w}" for s, k, _, w in CASES])
def test_bad_value_is_one_line_naming_the_key(tmp_path, section, key, value, why):
    path = tmp_path / "bad.toml"
    path.write_text(_config_text(section, key, value))
    with pytest.raises(ConfigError) as info:
        load_config(path)
    msg = str(info.value)
    assert "\n" not in msg and len(msg) < 300, msg
    assert str(path) in msg
    if why != "huge":  # tomllib itself cannot read the number; the line says so
        dotted = f"{section}.{key}" if section else key
        assert dotted in msg, msg
    else:
        assert "cannot be read" in msg or key in msg, msg


@pytest.mark.parametrize("section, key, value, why",
                         [c for c in CASES if c[3] in ("type", "choice")][::7])
def test_command_exits_2_before_any_fit(tmp_path, capsys, section, key, value, why):
    path = tmp_path / "bad.toml"
    path.write_text(_config_text(section, key, value))
    assert main(["evaluate", str(path), "--no-track"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("workbench: error: ") and len(err[0]) < 320


@pytest.mark.parametrize("params, pattern", [
    ('{ alpha = "x" }', r"model\.basis_params \(ridge\).*'alpha' parameter of Ridge"),
    ("{ alpha = -5 }", r"model\.basis_params \(ridge\).*'alpha' parameter of Ridge"),
    ("{ nonsense = 1 }", r"nonsense"),
])
def test_basis_params_checked_against_the_estimators_constraints(tmp_path, params, pattern):
    path = tmp_path / "c.toml"
    path.write_text(f'[model]\nbasis = "ridge"\nbasis_params = {params}\n')
    with pytest.raises(ConfigError, match=pattern):
        load_config(path)


@pytest.mark.parametrize("basis, params, pattern", [
    ("lightgbm", '{ n_estimators = 0 }', "n_estimators"),
    ("lightgbm", '{ learning_rate = "fast" }', "learning_rate"),
    ("lightgbm", '{ bogus_lgbm = 1 }', "bogus_lgbm"),
    ("lightgbm", '{ num_leaves = 1 }', r"num_leaves = 1: LightGBM: .*num_leaves"),
    ("lightgbm", '{ n_estimators = 5, subsample = 1.5 }', r"subsample = 1\.5: LightGBM"),
    ("paper_stacking", '{ mlp_alpha = -1.0 }', "alpha"),
    ("mlp", '{ solver = "bogus" }', "solver"),
    ("kernel_ridge", '{ alpha = "x" }', "alpha"),
])
def test_nested_and_lightgbm_parameters_are_checked(tmp_path, basis, params, pattern):
    path = tmp_path / "c.toml"
    path.write_text(f'[model]\nbasis = "{basis}"\nbasis_params = {params}\n')
    with pytest.raises(ConfigError, match=pattern):
        load_config(path)


def test_lightgbm_checks_its_own_parameters_in_one_line(tmp_path, capfd):
    """LightGBM declares no constraints: its own checks run on a few rows at load (stopped
    after one round), and its native error line does not reach the terminal."""
    path = tmp_path / "c.toml"
    path.write_text('[model]\nbasis = "lightgbm"\nbasis_params = { max_bin = 1 }\n')
    assert main(["evaluate", str(path), "--no-track"]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "max_bin = 1: LightGBM: Check failed" in err[0], err
    # a setting LightGBM accepts loads, however many rounds it asks for (none are run)
    path.write_text('[model]\nbasis = "lightgbm"\nbasis_params = { n_estimators = 10000000, '
                    "lambda_l1 = 0.5 }\n")
    assert load_config(path).model_for(None)["basis_params"]["n_estimators"] == 10_000_000


@pytest.mark.parametrize("argv", [["--trials", "0"], ["--trials", "-3"], ["--workers", "0"],
                                  ["--trials", "x"]])
def test_command_line_counts_must_be_positive(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(["sweep", "experiments/smoke.toml", *argv])
    assert info.value.code == 2
    assert re.search(r"expected an integer >= 1", capsys.readouterr().err)


def test_jobs_must_be_positive(capsys):
    with pytest.raises(SystemExit) as info:
        main(["evaluate", "experiments/smoke.toml", "--jobs", "0"])
    assert info.value.code == 2


def test_search_family_values_checked_against_the_family_schema(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[model]\nfamily = "hamiltonian"\n[search.hamiltonian]\n'
                    'loss = ["huber", "bogus_loss"]\n')
    with pytest.raises(ConfigError, match=r"hamiltonian\.loss = 'bogus_loss'"):
        load_config(path)


def test_family_table_for_another_family_is_an_error(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[model]\nbasis = "ridge"\n[model.hamiltonian]\nalpha = 1.0\n')
    with pytest.raises(ConfigError, match=r"\[model\.hamiltonian\]: applies to family"):
        load_config(path)


def test_unknown_family_lists_the_valid_ones(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[model]\nfamily = "bogus_family"\n')
    with pytest.raises(ConfigError,
                       match=r"model\.family = 'bogus_family'.*eigenvalue.*hamiltonian"):
        load_config(path)


def test_every_shipped_config_loads():
    for path in sorted(Path(__file__).resolve().parents[1].glob("experiments/*.toml")):
        load_config(path)


GRAPH_DATA = ('[data]\ncsv = "d.csv"\nprior = ["p1", "p2", "p3", "p4"]\n'
              'targets = ["y1", "y2", "y3", "y4"]\ntest_fraction = 0.3\n'
              '[data.hamiltonian]\nonsite = ["f1", "f2", "f3", "f4"]\n')


@pytest.mark.parametrize("graph, pattern", [
    ('couplings = ["g1", "g2", "g3"]\ntopology = "grid"\nshape = [3, 3]', r"coupling graph:"),
    ('couplings = ["g1", "g2", "g3"]\nedges = [[0, 1], [1, 2], [2, 7]]', r"coupling graph:"),
    ('couplings = ["g1", "g2"]\ntopology = "ring"', r"couplings: the ring graph of 4 sites has 4"),
    ('couplings = ["g1", "g2", "g3"]\nshape = [2, 2]', r"shape applies to topology = \"grid\""),
    ('couplings = ["g1", "g2", "g3"]\ntopology = "star"', r"data\.hamiltonian\.topology = 'star'"),
])
def test_bad_coupling_graphs_are_one_line(tmp_path, graph, pattern):
    path = tmp_path / "g.toml"
    path.write_text(f"{GRAPH_DATA}{graph}\n[model]\nfamily = \"hamiltonian\"\n")
    with pytest.raises(ConfigError, match=pattern) as info:
        load_config(path)
    assert "\n" not in str(info.value) and len(str(info.value)) < 300


def test_a_grid_and_parasitic_couplings_load(tmp_path):
    path = tmp_path / "g.toml"
    path.write_text(f'{GRAPH_DATA}couplings = ["g1", "g2", "g3", "g4"]\ntopology = "grid"\n'
                    'shape = [2, 2]\n[model]\nfamily = "hamiltonian"\n[model.hamiltonian]\n'
                    'parasitic = "diagonal"\n')
    cfg = load_config(path)
    assert cfg.data.hamiltonian.shape == [2, 2] and cfg.family_settings.parasitic == "diagonal"


@pytest.mark.parametrize("section, old, new", [
    ("evaluation", "seeds = [0, 1]", "random_states"),
    ("cv", "seed = 3", "sweep_seed"),
])
def test_a_renamed_key_fails_naming_its_new_name(tmp_path, capsys, section, old, new):
    """A config with a key's old name is refused (not read differently), in one line."""
    path = tmp_path / "old.toml"
    path.write_text(f"[{section}]\n{old}\n")
    with pytest.raises(ConfigError, match=rf"{section}.*is now '{new}'") as info:
        load_config(path)
    assert "\n" not in str(info.value)
    assert main(["evaluate", str(path), "--no-track"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


@pytest.mark.parametrize("argv, new", [
    (["evaluate", "any.toml", "--seeds", "0-2"], "--seeds is now --random-states"),
    (["reproduce", "--seed", "1"], "--seed is now --random-state"),
    (["simulate", "--seed", "1", "--out", "x.csv"], "--seed is now --device-seed"),
])
def test_a_renamed_option_fails_naming_its_new_name(capsys, argv, new):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and new in err, err


def test_reproduce_takes_the_random_state():
    from workbench.experiment.cli.parser import build_parser

    args = build_parser().parse_args(["reproduce", "--random-state", "3"])
    assert args.random_state == 3 and not hasattr(args, "seed")


def test_simulate_takes_the_device_seed():
    from workbench.experiment.cli.parser import build_parser

    args = build_parser().parse_args(["simulate", "--device-seed", "3", "--out", "x.csv"])
    assert args.device_seed == 3 and not hasattr(args, "seed")
