"""``workbench evaluate --random-states``: a fit per seed, a child run each under one parent whose
metrics are the mean and sd of the children's test MAE (issue 34)."""

from __future__ import annotations

import contextlib
import io
import json
import signal

import numpy as np
import pytest
from mlflow import MlflowClient

from workbench.experiment.api import evaluate_seeds, load_config
from workbench.experiment.cli import main
from workbench.experiment.process import signals
from workbench.experiment.runs import seeds as seeds_module
from workbench.simulate import Mismatch, simulate

TARGETS = ["measured_E1", "measured_E2"]

#: Two targets of a simulated device, a small MLP basis (random: the seed matters), no
#: intervals: a fit takes about a second.
CONFIG = """\
name = "seeds_test"
random_state = 0

[data]
csv = "sim.csv"
prior = ["model_E1", "model_E2"]
targets = ["measured_E1", "measured_E2"]
features = ["v_q1", "v_q2", "v_c1"]
test_fraction = 0.3

[model]
basis = "mlp"
basis_params = { hidden_layer_sizes = [4], max_iter = 30 }
basis_inputs = "prior+features"
input_transform = "standard"

[selection]
cv = 3

[intervals]
enabled = false
"""

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    root = tmp_path_factory.mktemp("seeds")
    simulate(2, 120, device_seed=0, mismatch=Mismatch.default()).data.to_csv(root / "sim.csv",
                                                                      index=False)
    (root / "c.toml").write_text(CONFIG)
    return root / "c.toml"


def _main(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue()


def _runs(experiment: str) -> list:
    """The runs of ``experiment`` in the session's store (conftest's $MLFLOW_TRACKING_URI:
    one store for the session, no new store's migration per test)."""
    client = MlflowClient()
    return client.search_runs([client.get_experiment_by_name(experiment).experiment_id])


@pytest.fixture(scope="module")
def tracked(config, tmp_path_factory):
    """``evaluate --random-states 0-2`` once, tracked, with ``--json`` and ``--out``."""
    root = tmp_path_factory.mktemp("tracked")
    rc, out, err = _main("evaluate", config, "--random-states", "0-2", "--set",
                         "tracking.experiment=seeds_tracked", "--json", root / "out.json",
                         "--out", root / "out", "--jobs", "1")
    assert rc == 0, err
    return dict(root=root, stdout=out, runs=_runs("seeds_tracked"),
                json=json.loads((root / "out.json").read_text()))


def test_one_parent_whose_metrics_are_the_mean_and_sd_of_its_three_children(tracked):
    runs = tracked["runs"]
    parents = [r for r in runs if "mlflow.parentRunId" not in r.data.tags]
    assert len(parents) == 1
    parent = parents[0]
    children = [r for r in runs if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id]
    assert len(runs) == 4 and len(children) == 3
    assert {r.info.status for r in runs} == {"FINISHED"}
    children.sort(key=lambda r: int(r.data.params["random_state"]))
    assert [r.data.params["random_state"] for r in children] == ["0", "1", "2"]
    params = parent.data.params
    assert params["random_states"] == "0,1,2" and "random_state" not in params
    m = parent.data.metrics
    for target in [*TARGETS, None]:
        key = f"test_mae/{target}" if target else "test_mae_avg"
        values = np.array([c.data.metrics[key] for c in children])
        stem = f"test_mae_%s/{target}" if target else "test_mae_avg_%s"
        assert m[stem % "mean"] == pytest.approx(values.mean(), rel=1e-6)
        assert m[stem % "sd"] == pytest.approx(values.std(ddof=1), rel=1e-5)
        assert len(set(values)) == 3  # a random model: each seed its own numbers
    assert m["n_seeds"] == 3
    client = MlflowClient()
    png = client.download_artifacts(parent.info.run_id, "plots/seed_spread.png",
                                    str(tracked["root"]))
    assert open(png, "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    assert "| measured_E1 |" in parent.data.tags["mlflow.note.content"]
    # each child carries what `workbench compare` pairs
    assert {a.path for a in client.list_artifacts(children[0].info.run_id, "predictions")} \
        == {"predictions/test.csv", "predictions/test_measured.csv"}


def test_json_out_and_table(tracked):
    data = tracked["json"]
    assert data["random_states"] == [0, 1, 2] and data["targets"] == TARGETS
    assert [r["random_state"] for r in data["runs"]] == [0, 1, 2]
    summary = data["summary"]
    per_seed = np.array([r["model"]["test_mae"] for r in data["runs"]])
    assert summary["test_mae"] == per_seed.tolist()
    assert summary["test_mae_mean"] == pytest.approx(per_seed.mean(axis=0).tolist())
    assert summary["test_mae_sd"] == pytest.approx(per_seed.std(axis=0, ddof=1).tolist())
    parent = next(r for r in tracked["runs"] if "mlflow.parentRunId" not in r.data.tags)
    assert data["mlflow"]["run_id"] == parent.info.run_id
    assert {r["mlflow"]["run_id"] for r in data["runs"]} == {
        r.info.run_id for r in tracked["runs"]} - {parent.info.run_id}
    assert sorted(p.name for p in (tracked["root"] / "out").iterdir()) == [
        "seed_spread.png", "seed_test_mae.csv"]
    lines = tracked["stdout"].splitlines()
    assert lines[0].split() == ["target", "prior", "MAE", "model", "mean", "sd", "lowest",
                                "highest"]
    assert any(line.startswith("average") for line in lines)


@pytest.mark.parametrize("value", ["2-0", "a", "", "3", "1,1"])
def test_a_bad_seeds_value_is_one_line(value, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "any.toml", "--random-states", value])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("workbench: error: argument --random-states: "), err


def test_config_seeds_run_untracked_and_are_checked(config, tmp_path):
    cfg = config.parent / "from_config.toml"
    cfg.write_text(CONFIG + "\n[evaluation]\nrandom_states = [3, 5]\n")
    rc, out, err = _main("evaluate", cfg, "--no-track", "--jobs", "1")
    assert rc == 0, err
    assert "test MAE over 2 seeds (3, 5)" in out and "tracked" not in out
    bad = config.parent / "bad.toml"
    for seeds, needle in (("[4]", "two or more"), ("[1, 1]", "twice")):
        bad.write_text(CONFIG + f"\n[evaluation]\nrandom_states = {seeds}\n")
        rc, _, err = _main("evaluate", bad, "--no-track")
        assert rc == 2 and needle in err and err.count("\n") == 1, err
    rc, _, err = _main("evaluate", config, "--random-states", "0,1", "--register", "m")
    assert rc == 2 and "--register" in err


def test_the_api_matches_and_checks_its_seeds(config):
    cfg = load_config(config)
    done = evaluate_seeds(cfg, [0, 1])
    assert done.random_states == [0, 1] and len(done.results) == 2
    assert done.summary.test_mae_avg_mean == pytest.approx(
        np.mean([r.model.avg("test_mae") for r in done.results]))
    with pytest.raises(ValueError, match="two or more"):
        evaluate_seeds(cfg, [0])


def test_an_interrupt_ends_the_parent_and_the_current_child_killed(config, tmp_path,
                                                                    monkeypatch):
    """Ctrl-C during the second seed's fit: the first child FINISHED, the second and the
    parent KILLED, nothing RUNNING, no third child, exit 130."""
    real = seeds_module.evaluate
    calls = []

    def evaluate(cfg, *args, **kwargs):
        calls.append(cfg.random_state)
        if len(calls) == 2:
            raise signals.Interrupted(signal.SIGINT)
        return real(cfg, *args, **kwargs)

    monkeypatch.setattr(seeds_module, "evaluate", evaluate)
    rc, _, err = _main("evaluate", config, "--random-states", "0-2", "--set",
                       "tracking.experiment=seeds_interrupted", "--jobs", "1", "--json",
                       tmp_path / "out.json")
    assert rc == 130 and signals.MESSAGE in err
    assert not (tmp_path / "out.json").exists()
    status = {r.info.run_name: r.info.status for r in _runs("seeds_interrupted")}
    assert status == {"evaluate seeds_test": "KILLED", "evaluate seeds_test seed 0": "FINISHED",
                      "evaluate seeds_test seed 1": "KILLED"}
