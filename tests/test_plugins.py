"""Bases, data sources and model families are plug-ins of one shape: a registry with one
``register_*`` and an entry-point group (``workbench.bases``, ``workbench.sources``,
``workbench.families``), read when a name is not found.

The test plug-ins are installed the real way: a module and a ``*.dist-info`` directory with
its ``entry_points.txt`` in a temporary folder put on ``sys.path``.
"""

from __future__ import annotations

import json
import logging
import sys
import textwrap

import pytest
from sklearn.linear_model import Ridge

from workbench import bases
from workbench.datasets import SOURCES, DatasetError, get_source, sources
from workbench.experiment import families
from workbench.experiment.cli import main
from workbench.experiment.config import ConfigError
from workbench.experiment.config.space import SearchSpace
from workbench.experiment.families import FAMILIES
from workbench.experiment.runs.prepare import parse_config, prepare

MODULE = "wb_plugin_for_tests"

PLUGIN = '''
import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.linear_model import Ridge

from workbench.datasets import Dataset
from workbench.experiment.families import ModelFamily


def shrunk_ridge(**params):
    """A basis: a ridge with a strong default penalty."""
    return Ridge(**{"alpha": 10.0, **params})


def load_tiny(options, base, name):
    """A data source: 40 rows, one prior, one target, one feature."""
    rng = np.random.default_rng(0)
    prior = pd.DataFrame({"p": rng.normal(size=40)})
    features = pd.DataFrame({"x": rng.normal(size=40)})
    return Dataset(name=name, features=features, prior=prior,
                   targets=pd.DataFrame({"y": prior["p"] + features["x"]}),
                   train_index=np.arange(30), test_index=np.arange(30, 40))


class PriorModel(RegressorMixin, BaseEstimator):
    def __init__(self, priors=None, targets=None):
        self.priors = priors
        self.targets = targets

    def fit(self, X, Y):
        self.selected_ = ["prior"] * len(self.targets)
        return self

    def predict(self, X):
        return pd.DataFrame(X[self.priors].to_numpy(float), index=X.index,
                            columns=self.targets)


class PriorFamily(ModelFamily):
    """A family: predicts each target's prior."""

    name = "plugin_prior"

    def build(self, cfg, ds):
        return PriorModel(priors=ds.prior_names, targets=ds.target_names)
'''

ENTRY_POINTS = f"""
[workbench.bases]
shrunk_ridge = {MODULE}:shrunk_ridge

[workbench.sources]
tiny = {MODULE}:load_tiny

[workbench.families]
plugin_prior = {MODULE}:PriorFamily
"""

BROKEN = f"""
[workbench.bases]
broken_basis = {MODULE}:no_such_factory

[workbench.sources]
broken_source = no_such_module_anywhere:load

[workbench.families]
broken_family = {MODULE}:shrunk_ridge
"""


@pytest.fixture
def install(tmp_path, monkeypatch):
    """``install(entry_points_txt)``: the plug-in module and a distribution declaring those
    entry points, on ``sys.path``; the registries and the entry points seen restored after."""
    saved = dict(bases.BASES), dict(SOURCES), dict(FAMILIES)
    for module in (bases, sources, families):
        monkeypatch.setattr(module, "_discovered", set())

    def install(entry_points: str) -> None:
        (tmp_path / f"{MODULE}.py").write_text(PLUGIN)
        info = tmp_path / "wb_plugin_for_tests-1.0.dist-info"
        info.mkdir()
        (info / "METADATA").write_text("Metadata-Version: 2.1\nName: wb-plugin-for-tests\n"
                                       "Version: 1.0\n")
        (info / "entry_points.txt").write_text(textwrap.dedent(entry_points))
        monkeypatch.syspath_prepend(str(tmp_path))

    yield install
    sys.modules.pop(MODULE, None)
    for registry, before in zip((bases.BASES, SOURCES, FAMILIES), saved):
        registry.clear()
        registry.update(before)


def test_a_basis_loads_from_its_entry_point(install, tmp_path):
    install(ENTRY_POINTS)
    assert "shrunk_ridge" not in bases.BASES  # nothing is loaded before it is needed
    basis = bases.make_basis("shrunk_ridge")
    assert isinstance(basis, Ridge) and basis.alpha == 10.0
    assert bases.discover_bases() == []  # each entry point is loaded once
    # a config and a search space take its name
    cfg = parse_config({"model": {"basis": "shrunk_ridge", "basis_params": {"alpha": 2.0}}},
                       tmp_path / "c.toml")
    assert cfg.model_for("E1")["basis"] == "shrunk_ridge"
    space = SearchSpace.from_table({"basis": ["ridge", "shrunk_ridge"],
                                    "basis_params": {"shrunk_ridge": {"alpha": [1.0, 3.0]}}})
    assert space.table["basis"] == ["ridge", "shrunk_ridge"]


def test_a_data_source_loads_from_its_entry_point(install, tmp_path):
    install(ENTRY_POINTS)
    assert "tiny" not in SOURCES
    cfg = parse_config({"name": "t", "data": {"source": "tiny"}}, tmp_path / "c.toml")
    run = prepare(cfg)
    assert run.dataset.target_names == ["y"] and len(run.dataset.test_index) == 10
    assert get_source("tiny").name == "tiny"


def test_a_model_family_loads_from_its_entry_point(install, tmp_path):
    install(ENTRY_POINTS)
    assert "plugin_prior" not in FAMILIES
    cfg = parse_config({"model": {"family": "plugin_prior"}}, tmp_path / "c.toml")
    assert type(cfg.family).__name__ == "PriorFamily" and cfg.family.name == "plugin_prior"
    assert families.discover_families() == []  # each entry point is loaded once


def test_the_three_plug_ins_run_evaluate_together(install, tmp_path, capsys):
    """The plug-in source feeds a run of the plug-in basis; then of the plug-in family."""
    install(ENTRY_POINTS)
    config = tmp_path / "c.toml"
    model = 'basis = "shrunk_ridge"\nn_stages = 1\nbasis_inputs = "prior+features"'
    config.write_text(f'name = "plugged"\nrandom_state = 0\n[data]\nsource = "tiny"\n'
                      f'[model]\n{model}\n[intervals]\nenabled = false\n')
    main(["evaluate", str(config), "--no-track", "--json", str(tmp_path / "r.json")])
    result = json.loads((tmp_path / "r.json").read_text())
    assert result["targets"] == ["y"] and result["model"]["selected"] == ["boosted"]
    config.write_text(config.read_text().replace(model, 'family = "plugin_prior"'))
    main(["evaluate", str(config), "--no-track", "--json", str(tmp_path / "r.json")])
    result = json.loads((tmp_path / "r.json").read_text())
    assert result["model"]["test_mae"] == result["prior"]["test_mae"]  # the prior, as built


def test_a_broken_plug_in_is_one_warning_line_naming_it(install, tmp_path, caplog):
    install(BROKEN)
    with caplog.at_level(logging.WARNING, logger="workbench"):
        assert bases.discover_bases() == []
        assert sources.discover_sources() == []
        assert families.discover_families() == []
        assert bases.discover_bases() == []  # reported once, not at every look-up
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3, lines
    for name, group in [("broken_basis", "workbench.bases"),
                        ("broken_source", "workbench.sources"),
                        ("broken_family", "workbench.families")]:
        assert [line for line in lines if f"{group} plug-in {name!r}" in line
                and "not loaded" in line and "\n" not in line], lines


def test_an_unknown_name_lists_the_valid_ones_plug_ins_included(install, tmp_path):
    install(ENTRY_POINTS)
    with pytest.raises(ValueError, match=r"unknown basis 'nope'; valid names are: .*"
                                         r"shrunk_ridge"):
        bases.make_basis("nope")
    with pytest.raises(DatasetError, match=r"unknown data source 'nope'; valid: \['google_5q', "
                                           r"'ibm_gates', 'csv', 'tiny'\]"):
        get_source("nope")
    with pytest.raises(ConfigError, match=r"model\.family = 'nope': unknown family; valid: "
                                          r"\['eigenvalue', 'hamiltonian', 'parametric', "
                                          r"'plugin_prior'\]"):
        parse_config({"model": {"family": "nope"}}, tmp_path / "c.toml")
    with pytest.raises(ConfigError, match=r"model.basis = 'nope': unknown basis; valid: .*"
                                          r"'shrunk_ridge'"):
        parse_config({"model": {"basis": "nope"}}, tmp_path / "c.toml")


def test_registering_checks_the_name_and_the_object():
    with pytest.raises(ValueError, match="identifier"):
        bases.register_basis("not a name", Ridge)
    with pytest.raises(TypeError, match="callable"):
        bases.register_basis("ridge2", "Ridge")
    with pytest.raises(TypeError, match="callable"):
        sources.register_source("nothing", None)
    assert "ridge2" not in bases.BASES and "nothing" not in SOURCES
