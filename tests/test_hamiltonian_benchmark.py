"""The parameter-space model on the benchmark, as configured (slow: about 4 minutes on 2 cores).

    .venv/bin/python -m pytest -m slow
"""

import dataclasses
from pathlib import Path

import pytest

from workbench.experiment.runs.evaluate import evaluate
from workbench.experiment.runs.prepare import load_config

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"

pytestmark = pytest.mark.slow


def test_hamiltonian_config_meets_the_issue_criterion(google_5q_dir, monkeypatch):
    """Every choice on the 95 training rows; repeated 5-fold CV there <= 0.40 MHz; the test
    rows scored once; a nested CV over all 136 experiments reported."""
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    cfg = load_config(EXPERIMENTS / "hamiltonian.toml")  # what --nested 5 asks for:
    cfg = dataclasses.replace(cfg, evaluation=cfg.evaluation.model_copy(
        update={"nested_folds": 5}))
    res = evaluate(cfg).to_json()
    rep, nested = res["repeated_cv"], res["nested_cv_all"]
    assert rep["folds"] == 5 and rep["repeats"] >= 3
    assert rep["model_mae_avg"] <= 0.40, rep
    assert nested["n_rows"] == 136 and nested["folds"] == 5
    assert nested["model_mae_avg"] < 0.5 * nested["prior_mae_avg"], nested
    assert all(m < p for m, p in zip(res["model"]["test_mae"], res["prior"]["test_mae"]))
    assert res["model"]["test_mae_avg"] < 0.5 * res["prior"]["test_mae_avg"]
