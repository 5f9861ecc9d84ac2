"""A third model family, defined here in the test suite and registered at run time, runs
``evaluate`` and a small ``sweep`` without any workbench module knowing its name."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pydantic import Field
from sklearn.base import BaseEstimator, RegressorMixin

from workbench.experiment.cli import main
from workbench.experiment.config.schema import Section
from workbench.experiment.families import FAMILIES, ModelFamily, register_family

ROOT = Path(__file__).resolve().parents[1]


class ShiftModel(RegressorMixin, BaseEstimator):
    """Each target: its prior column plus ``shrink`` times the mean training residual."""

    def __init__(self, priors=None, targets=None, shrink=1.0):
        self.priors = priors
        self.targets = targets
        self.shrink = shrink

    def fit(self, X, Y):
        residual = np.asarray(Y, float) - X[self.priors].to_numpy(float)
        self.shift_ = self.shrink * residual.mean(axis=0)
        self.selected_ = ["shift"] * len(self.targets)
        return self

    def predict(self, X):
        return pd.DataFrame(X[self.priors].to_numpy(float) + self.shift_, index=X.index,
                            columns=self.targets)


class ShiftSettings(Section):
    shrink: float = Field(default=1.0, ge=0, le=1)


class ShiftFamily(ModelFamily):
    name = "toy_shift"
    settings = ShiftSettings

    def build(self, cfg, ds):
        return ShiftModel(priors=ds.prior_names, targets=ds.target_names,
                          shrink=cfg.family_settings.shrink)


@pytest.fixture
def toy_family():
    register_family(ShiftFamily())
    yield FAMILIES["toy_shift"]
    del FAMILIES["toy_shift"]


def _config(tmp_path, google_5q_dir, extra="") -> Path:
    path = tmp_path / "toy.toml"
    path.write_text(f'name = "toy"\nrandom_state = 0\n[data]\ndata_dir = "{google_5q_dir}"\n'
                    f'[model]\nfamily = "toy_shift"\n[model.toy_shift]\nshrink = 0.5\n{extra}')
    return path


def test_no_workbench_module_names_a_family_outside_its_own():
    """The families' names appear only in their own modules (and the registry's docs)."""
    pattern = r"(==|!=|in) *\(?[\"'](eigenvalue|hamiltonian)[\"']"
    out = subprocess.run(["git", "grep", "-nE", pattern, "--", "workbench"], cwd=ROOT,
                         capture_output=True, text=True)
    hits = [line for line in out.stdout.splitlines() if "/families/" not in line]
    assert hits == [], hits


def test_toy_family_evaluates(toy_family, tmp_path, google_5q_dir, google_5q, capsys):
    path = _config(tmp_path, google_5q_dir)
    out = tmp_path / "result.json"
    assert main(["evaluate", str(path), "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["family"] == "toy_shift" and result["model"]["selected"] == ["shift"] * 5
    # the numbers are the toy model's: prior + half the mean training residual
    X_train, X_test, y_train, y_test = google_5q.split()
    residual = (y_train.to_numpy() - X_train[google_5q.prior_names].to_numpy()).mean(axis=0)
    pred = X_test[google_5q.prior_names].to_numpy() + 0.5 * residual
    expected = np.abs(y_test.to_numpy() - pred).mean(axis=0)
    np.testing.assert_allclose(result["model"]["test_mae"], expected, rtol=1e-12)
    assert result["mlflow"]["run_id"]
    # a model that keeps no out-of-fold predictions of its own: CV+ by default
    assert result["intervals"]["method"] == "cv_plus"
    # every family's test errors get bootstrap intervals over the 41 test rows, seeded by
    # the config's random_state: the prior's, the model's and the paired model - prior
    assert result["bootstrap"] == {"method": "percentile", "level": 0.95, "n_resamples": 10_000,
                                   "random_state": 0, "n_rows": 41}
    for part in ("prior", "model"):
        for key in ("test_mae", "test_mse"):
            bounds = [*result[part][f"{key}_ci"], result[part][f"{key}_avg_ci"]]
            point = [*result[part][key], result[part][f"{key}_avg"]]
            assert all(lo < p < hi for (lo, hi), p in zip(bounds, point, strict=True))
    diff = np.subtract(result["model"]["test_mae"], result["prior"]["test_mae"]).mean()
    low, high = result["model"]["test_mae_diff_avg_ci"]
    assert low < diff < high
    assert "95% bootstrap intervals over the 41 test rows, average test MAE" in \
        capsys.readouterr().out


def test_toy_family_refuses_oof_intervals_before_any_fit(toy_family, tmp_path, google_5q_dir,
                                                         capsys):
    path = _config(tmp_path, google_5q_dir, extra='[intervals]\nmethod = "oof"\n')
    assert main(["evaluate", str(path), "--no-track"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "intervals.method = 'oof'" in err[0] and "'cv_plus'" in err[0]


def test_toy_family_sweeps(toy_family, tmp_path, google_5q_dir):
    path = _config(tmp_path, google_5q_dir, extra=(
        "[search.toy_shift]\nshrink = { low = 0.0, high = 1.0 }\n"
        "[cv]\nouter_folds = 2\ninner_folds = 2\n"
        f'[study]\ntrials = 3\nstorage = "{tmp_path / "toy.journal"}"\n'))
    out = tmp_path / "sweep.json"
    assert main(["sweep", str(path), "--json", str(out), "--no-track"]) == 0
    result = json.loads(out.read_text())
    assert result["trials"] == {"per_study": 3, "counted": 9, "studies": 3}
    assert len(result["nested_cv_mae"]) == 5
    shrinks = {p["toy_shift.shrink"] for p in result["best_params"]}
    assert len(shrinks) == 1 and 0.0 <= shrinks.pop() <= 1.0  # one study over all targets


def test_toy_family_settings_are_validated(toy_family, tmp_path, google_5q_dir, capsys):
    path = _config(tmp_path, google_5q_dir).with_name("bad.toml")
    path.write_text('[model]\nfamily = "toy_shift"\n[model.toy_shift]\nshrink = 2.0\n')
    assert main(["evaluate", str(path), "--no-track"]) == 2
    assert "model.toy_shift.shrink = 2.0" in capsys.readouterr().err
