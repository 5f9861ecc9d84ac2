"""Config overrides (``--set SECTION.KEY=VALUE``): parsing, applying, and the schema's
messages for what they set."""

import tomllib
from pathlib import Path

import pytest

from workbench.experiment.config.overrides import (
    apply_overrides,
    format_overrides,
    parse_override,
    parse_overrides,
)
from workbench.experiment.process.errors import ConfigError
from workbench.experiment.runs.prepare import parse_config

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("text, expected", [
    ("model.n_stages=2", ("model.n_stages", 2)),
    ("model.line_search_penalty = 0.25", ("model.line_search_penalty", 0.25)),
    ("selection.shuffle=true", ("selection.shuffle", True)),
    ('model.loss="huber"', ("model.loss", "huber")),
    ("model.loss=huber", ("model.loss", "huber")),  # a bare word is a string
    ('model.basis=["ridge", "lightgbm"]', ("model.basis", ["ridge", "lightgbm"])),
    ("search.n_stages={ low = 1, high = 3 }", ("search.n_stages", {"low": 1, "high": 3})),
    ("model.targets.eeig1.n_stages=3", ("model.targets.eeig1.n_stages", 3)),
    ("name=a=b", ("name", "a=b")),
])
def test_parse(text, expected):
    assert parse_override(text) == expected


@pytest.mark.parametrize("text", ["model.n_stages", "=2", "model..n_stages=2", ".x=1"])
def test_parse_malformed(text):
    with pytest.raises(ConfigError, match="give SECTION.KEY=VALUE"):
        parse_override(text)


def test_apply_copies_and_creates_tables():
    raw = {"name": "x", "model": {"n_stages": 1}}
    out = apply_overrides(raw, parse_overrides(["model.n_stages=2", "model.n_stages=3",
                                                "model.targets.eeig1.loss=huber"]))
    assert out["model"] == {"n_stages": 3, "targets": {"eeig1": {"loss": "huber"}}}
    assert raw == {"name": "x", "model": {"n_stages": 1}}
    with pytest.raises(ConfigError, match="--set name.x: name is a value, not a table"):
        apply_overrides(raw, {"name.x": 1})


def _smoke():
    return tomllib.loads((ROOT / "experiments" / "smoke.toml").read_text())


def test_schema_checks_what_is_set():
    cfg = parse_config(apply_overrides(_smoke(), {"model.n_stages": 2, "selection.cv": 3}))
    assert cfg.model_for(None)["n_stages"] == 2 and cfg.selection.cv == 3
    with pytest.raises(ConfigError, match=r"\[model\]: unknown key\(s\) \['n_stagse'\].*"
                                          r"valid keys are 'alpha', 'basis'"):
        parse_config(apply_overrides(_smoke(), {"model.n_stagse": 2}))
    with pytest.raises(ConfigError, match="model.n_stages = 'two'"):
        parse_config(apply_overrides(_smoke(), parse_overrides(["model.n_stages=two"])))


def test_format_round_trips():
    overrides = {"model.n_stages": 2, "model.loss": "huber", "selection.shuffle": True,
                 "model.basis": ["ridge", "lightgbm"]}
    text = format_overrides(overrides)
    assert text == ('model.n_stages=2 model.loss="huber" selection.shuffle=true '
                    'model.basis=["ridge", "lightgbm"]')
    assert parse_overrides(text.replace(' model.', '\nmodel.').replace(' sel', '\nsel')
                           .splitlines()) == overrides


@pytest.mark.parametrize("name", ["smoke.toml", "generic.toml", "hamiltonian.toml",
                                  "paper_main_body.toml"])
def test_dump_reads_back(name):
    from workbench.experiment.config.overrides import dump_config

    raw = tomllib.loads((ROOT / "experiments" / name).read_text())
    raw = apply_overrides(raw, {"model.n_stages": 2, "model.targets.eeig1.loss": "huber"})
    text = dump_config(raw, header=f"experiments/{name}\n--set model.n_stages=2")
    assert text.startswith(f"# experiments/{name}\n# --set model.n_stages=2\n")
    assert tomllib.loads(text) == raw
