"""Tests for the ``workbench`` command (``workbench.experiment.cli.main``)."""

from __future__ import annotations

import contextlib
import fcntl
import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from workbench.datasets import google_5q as g5
from workbench.experiment.cli import main

PAPER_TOML = Path(__file__).resolve().parents[1] / "experiments" / "paper_main_body.toml"
TARGETS = [f"eeig{i}" for i in range(1, 6)]

# the cheap MLP bases below stop early on purpose
pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")


def write_config(tmp_path: Path, data_dir: Path | None, model: str = 'basis = "ridge"', *,
                 random_state: int = 0, name: str = "cfg.toml") -> Path:
    data_line = f"data_dir = {json.dumps(str(data_dir))}\n" if data_dir is not None else ""
    path = tmp_path / name
    path.write_text(f'name = "cli_test"\nrandom_state = {random_state}\n\n'
                    f'[data]\nsource = "google_5q"\n{data_line}\n[model]\n{model}\n')
    return path


def _numbers(result: dict) -> dict:
    """The JSON minus what legitimately differs between runs (timing, file path)."""
    return {k: v for k, v in result.items() if k not in ("wall_s", "config")}


def _assert_clean_error(err: str, *needles: str) -> None:
    """No traceback; one error line (progress lines, e.g. "downloading ...", may precede it)."""
    assert "Traceback" not in err
    errors = [line for line in err.strip().splitlines() if line.startswith("workbench: error:")]
    assert len(errors) == 1, err
    for needle in needles:
        assert needle in err, (needle, err)


# --- evaluate end to end (run once per module) ----------------------------------------------

#: The paper's settings (experiments/paper_main_body.toml) with a ridge basis instead of the
#: paper's stacking: the same command, data, split, selection, intervals, tracking and figures
#: for the checks of evaluate's outputs below, at a fraction of the stacking's CPU time. The
#: stacking's own numbers are checked on the paper config itself by
#: test_reproduce.py::test_report_and_numbers (same config and seed) and, in the slow suite,
#: by test_paper_run_meets_acceptance_criterion below.
PAPER_RIDGE = """\
name = "paper_ridge"
random_state = 0
n_jobs = -1

[data]
source = "google_5q"

[model]
basis = "ridge"
n_stages = 1
loss = "squared_error"
line_search_loss = "absolute_error"
line_search_penalty = 0.1
basis_inputs = "prior"
input_transform = "quantile_normal"

[selection]
cv = 5
scoring = "neg_mean_absolute_error"
"""


def _run_evaluate(config: Path, google_5q_dir: Path, out: Path) -> dict:
    stdout, stderr = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(g5.ENV_VAR, str(google_5q_dir))
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            rc = main(["evaluate", str(config), "--json", str(out)])
    return dict(rc=rc, stdout=stdout.getvalue(), stderr=stderr.getvalue())


def _with_result(run: dict, out: Path) -> dict:
    run["out"] = out
    run["result"] = json.loads(out.read_text()) if out.exists() else None
    return run


@pytest.fixture(scope="module")
def evaluate_run(google_5q_dir, tmp_path_factory):
    """:data:`PAPER_RIDGE` through ``main`` once, tracked in the session's store."""
    root = tmp_path_factory.mktemp("evaluate_run")
    config = root / "paper_ridge.toml"
    config.write_text(PAPER_RIDGE)
    out = root / "sub" / "paper.json"
    return _with_result(_run_evaluate(config, google_5q_dir, out), out)


@pytest.fixture(scope="module")
def paper_run(google_5q_dir, tmp_path_factory):
    """The paper config through ``main`` once. Under pytest-xdist the workers share one run
    through a lock in the session's common temp directory, so the evaluation is not repeated
    (and does not compete with itself for the cores) on every worker."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = tmp_path_factory.getbasetemp().parent / "paper_run"  # this session's, shared
    else:
        root = tmp_path_factory.mktemp("paper_run")
    root.mkdir(exist_ok=True)
    out = root / "sub" / "paper.json"
    record = root / "run.json"
    with open(root / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not record.exists():
            record.write_text(json.dumps(_run_evaluate(PAPER_TOML, google_5q_dir, out)))
    return _with_result(json.loads(record.read_text()), out)


def test_evaluate_run_exit_code_and_json_written(evaluate_run):
    assert evaluate_run["rc"] == 0, evaluate_run["stderr"]
    assert evaluate_run["out"].is_file()  # parent directory created on demand
    assert not evaluate_run["out"].with_name(evaluate_run["out"].name + ".tmp").exists()
    assert f"wrote {evaluate_run['out']}" in evaluate_run["stdout"]


def test_evaluate_run_json_schema(evaluate_run, tmp_path):
    r = evaluate_run["result"]
    assert r is not None
    assert r["targets"] == TARGETS
    assert r["n_train"] == 95 and r["n_test"] == 41
    for part in ("prior", "model"):
        for key in ("test_mae", "test_mse", "cv_mae"):
            values = r[part][key]
            assert len(values) == 5 and all(np.isfinite(values)), (part, key)
            assert r[part][f"{key}_avg"] == pytest.approx(np.mean(values))
    assert all(v >= 0 for v in r["model"]["test_mae"] + r["model"]["test_mse"])
    assert len(r["model"]["selected"]) == 5
    assert set(r["model"]["selected"]) <= {"prior", "boosted"}
    # evaluate logs one parent run (no children) with the metrics, figures and the model
    from mlflow import MlflowClient

    client = MlflowClient(r["mlflow"]["tracking_uri"])
    run = client.get_run(r["mlflow"]["run_id"])
    assert run.data.metrics["test_mae_avg"] == pytest.approx(r["model"]["test_mae_avg"])
    assert run.data.tags["workbench.kind"] == "evaluate"
    assert not client.search_runs([run.info.experiment_id],
                                  f"tags.mlflow.parentRunId = '{run.info.run_id}'")
    plots = {a.path for a in client.list_artifacts(run.info.run_id, "plots")}
    assert {"plots/mae_bars.png", "plots/learning_curve_eeig3.png", "plots/shap_eeig1.png"} <= plots
    assert r["mlflow"]["model_uri"].startswith("models:/")
    assert isinstance(r["wall_s"], float) and r["wall_s"] > 0
    # the whole command's wall time, the same in MLflow (metric, result.json) and --json
    assert run.data.metrics["wall_s"] == pytest.approx(r["wall_s"])
    local = client.download_artifacts(run.info.run_id, "result.json", str(tmp_path))
    assert json.loads(Path(local).read_text())["wall_s"] == pytest.approx(r["wall_s"])


def test_evaluate_run_reports_prediction_intervals(evaluate_run):
    """Family eigenvalue with [intervals] absent: 90% intervals from the model's own
    out-of-fold residuals ("oof"), coverage and width per target on the test rows and in CV
    in the JSON and as MLflow metrics; the existing keys are unchanged (checked above)."""
    r = evaluate_run["result"]
    assert r["intervals"] == {"method": "oof", "alpha": 0.1, "level": 0.9}
    for key in ("test_coverage", "test_width", "cv_coverage", "cv_width"):
        values = r["model"][key]
        assert len(values) == 5 and all(np.isfinite(values)), key
        assert r["model"][f"{key}_avg"] == pytest.approx(np.mean(values))
        assert key not in r["prior"]
    # a fraction of the 41 test rows, and the 90% intervals cover most of them
    assert all(abs(v * 41 - round(v * 41)) < 1e-9 and 0.5 < v <= 1
               for v in r["model"]["test_coverage"])
    from mlflow import MlflowClient

    run = MlflowClient(r["mlflow"]["tracking_uri"]).get_run(r["mlflow"]["run_id"])
    assert run.data.metrics["test_coverage_avg"] == pytest.approx(
        r["model"]["test_coverage_avg"])
    assert run.data.metrics["cv_width/eeig3"] == pytest.approx(r["model"]["cv_width"][2])
    # one metric schema (the dataset's target names after a slash), described on the run page
    assert [run.data.metrics[f"test_mae/{t}"] for t in r["targets"]] == pytest.approx(
        r["model"]["test_mae"])
    assert "`test_mae/<target>`" in run.data.tags["mlflow.note.content"]


# The paper basis' fit (~45 s of CPU). In the default suite the same numbers are checked by
# test_reproduce.py::test_report_and_numbers (this config and seed: average test MAE <= 1.10,
# every target below the prior) and test_google_5q.py::test_prior_mae_matches_readme (1.3411).
@pytest.mark.slow
def test_paper_run_meets_acceptance_criterion(paper_run):
    assert paper_run["rc"] == 0, paper_run["stderr"]
    r = paper_run["result"]
    assert r["prior"]["test_mae_avg"] == pytest.approx(1.3411, abs=1e-3)
    assert r["model"]["test_mae_avg"] <= 1.10
    for name, prior_mae, model_mae in zip(r["targets"], r["prior"]["test_mae"],
                                          r["model"]["test_mae"]):
        assert model_mae < prior_mae, name


def test_evaluate_run_prints_table(evaluate_run):
    out = evaluate_run["stdout"]
    for name in TARGETS:
        assert re.search(rf"^{name}\s", out, re.M), name
    avg_line = next(line for line in out.splitlines() if line.startswith("average"))
    r = evaluate_run["result"]
    assert f"{r['prior']['test_mae_avg']:.3f}" in avg_line
    assert f"{r['model']['test_mae_avg']:.3f}" in avg_line
    assert "Traceback" not in evaluate_run["stderr"]


# --- cheap configs -------------------------------------------------------------------------

def _run_json(tmp_path: Path, cfg: Path, tag: str, *extra: str) -> dict:
    out = tmp_path / f"{tag}.json"
    assert main(["evaluate", str(cfg), "--json", str(out), "--no-track", *extra]) == 0
    return json.loads(out.read_text())


@pytest.mark.parametrize("model", [
    'basis = "ridge"',
    'basis = "mlp"\nbasis_params = { hidden_layer_sizes = [4], max_iter = 50 }',
], ids=["ridge", "mlp"])
def test_repeatable_with_same_random_state(tmp_path, google_5q_dir, capsys, model):
    cfg = write_config(tmp_path, google_5q_dir, model)
    first = _run_json(tmp_path, cfg, "a")
    second = _run_json(tmp_path, cfg, "b")
    assert _numbers(first) == _numbers(second)
    assert first["targets"] == TARGETS
    out = capsys.readouterr().out
    assert sum(line.startswith("average") for line in out.splitlines()) == 2  # a table each


def test_random_state_matters_for_random_basis(tmp_path, google_5q_dir, capsys):
    """Guards the repeatability test above against passing only because nothing is random."""
    model = 'basis = "mlp"\nbasis_params = { hidden_layer_sizes = [4], max_iter = 50 }'
    a = _run_json(tmp_path, write_config(tmp_path, google_5q_dir, model, name="a.toml"), "a")
    b = _run_json(tmp_path, write_config(tmp_path, google_5q_dir, model, random_state=1,
                                         name="b.toml"), "b")
    assert a["model"]["cv_mae_boosted"] != b["model"]["cv_mae_boosted"]
    # the prior never depends on the seed (its bootstrap intervals' resamples do)
    def point(scores):
        return {k: v for k, v in scores.items() if "_ci" not in k}

    assert point(a["prior"]) == point(b["prior"])


def test_jobs_override_gives_same_numbers(tmp_path, google_5q_dir, capsys):
    cfg = write_config(tmp_path, google_5q_dir)
    serial = _run_json(tmp_path, cfg, "serial")
    parallel = _run_json(tmp_path, cfg, "parallel", "--jobs", "2")
    assert _numbers(serial) == _numbers(parallel)


def test_no_intervals_gives_the_same_point_numbers(tmp_path, google_5q_dir, capsys):
    """``--no-intervals`` switches ``[intervals]`` off: no interval keys, the same fit."""
    cfg = write_config(tmp_path, google_5q_dir)
    with_iv = _run_json(tmp_path, cfg, "with")
    without = _run_json(tmp_path, cfg, "without", "--no-intervals")
    assert with_iv["intervals"]["method"] == "oof" and not without.get("intervals")
    assert "test_coverage" in with_iv["model"] and "test_coverage" not in without["model"]
    for key in ("test_mae", "cv_mae_boosted", "selected"):
        assert without["model"][key] == with_iv["model"][key]


def test_data_dir_from_environment(tmp_path, google_5q_dir, monkeypatch, capsys):
    monkeypatch.setenv(g5.ENV_VAR, str(google_5q_dir))
    cfg = write_config(tmp_path, None)
    r = _run_json(tmp_path, cfg, "env")
    assert r["prior"]["test_mae_avg"] == pytest.approx(1.3411, abs=1e-3)
    assert r["config"] == str(cfg)


# --- error paths ---------------------------------------------------------------------------

def test_unknown_basis_is_a_clean_error(tmp_path, google_5q_dir, capsys):
    cfg = write_config(tmp_path, google_5q_dir, 'basis = "bogus_basis"')
    out = tmp_path / "never.json"
    assert main(["evaluate", str(cfg), "--json", str(out)]) == 2
    captured = capsys.readouterr()
    _assert_clean_error(captured.err, "bogus_basis", "ridge", "paper_stacking")
    assert len(captured.err.strip().splitlines()) == 1
    assert not out.exists()
    assert captured.out == ""


def test_missing_config_is_a_clean_error(tmp_path, capsys):
    missing = tmp_path / "missing.toml"
    out = tmp_path / "never.json"
    assert main(["evaluate", str(missing), "--json", str(out)]) == 2
    captured = capsys.readouterr()
    _assert_clean_error(captured.err, str(missing), "not found")
    assert len(captured.err.strip().splitlines()) == 1
    assert not out.exists()


def test_unavailable_data_is_a_clean_error(tmp_path, monkeypatch, capsys):
    empty = tmp_path / "empty_data"
    empty.mkdir()
    calls = []

    def failing_cmd(dest):
        calls.append(dest)
        return [sys.executable, "-c", "raise SystemExit(1)"]

    monkeypatch.setattr(g5.WHEEL, "pip_download_cmd", failing_cmd)
    monkeypatch.delenv(g5.ENV_VAR, raising=False)
    cfg = write_config(tmp_path, empty)
    out = tmp_path / "never.json"
    assert main(["evaluate", str(cfg), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    _assert_clean_error(err, "WORKBENCH_DATA_DIR", "google_5q data unavailable")
    assert calls, "the download was not attempted"
    assert not out.exists()
    assert list(empty.iterdir()) == []  # nothing half-written into the data directory


def test_directory_as_config_is_a_clean_error(tmp_path, capsys):
    assert main(["evaluate", str(tmp_path)]) == 2
    _assert_clean_error(capsys.readouterr().err, str(tmp_path))


def test_missing_subcommand_is_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2
    err = capsys.readouterr().err  # one line, not the usage block
    assert err.count("\n") == 1 and err.startswith("workbench: error: ")
    assert "command" in err and "sweep" in err and "workbench --help" in err


def test_missing_subcommand_lists_every_command_help_shows(capsys):
    """The list comes from the parser's own subcommands, so it cannot drift from them."""
    with pytest.raises(SystemExit):
        main(["--help"])
    usage = capsys.readouterr().out
    shown = re.search(r"\{([a-z,]+)\}", usage).group(1).split(",")
    assert len(shown) >= 9 and {"compare", "design"} <= set(shown)  # it read the help
    with pytest.raises(SystemExit):
        main([])
    err = capsys.readouterr().err
    assert f"({', '.join(shown)}; see workbench --help)" in err, err


# --- the installed console script -----------------------------------------------------------

def test_console_script_help():
    script = Path(sys.executable).parent / "workbench"
    assert script.is_file()
    res = subprocess.run([str(script), "--help"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    assert "usage: workbench" in res.stdout and "evaluate" in res.stdout


def test_ui_command_serves_the_local_store_on_loopback(tmp_path):
    from workbench.experiment.tracking.views import ui_command

    uri = f"sqlite:///{tmp_path / 'mlruns' / 'mlflow.db'}"
    cmd = ui_command(uri, 5055)
    assert cmd[1:4] == ["-m", "mlflow", "server"]
    assert cmd[cmd.index("--host") + 1] == "127.0.0.1"
    assert cmd[cmd.index("--port") + 1] == "5055"
    assert cmd[cmd.index("--workers") + 1] == "1"  # one process serves a user's browser
    assert ui_command(uri, 5055, 3)[cmd.index("--workers") + 1] == "3"
    assert cmd[cmd.index("--backend-store-uri") + 1] == uri
    artifacts = (tmp_path / "mlruns" / "artifacts").as_uri()
    assert cmd[cmd.index("--default-artifact-root") + 1] == artifacts
    # an in-memory SQLite store has no folder for the artifacts (was an AttributeError)
    memory = ui_command("sqlite:///:memory:", 5055)
    assert memory[memory.index("--backend-store-uri") + 1] == "sqlite:///:memory:"
    assert "--default-artifact-root" not in memory


def test_ui_servers_run_without_mlflow_server_jobs_unless_asked(monkeypatch):
    from workbench.experiment.tracking.views import ui_env

    monkeypatch.delenv("MLFLOW_SERVER_ENABLE_JOB_EXECUTION", raising=False)
    monkeypatch.setenv("WORKBENCH_SOME_SETTING", "kept")
    env = ui_env()
    assert env["MLFLOW_SERVER_ENABLE_JOB_EXECUTION"] == "false"
    assert env["WORKBENCH_SOME_SETTING"] == "kept"  # the rest of the environment as is
    monkeypatch.setenv("MLFLOW_SERVER_ENABLE_JOB_EXECUTION", "true")  # the user's choice wins
    assert ui_env()["MLFLOW_SERVER_ENABLE_JOB_EXECUTION"] == "true"


def test_corrupt_store_is_a_clean_error_and_left_untouched(tmp_path, capsys, google_5q_dir,
                                                          monkeypatch):
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    db = tmp_path / "mlflow.db"
    db.write_bytes(b"not a database at all" * 10)
    before = db.read_bytes()
    cfg = tmp_path / "c.toml"
    cfg.write_text('[data]\nsource = "google_5q"\n[model]\nbasis = "ridge"\n')
    out = tmp_path / "out.json"
    assert main(["evaluate", str(cfg), "--json", str(out), "--tracking-uri",
                 f"sqlite:///{db}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("workbench: error:") and "mlflow.db" in err[0]
    assert db.read_bytes() == before and not out.exists()
