"""The prepared run: a command loads its config's data once; data sources and model families
are found through registries (their entry points: tests/test_plugins.py)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from sklearn.base import BaseEstimator, RegressorMixin

from workbench.datasets import SOURCES, Dataset, DatasetError, get_source, register_source
from workbench.experiment import families
from workbench.experiment.cli import main
from workbench.experiment.config import ConfigError
from workbench.experiment.families import FAMILIES, ModelFamily
from workbench.experiment.runs.prepare import load_config, parse_config, prepare


class PriorModel(RegressorMixin, BaseEstimator):
    """Predicts each target's prior column (nothing learned: the cheapest model)."""

    def __init__(self, priors=None, targets=None):
        self.priors = priors
        self.targets = targets

    def fit(self, X, Y):
        self.selected_ = ["prior"] * len(self.targets)
        return self

    def predict(self, X):
        return pd.DataFrame(X[self.priors].to_numpy(float), index=X.index,
                            columns=self.targets)


class PluginFamily(ModelFamily):
    """A family another package would declare as an entry point."""

    name = "plugin_prior"

    def build(self, cfg, ds):
        return PriorModel(priors=ds.prior_names, targets=ds.target_names)


@pytest.fixture
def registries(monkeypatch):
    """FAMILIES and the entry points seen, restored after the test."""
    monkeypatch.setattr(families, "_discovered", set())
    saved = dict(FAMILIES)
    yield
    FAMILIES.clear()
    FAMILIES.update(saved)


def test_an_unknown_data_source_lists_the_registered_ones(tmp_path):
    with pytest.raises(DatasetError, match=r"unknown data source 'nope'; valid: \['google_5q', "
                                           r"'ibm_gates', 'csv'\]"):
        get_source("nope")
    with pytest.raises(ConfigError, match=r"data\.source = 'nope': unknown data source; valid: "
                                          r"'google_5q', 'ibm_gates' or 'csv'"):
        parse_config({"data": {"source": "nope"}}, tmp_path / "c.toml")


def _tiny(options, base, name) -> Dataset:
    rng = np.random.default_rng(0)
    prior = pd.DataFrame({"p": rng.normal(size=40)})
    return Dataset(name=name, features=pd.DataFrame(index=prior.index), prior=prior,
                   targets=pd.DataFrame({"y": prior["p"] + 0.1}),
                   train_index=np.arange(30), test_index=np.arange(30, 40))


def test_a_registered_data_source_feeds_a_config(monkeypatch, tmp_path):
    monkeypatch.setitem(SOURCES, "tiny", SOURCES["csv"])  # restored after the test
    register_source("tiny", _tiny)
    cfg = parse_config({"name": "t", "data": {"source": "tiny"}}, tmp_path / "c.toml")
    run = prepare(cfg)
    assert run.dataset.target_names == ["y"] and run.family is cfg.family


@pytest.fixture
def counted(monkeypatch, registries, google_5q_dir, tmp_path):
    """The benchmark's loader, counting its calls in a file (worker processes count too);
    the cheap family registered."""
    log = tmp_path / "loads.txt"
    log.touch()
    source = SOURCES["google_5q"]

    def load(options, base, name):
        with open(log, "a") as fh:
            fh.write(name + "\n")
        return source.load(options, base, name)

    monkeypatch.setitem(SOURCES, "google_5q", source)
    register_source("google_5q", load)
    families.register_family(PluginFamily())
    path = tmp_path / "c.toml"
    path.write_text(f'name = "once"\nrandom_state = 0\n[data]\ndata_dir = "{google_5q_dir}"\n'
                    '[model]\nfamily = "plugin_prior"\n[intervals]\nenabled = false\n'
                    "[cv]\nouter_folds = 2\ninner_folds = 2\n"
                    f'[study]\ntrials = 2\nstorage = "{tmp_path / "s.journal"}"\n')
    return path, log


def test_evaluate_loads_the_dataset_once(counted, tmp_path):
    path, log = counted
    assert main(["evaluate", str(path), "--no-track"]) == 0
    assert log.read_text().split() == ["once"]


def test_a_tracked_evaluate_loads_the_dataset_once(counted, tmp_path, new_store):
    """Recording the run (its input datasets, hashes, test predictions, model) reads no data
    again."""
    path, log = counted
    uri = new_store(tmp_path / "mlruns" / "mlflow.db")
    assert main(["evaluate", str(path), "--tracking-uri", uri]) == 0
    assert log.read_text().split() == ["once"]
    from mlflow import MlflowClient

    client = MlflowClient(uri)
    (run,) = client.search_runs([client.get_experiment_by_name("once").experiment_id])
    assert run.info.status == "FINISHED" and run.inputs.dataset_inputs  # it was recorded


def test_evaluate_with_seeds_loads_the_dataset_once(counted, tmp_path):
    """One load for every seed of ``evaluate --random-states``."""
    path, log = counted
    assert main(["evaluate", str(path), "--no-track", "--random-states", "0-2"]) == 0
    assert log.read_text().split() == ["once"]


def test_sweep_loads_the_dataset_once(counted, tmp_path):
    path, log = counted
    out = tmp_path / "sweep.json"
    assert main(["sweep", str(path), "--no-track", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["trials"]["studies"] == 3
    assert log.read_text().split() == ["once"]


def test_sweep_workers_receive_the_dataset(counted, tmp_path):
    """The search's worker processes get the loaded dataset with their task: none loads it."""
    path, log = counted
    assert main(["sweep", str(path), "--no-track", "--workers", "2"]) == 0
    assert log.read_text().split() == ["once"]


def test_a_loaded_config_resolves_its_family(tmp_path, google_5q_dir):
    path = tmp_path / "c.toml"
    path.write_text(f'[data]\ndata_dir = "{google_5q_dir}"\n')
    cfg = load_config(path)
    assert cfg.family is FAMILIES["eigenvalue"]


def test_design_loads_the_dataset_once(counted, tmp_path):
    """``workbench design`` fits the config's model and reads the candidates: one load of the
    config's data."""
    path, log = counted
    ds = prepare(load_config(path)).dataset  # the candidates' columns (a load of its own)
    assert log.read_text().split() == ["once"]
    candidates = tmp_path / "candidates.csv"
    ds.X.iloc[:12].to_csv(candidates, index=False)
    assert main(["design", str(path), "--candidates", str(candidates), "--n", "2",
                 "--out", str(tmp_path / "next.csv"), "--jobs", "1"]) == 0
    assert len(pd.read_csv(tmp_path / "next.csv")) == 2  # the command did run
    assert log.read_text().split() == ["once", "once"]
